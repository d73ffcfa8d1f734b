"""The zone gate prototype (depthor_models/zone_gate.py): the joint bilateral candidate follows
the host baseline's definition, and the gate learns to pick the candidate that is right."""

import math

import numpy as np
import torch

from depthor_models import zone_gate


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
