"""The zone gate prototype (depthor_models/zone_gate.py): the joint bilateral candidate follows
the host baseline's definition, and the gate learns to pick the candidate that is right."""

import json
import math

import numpy as np
import torch

from depthor_models import data, zone_gate
from depthor_models.net import build


def test_joint_bilateral_weights_points_by_distance_and_colour():
    h, w = 8, 8
    rgb = np.zeros((h, w, 3), np.uint8)
    rgb[:, 4:] = 60  # right half another colour (3 levels of σ per channel)
    sparse = np.zeros((h, w), np.float32)
    sparse[3, 1], sparse[3, 6] = 1.0, 3.0
    out = zone_gate.joint_bilateral(rgb, sparse)
    spacing = math.sqrt(h * w / 2)
    # pixel (3, 2): both points in reach; colour difference only to the right point
    d_left, d_right = 1.0, 16.0
    r2 = 3 * 60.0**2
    wl = math.exp(-d_left / (2 * spacing**2))
    wr = math.exp(-d_right / (2 * spacing**2) - r2 / (2 * 20.0**2))
    assert math.isclose(out[3, 2], (wl * 1.0 + wr * 3.0) / (wl + wr), rel_tol=1e-5)
    # on the points themselves, each side keeps (nearly) its own point's depth
    assert abs(out[3, 1] - 1.0) < 1e-3 and abs(out[3, 6] - 3.0) < 1e-3
    assert np.all(zone_gate.joint_bilateral(rgb, np.zeros((h, w), np.float32)) == 1.0)


def test_gate_learns_to_follow_the_candidate_that_is_right():
    """Candidate 0 (the network) is 10 % off everywhere; candidate 1 (the zones) is exact in
    bright frames and 30 % off in dark ones; candidate 2 is always 50 % off. The trained gate
    must follow candidate 1 in bright frames, candidate 0 in dark ones, and beat every single
    candidate."""
    g = torch.Generator().manual_seed(0)
    n, h, w = 32, 16, 16
    gt = 1.0 + 3.0 * torch.rand(n, 1, h, w, generator=g)
    bright = (torch.arange(n) % 2 == 0).view(n, 1, 1, 1).float()
    rgb = bright.expand(n, 3, h, w).clone()
    def noisy(amplitude):
        return gt * (1.0 + amplitude * (2 * torch.rand(n, 1, h, w, generator=g) - 1))

    c0 = noisy(0.1)
    c1 = torch.where(bright > 0, gt, noisy(0.3))
    c2 = gt * 1.5
    cand = torch.cat([c0, c1, c2], 1)
    gate = zone_gate.train(cand, rgb, gt, steps=300, channels=8, batch=8, lr=3e-3)
    with torch.no_grad():
        fused, wts = gate(cand, rgb)
    err = zone_gate.image_rmse(fused, gt).mean().item()
    singles = [zone_gate.image_rmse(cand[:, k:k + 1], gt).mean().item() for k in range(3)]
    assert err < 0.7 * min(singles), (err, singles)
    assert wts[bright[:, 0, 0, 0] > 0, 1].mean() > 0.8
    assert wts[bright[:, 0, 0, 0] == 0, 0].mean() > 0.8


def test_gate_macs_at_the_mcu_size():
    # 30×40 positions × (8·16 + 16·16 + 16·16 + 16·3)·9
    assert zone_gate.ZoneGate(16).macs(120, 160) == 1200 * (128 + 256 + 256 + 48) * 9


def test_gate_macs_at_the_phone_size():
    # 80×60 positions at 320×240 (phone_lite's input): 29.7 M MACs beside phone_lite's ~84 M
    assert zone_gate.ZoneGate(16).macs(320, 240) == 4800 * (128 + 256 + 256 + 48) * 9


