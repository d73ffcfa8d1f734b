"""The learned baseline of issue 39 item 4 (depthor_models/sparse_to_dense.py): shapes and
output range, its MAC count (recounted independently, and within ±10 % of mcu_lite's), its
input channels, a tiny overfit, the train.py hook and the grid's metric."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from depthor_models import sparse_to_dense as S
from depthor_models import train as T
from depthor_models.budget import budget

from test_train import write_recording


def test_shapes_and_output_range():
    net = S.build(seed=0).eval()
    for h, w in ((120, 160), (64, 96)):
        rgb = torch.rand(2, 3, h, w)
        sp = torch.zeros(2, 1, h, w)
        sp[:, :, ::15, ::20] = 2.5
        with torch.no_grad():
            d = net(rgb, sp)
        assert d.shape == (2, 1, h, w)
        assert torch.isfinite(d).all()
        assert d.min() >= net.cfg.min_depth_m * (1 - 1e-5)
        assert d.max() <= net.cfg.max_depth_m * (1 + 1e-5)


def test_inputs_are_rgb_scaled_depth_and_validity():
    net = S.build(seed=0)
    rgb = torch.rand(1, 3, 8, 8)
    sp = torch.zeros(1, 1, 8, 8)
    sp[0, 0, 2, 3], sp[0, 0, 5, 6] = 4.0, 0.5
    x = net.inputs(rgb, sp)
    assert x.shape == (1, 5, 8, 8)
    assert torch.equal(x[:, :3], rgb)
    assert torch.allclose(x[:, 3:4], sp / 10.0)
    assert torch.equal(x[:, 4:5], (sp > 0).float())
    assert x[0, 4].sum() == 2


def _independent_macs(net: S.SparseToDense) -> int:
    """conv2d = out elements × in/groups × kh × kw, bilinear upsampling = 4 per output, counted
    with forward hooks on torch's own modules and a patched interpolate."""
    total = [0]

    def conv_hook(m, _i, out):
        total[0] += out.numel() * m.in_channels // m.groups * m.kernel_size[0] * m.kernel_size[1]

    hooks = [m.register_forward_hook(conv_hook) for m in net.modules()
             if isinstance(m, torch.nn.Conv2d)]
    orig = F.interpolate

    def interp(x, *a, **k):
        y = orig(x, *a, **k)
        total[0] += 4 * y.numel()
        return y

    F.interpolate = interp
    try:
        with torch.no_grad():
            net.eval().body(torch.zeros(1, 5, net.cfg.height, net.cfg.width))
    finally:
        F.interpolate = orig
        for h in hooks:
            h.remove()
    return total[0]


def test_macs_match_an_independent_count_and_the_mcu_lite_budget():
    net = S.build(seed=0)
    macs = net.macs()
    assert macs == _independent_macs(net)
    ref = budget("mcu_lite")["macs"]
    assert ref == S.MCU_LITE_MACS
    assert abs(macs / ref - 1) <= 0.10, (macs, ref)
    # the count follows the widths: a wider encoder costs more
    assert S.build(enc_widths=(16, 24, 32, 48, 64)).macs() > macs


@pytest.fixture
def one_thread():
    """One torch thread (a tiny network; two threads on a busy machine spin far longer)."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


def test_overfits_two_frames(one_thread):
    """Two 32×48 frames whose depth is the sparse points' value, one plane each: 150 AdamW
    steps on the SILog loss must bring the RMSE below a quarter of its start."""
    torch.manual_seed(0)
    net = S.build(seed=0, height=32, width=48)
    rgb = torch.rand(2, 3, 32, 48)
    gt = torch.tensor([1.0, 3.0]).view(2, 1, 1, 1).expand(2, 1, 32, 48).clone()
    sp = torch.zeros_like(gt)
    sp[:, :, 4::8, 4::8] = gt[:, :, 4::8, 4::8]
    opt = torch.optim.AdamW(net.parameters(), 3e-3)

    def rmse():
        net.eval()
        with torch.no_grad():
            e = float(((net(rgb, sp) - gt) ** 2).mean().sqrt())
        net.train()
        return e

    start = rmse()
    for _ in range(150):
        loss = T.silog_loss(net(rgb, sp), gt)
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert rmse() < 0.25 * start


def test_train_hook_trains_and_evaluates_the_baseline(tmp_path, capsys):
    rec_dir = write_recording(tmp_path / "rec", n=4)
    out = tmp_path / "run"
    T.main(["--arch", "sparse_to_dense", "--train", str(rec_dir), "--test", str(rec_dir),
            "--out", str(out), "--steps", "3", "--batch", "2", "--max-lr", "1e-3",
            "--eval-frames", "1", "--ckpt-every-s", "1e9", "--threads", "1", "--augment"])
    state = torch.load(out / "model_final.pt")
    ref = S.build(seed=0).state_dict()
    assert set(state) == set(ref)
    moved = [k for k in ref if ref[k].dtype.is_floating_point and not torch.equal(state[k], ref[k])]
    assert moved, "no weight changed in 3 steps"
    net = S.load(out / "model_final.pt")
    assert isinstance(net, S.SparseToDense) and not net.training
    with pytest.raises(ValueError):
        T.main(["--arch", "sparse_to_dense", "--stage", "prior", "--train", str(rec_dir),
                "--test", str(rec_dir), "--out", str(tmp_path / "p"), "--steps", "1",
                "--batch", "2", "--threads", "1"])
    capsys.readouterr()
    assert T.main(["--arch", "sparse_to_dense", "--test", str(rec_dir), "--eval-frames", "1",
                   "--eval-only", str(out / "model_final.pt")]) == 0
    row = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert row["prior_ssi"] == "" and math.isfinite(row["model_rmse"])


def test_image_rmse_follows_the_host_metric():
    gt = np.zeros((3, 2, 2), np.float32)
    gt[0] = [[1.0, 2.0], [0.0, 12.0]]  # two valid pixels (0 and ≥ 10 m are not counted)
    gt[2] = 4.0
    pred = np.zeros_like(gt)
    pred[0] = [[2.0, 2.0], [5.0, 5.0]]
    pred[2] = 20.0  # clamped to 10 m
    r = S.image_rmse(pred, gt)
    assert r.shape == (2,)  # the frame without valid pixels is left out
    assert r[0] == pytest.approx(math.sqrt(0.5))
    assert r[1] == pytest.approx(6.0)


def test_condition_config_merges_the_file_over_clean(tmp_path):
    (tmp_path / "manifest.json").write_text(json.dumps({"base": "clean.json", "conditions": [
        {"name": "preset", "on_base": False}, {"name": "clean"},
        {"name": "noisy", "file": "n.json"}]}))
    (tmp_path / "clean.json").write_text(json.dumps({"a": {"x": 1, "y": 2}, "b": 0}))
    (tmp_path / "n.json").write_text(json.dumps({"a": {"y": 5}, "c": 1}))
    assert S.condition_config(tmp_path, "preset") is None
    assert S.condition_config(tmp_path, "clean") == {"a": {"x": 1, "y": 2}, "b": 0}
    assert S.condition_config(tmp_path, "noisy") == {"a": {"x": 1, "y": 5}, "b": 0, "c": 1}