def test_features_resample_frames_to_the_network_input(tmp_path):
    """A recording at twice mcu_lite's input (as the phone's rendered frames are larger than
    phone_lite's input): the candidates come out at the network's size, with the ground truth
    resampled the way `depthor eval` resamples it."""
    from PIL import Image

    h, w, n = 240, 320, 2
    rng = np.random.default_rng(0)
    rects = [[y0, x0, y0 + 120, x0 + 160] for y0 in (0, 120) for x0 in (0, 160)]
    meta = {"format": "depthor-recording/1",
            "camera": {"width": w, "height": h, "fx": 200.0, "fy": 200.0, "cx": 160.0,
                       "cy": 120.0},
            "dtof": {"rows": 2, "cols": 2, "fov_deg": [60.0, 60.0], "distance": "z",
                     "max_range_m": 4.0, "zone_rects_px": rects},
            "frames": [{"id": f"{i:06d}", "t_s": float(i)} for i in range(n)]}
    rec = tmp_path / "rec"
    rec.mkdir()
    (rec / "recording.json").write_text(json.dumps(meta))
    depth = (1000 + 5 * np.arange(w)[None, :] + 3 * np.arange(h)[:, None]).astype(np.uint16)
    for i in range(n):
        f = rec / "frames" / f"{i:06d}"
        f.mkdir(parents=True)
        Image.fromarray(rng.integers(0, 256, (h, w, 3), dtype=np.uint8)).save(f / "rgb.png")
        Image.fromarray(depth).save(f / "depth.png")
        (f / "dtof.json").write_text(json.dumps({"distance_mm": [1000.0, 2000.0, 3000.0, 4000.0],
                                                 "status": [5, 5, 5, 5]}))
    weights = tmp_path / "w.pt"
    torch.save(build("mcu_lite", calibrate_bn=False).state_dict(), weights)
    out = tmp_path / "f.npz"
    zone_gate.features(str(rec), 0, out, weights=weights, variant="mcu_lite")
    z = np.load(out)
    assert z["cand"].shape == (n, 3, 120, 160) and z["rgb"].shape == (n, 120, 160, 3)
    _, gt_mm = data.resample(np.zeros((1, h, w, 3), np.uint8), depth[None], (120, 160))
    assert np.allclose(z["gt"][0], gt_mm[0] / 1000)
    assert np.isfinite(z["cand"]).all() and (z["cand"][:, 1:] >= 1.0).all()


def test_export_writes_the_core_format_and_a_golden_vector():
    """The DZG1 file has the header and layer layout `depthor_core::zone_gate` parses, and the
    golden vector holds the inputs and PyTorch's blend (host/tests/zone_gate.rs compares the
    core against it)."""
    torch.manual_seed(0)
    gate = zone_gate.ZoneGate(4).eval()
    b = zone_gate.to_bytes(gate)
    assert b[:4] == b"DZG1"
    assert list(np.frombuffer(b[4:12], "<u2")) == [3, 4, 4, 4]
    assert np.frombuffer(b[12:16], "<f4")[0] == np.float32(0.1)
    widths = [(8, 4), (4, 4), (4, 4), (4, 3)]
    assert len(b) == 16 + sum(4 + 4 * (o * i * 9 + o) for i, o in widths)
    # dilations 1, 2, 4, 1 in the layer headers
    at, dil = 16, []
    for i, o in widths:
        dil.append(int(np.frombuffer(b[at:at + 2], "<u2")[0]))
        at += 4 + 4 * (o * i * 9 + o)
    assert dil == [1, 2, 4, 1]
    cand = (1 + np.random.default_rng(0).random((3, 8, 12))).astype(np.float32)
    rgb = np.random.default_rng(1).integers(0, 256, (8, 12, 3), dtype=np.uint8)
    g = zone_gate.golden_bytes(gate, cand, rgb)
    assert list(np.frombuffer(g[:8], "<u4")) == [12, 8]
    assert len(g) == 8 + 4 * 3 * 96 + 3 * 96 + 4 * 96
    blend = np.frombuffer(g[-4 * 96:], "<f4").reshape(8, 12)
    assert np.all(blend >= cand.min(0) - 1e-6) and np.all(blend <= cand.max(0) + 1e-6)


def test_best_candidate_norm_trains_and_a_bad_norm_is_refused():
    g = torch.Generator().manual_seed(0)
    gt = 1.0 + torch.rand(8, 1, 8, 8, generator=g)
    cand = torch.cat([gt * 1.2, gt, gt * 0.7], 1)
    rgb = torch.rand(8, 3, 8, 8, generator=g)
    gate = zone_gate.train(cand, rgb, gt, steps=300, channels=4, batch=4, lr=3e-3, norm="best")
    with torch.no_grad():
        _, wts = gate(cand, rgb)
    # from 0.11 at the start (the initial bias prefers candidate 0) toward the exact one
    assert wts[:, 1].mean() > 0.3
    try:
        zone_gate.train(cand, rgb, gt, steps=1, norm="median")
    except ValueError as e:
        assert "norm" in str(e)
    else:
        raise AssertionError("norm='median' was accepted")
