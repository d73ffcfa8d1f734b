"""Training pieces: losses, metrics, zone baselines, the recording loader and resumable training,
on hand-computed cases and a tiny synthetic recording."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from depthor_models import data
from depthor_models import train as T

H, W = 32, 48


def write_recording(root: Path, n: int = 3, seed: int = 0) -> Path:
    """A 2×2-zone recording of H×W frames: zone k's rectangle is centred on pixel ZONE_PX[k]."""
    from PIL import Image

    rng = np.random.default_rng(seed)
    rects = [[2.0, 4.0, 10.0, 14.0],      # centre (6, 9)
             [2.0, 30.0, 10.0, 40.0],     # centre (6, 35)
             [18.0, 4.0, 26.0, 14.0],     # centre (22, 9)
             [18.0, 30.0, 26.5, 41.0]]    # centre (22.25, 35.5) -> (22, 36)
    meta = {"format": "depthor-recording/1",
            "camera": {"width": W, "height": H, "fx": 40.0, "fy": 40.0, "cx": 24.0, "cy": 16.0},
            "dtof": {"rows": 2, "cols": 2, "fov_deg": [45.0, 45.0], "distance": "z",
                     "max_range_m": 4.0, "zone_rects_px": rects},
            "frames": [{"id": f"{i:06d}", "t_s": float(i)} for i in range(n)]}
    root.mkdir(parents=True)
    (root / "recording.json").write_text(json.dumps(meta))
    for i in range(n):
        f = root / "frames" / f"{i:06d}"
        f.mkdir(parents=True)
        Image.fromarray(rng.integers(0, 256, (H, W, 3), dtype=np.uint8)).save(f / "rgb.png")
        depth = (1000 + 100 * np.arange(W)[None, :] + 10 * np.arange(H)[:, None] + 500 * i)
        Image.fromarray(depth.astype(np.uint16)).save(f / "depth.png")
        dist = [1000.0, 2000.0, 3000.0, 4000.0]
        status = [5, 255, 5, 9] if i == 0 else [5, 5, 5, 5]
        (f / "dtof.json").write_text(json.dumps({"distance_mm": dist, "status": status}))
    return root


ZONE_PX = [(6, 9), (6, 35), (22, 9), (22, 36)]


@pytest.fixture
def rec(tmp_path):
    return data.load_recording(write_recording(tmp_path / "rec"))


def test_zone_pixels_round_half_up_and_outside():
    px = data.zone_pixels([[-6.03125, 21.28125, 6.96875, 35.28125],  # centre (0.47, 28.28)
                           [0.0, 0.0, 1.0, 1.0],                     # centre (0.5, 0.5) -> (1, 1)
                           [-3.0, 0.0, -1.0, 2.0]], 10, 40)          # centre row -2: outside
    assert px.tolist() == [[0, 28], [1, 1], [-1, -1]]


def test_loader_sparse_and_cache(rec, tmp_path):
    assert len(rec) == 3 and (rec.height, rec.width) == (H, W)
    assert rec.zone_px.tolist() == [list(p) for p in ZONE_PX]
    assert rec.depth_mm[1, 2, 3] == 1000 + 300 + 20 + 500
    sp = data.sparse_maps(rec, np.array([0, 1]))
    # frame 0: zone 1 has no target (255) and zone 3 status 9 is not used (status 5 only)
    assert np.count_nonzero(sp[0]) == 2 and np.count_nonzero(sp[1]) == 4
    assert sp[0][6, 9] == pytest.approx(1.0) and sp[0][22, 9] == pytest.approx(3.0)
    assert sp[1][22, 36] == pytest.approx(4.0)
    assert np.count_nonzero(data.sparse_maps(rec, np.array([0]), (5, 9))) == 3
    again = data.load_recording(tmp_path / "rec")  # from the cache
    assert (tmp_path / "rec" / data.CACHE_NAME).exists()
    assert np.array_equal(again.rgb, rec.rgb) and np.array_equal(again.zone_m, rec.zone_m)


def test_batch_flip_is_consistent(rec):
    rgb, sp, gt = data.batch(rec, np.array([1, 1]), np.array([False, True]))
    assert rgb.shape == (2, 3, H, W) and sp.shape == (2, 1, H, W) and gt.shape == (2, 1, H, W)
    assert torch.equal(rgb[1], rgb[0].flip(-1)) and torch.equal(gt[1], gt[0].flip(-1))
    assert sp[1, 0, 22, W - 1 - 36] == pytest.approx(4.0) and sp[1, 0, 22, 36] == 0.0
    assert gt[0, 0, 0, 0] == pytest.approx(1.5) and gt[1, 0, 0, 0] == pytest.approx(1.5 + 4.7)
    ds = data.RecordingDataset(rec, augment=True, generator=torch.Generator().manual_seed(0))
    items = [ds[1] for _ in range(16)]
    flipped = [torch.equal(it[2], gt[1]) for it in items]
    assert any(flipped) and not all(flipped)


def test_silog_hand_case():
    gt = torch.tensor([[[[1.0, 2.0], [4.0, 20.0]]]])  # 20 m is outside (0.1, 10): ignored
    pred = gt * math.exp(0.5)
    pred[0, 0, 1, 1] = 1.0
    # g = 0.5 on 3 pixels: mean g² - λ (mean g)² = 0.25 (1 - 0.85)
    assert float(T.silog_loss(pred, gt)) == pytest.approx(10 * math.sqrt(0.25 * 0.15), rel=1e-5)
    g = torch.tensor([0.1, -0.2, 0.4])  # unequal g: variance term appears
    d = float((g * g).mean() - 0.85 * g.mean() ** 2)
    pred2 = torch.tensor([[[[1.0, 2.0], [4.0, 1.0]]]]) * torch.tensor(
        [[[[math.exp(0.1), math.exp(-0.2)], [math.exp(0.4), 1.0]]]])
    assert float(T.silog_loss(pred2, gt)) == pytest.approx(10 * math.sqrt(d), rel=1e-5)


def test_ssi_inverse_loss_is_affine_invariant():
    gt = torch.linspace(0.5, 8.0, 64).reshape(1, 1, 8, 8).repeat(2, 1, 1, 1)
    d_inv = 3.0 / gt + 0.7
    assert float(T.ssi_inverse_loss(d_inv, gt)) < 1e-5
    assert float(T.ssi_inverse_loss(gt.clone(), gt)) > 0.3  # depth instead of inverse depth


def test_metrics_hand_case():
    gt = np.array([[[1.0, 2.0], [4.0, 0.0]]])
    pred = np.array([[[1.0, 2.0], [2.0, 5.0]]])  # last pixel has no gt
    m = T.metrics(pred, gt)
    assert m["rmse"] == pytest.approx(math.sqrt(4.0 / 3.0))
    assert m["delta1"] == pytest.approx(2.0 / 3.0)
    assert m["rel"] == pytest.approx(0.5 / 3.0)


def test_zone_baselines_hand_case(rec):
    b = T.zone_baselines(rec, np.array([0, 1]))
    bil, near = b["bilinear"], b["nearest"]
    # frame 1: all four zones valid (1, 2, 3, 4 m) at rows 6/22 and cols 9/35.5 (mean of 35, 36)
    assert bil[1, 6, 9] == pytest.approx(1.0) and bil[1, 22, 9] == pytest.approx(3.0)
    assert bil[1, 14, 9] == pytest.approx(2.0)            # halfway down column 9
    assert bil[1, 0, 0] == pytest.approx(1.0)             # clamped outside the grid
    ty = (14 - 6) / 16.0
    tx = (22 - 9) / 26.5
    want = (1 - ty) * (1 - tx) * 1 + (1 - ty) * tx * 2 + ty * (1 - tx) * 3 + ty * tx * 4
    assert bil[1, 14, 22] == pytest.approx(want, rel=1e-5)
    assert near[1, 20, 40] == pytest.approx(4.0) and near[1, 0, 0] == pytest.approx(1.0)
    # frame 0: zones 1 (255) and 3 (status 9) invalid: row 6 is 1.0 m all along
    assert bil[0, 6, 40] == pytest.approx(1.0) and near[0, 6, 40] == pytest.approx(1.0)
    assert bil[0, 14, 9] == pytest.approx(2.0)            # renormalised between zones 0 and 2


def test_batch_plan_epochs_and_determinism():
    seen = np.concatenate([T.batch_plan(7, s, 4, 10)[0] for s in range(5)])  # two epochs
    assert sorted(seen[:10].tolist()) == list(range(10))
    assert sorted(seen[10:20].tolist()) == list(range(10))
    a, b = T.batch_plan(7, 3, 4, 10), T.batch_plan(7, 3, 4, 10)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


def _args(train_dir, out, *extra):
    return ["--train", str(train_dir), "--test", str(train_dir), "--out", str(out),
            "--steps", "3", "--batch", "2", "--max-lr", "1e-3", "--eval-frames", "1",
            "--ckpt-every-s", "1e9", "--threads", "2", *extra]


def test_resume_matches_uninterrupted_run(tmp_path, capsys):
    rec_dir = write_recording(tmp_path / "rec", n=5)
    T.main(_args(rec_dir, tmp_path / "full"))
    T.main(_args(rec_dir, tmp_path / "cut", "--stop-after", "2"))
    ck = torch.load(tmp_path / "cut" / "ckpt.pt", weights_only=False)
    assert ck["step"] == 2 and ck["scheduler"]["last_epoch"] == 2
    with (tmp_path / "cut" / "train.csv").open("a") as f:
        f.write("3,99,0,0,0,0,0\n")  # a step logged after the checkpoint, then killed
    T.main(_args(rec_dir, tmp_path / "cut", "--resume"))
    full = torch.load(tmp_path / "full" / "model_final.pt")
    cut = torch.load(tmp_path / "cut" / "model_final.pt")
    for k in full:
        assert torch.allclose(full[k].float(), cut[k].float(), atol=1e-6), k
    with (tmp_path / "cut" / "train.csv").open() as f:
        steps = [int(r["step"]) for r in csv.DictReader(f)]
    assert steps == [1, 2, 3]
    with (tmp_path / "cut" / "eval.csv").open() as f:
        assert [int(r["step"]) for r in csv.DictReader(f)] == [2, 3]
    assert (tmp_path / "cut" / "loss.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with (tmp_path / "cut" / "eval.csv").open() as f:
        last = list(csv.DictReader(f))[-1]
    capsys.readouterr()
    assert T.main(["--test", str(rec_dir), "--eval-frames", "1", "--eval-only",
                   str(tmp_path / "cut" / "model_final.pt")]) == 0
    row = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert row["model_rmse"] == pytest.approx(float(last["model_rmse"]), rel=1e-6)


def test_onecycle_at_follows_torch_onecycle():
    """The time-keyed schedule is make_optim's OneCycle as a function of progress in [0, 1]."""
    max_lr, total = 1e-3, 1001
    net = torch.nn.Linear(2, 1)
    opt, sched = T.make_optim(net, max_lr, total)
    for k in range(total):
        lr, beta1 = T.onecycle_at(k / (total - 1), max_lr)
        assert lr == pytest.approx(opt.param_groups[0]["lr"], abs=0.01 * max_lr), k
        assert beta1 == pytest.approx(opt.param_groups[0]["betas"][0], abs=0.002), k
        opt.step()
        sched.step()
    assert T.onecycle_at(0.0, max_lr) == pytest.approx((max_lr / 25, 0.95))
    assert T.onecycle_at(0.3, max_lr) == pytest.approx((max_lr, 0.85))
    assert T.onecycle_at(1.0, max_lr) == pytest.approx((max_lr / 100, 0.95))
    assert T.onecycle_at(2.0, max_lr) == T.onecycle_at(1.0, max_lr)


def test_schedule_by_time_stops_when_spent(tmp_path):
    rec_dir = write_recording(tmp_path / "rec", n=5)
    T.main(_args(rec_dir, tmp_path / "run", "--schedule-s", "1e-9"))
    with (tmp_path / "run" / "train.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [int(r["step"]) for r in rows] == [1]  # one step spends any positive budget
    assert float(rows[0]["lr"]) == pytest.approx(1e-3 / 25, rel=1e-3)  # progress 0
    ck = torch.load(tmp_path / "run" / "ckpt.pt", weights_only=False)
    assert ck["step"] == 1 and ck["args"]["schedule_s"] == 1e-9


def test_step_cap_before_the_time_schedule_ends_is_reported(tmp_path, capsys):
    rec_dir = write_recording(tmp_path / "rec", n=5)
    T.main(_args(rec_dir, tmp_path / "run", "--schedule-s", "1e9"))
    out = capsys.readouterr().out
    assert "stopped at step 3/3" in out and "warning: --steps 3 ended the run" in out


def test_export_loads_trained_weights(tmp_path):
    from depthor_models.export import build_trained

    net = T.make_model("mcu", seed=3)
    with torch.no_grad():
        net.refine.sigma.fill_(0.25)
        net.prior.enc[0].down.bn.running_mean.fill_(0.5)
    torch.save({"model": net.state_dict(), "step": 7}, tmp_path / "ckpt.pt")
    torch.save(net.state_dict(), tmp_path / "plain.pt")
    for f in ("ckpt.pt", "plain.pt"):
        got = build_trained("mcu", tmp_path / f)
        assert not got.training
        for k, v in net.state_dict().items():
            assert torch.equal(got.state_dict()[k], v), k


def test_crop_plan_is_seeded_inside_and_optional():
    assert T.crop_plan(0, 5, 320, 240, None) == (0, 0, 320, 240)
    assert T.crop_plan(0, 5, 64, 64, (224, 192)) == (0, 0, 64, 64)
    a = [T.crop_plan(3, s, 320, 240, (224, 192)) for s in range(50)]
    assert a == [T.crop_plan(3, s, 320, 240, (224, 192)) for s in range(50)]
    assert all(0 <= y <= 96 and 0 <= x <= 48 and (h, w) == (224, 192) for y, x, h, w in a)
    assert len({(y, x) for y, x, _, _ in a}) > 10
    assert T.parse_crop("224x192") == (224, 192) and T.parse_crop(None) is None
    for bad in ("224", "200x192", "0x32", "axb"):
        with pytest.raises(ValueError):
            T.parse_crop(bad)


def test_load_recordings_concatenates_and_rejects_other_layouts(tmp_path):
    a = write_recording(tmp_path / "a", n=2, seed=1)
    b = write_recording(tmp_path / "b", n=3, seed=2)
    both = data.load_recordings(f"{a},{b}")
    assert len(both) == 5 and both.ids[0] == "a/000000" and both.ids[-1] == "b/000002"
    assert np.array_equal(both.rgb[2:], data.load_recording(b).rgb)
    meta = json.loads((b / "recording.json").read_text())
    meta["dtof"]["zone_rects_px"][0] = [0.0, 0.0, 2.0, 2.0]
    (b / "recording.json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match="differ"):
        data.load_recordings([a, b])


def test_resume_switch_train_keeps_schedule_and_uses_new_set(tmp_path, capsys):
    a = write_recording(tmp_path / "a", n=3, seed=1)
    b = write_recording(tmp_path / "b", n=4, seed=2)
    T.main(_args(a, tmp_path / "run", "--stop-after", "2"))
    T.main(_args(f"{a},{b}", tmp_path / "run", "--resume", "--test", str(a)))  # without the flag: checkpoint's set
    assert "using the checkpoint's train" in capsys.readouterr().out
    T.main(_args(a, tmp_path / "run2", "--stop-after", "2"))
    T.main(_args(f"{a},{b}", tmp_path / "run2", "--resume", "--switch-train", "--test", str(a)))
    out = capsys.readouterr().out
    assert "training set switched" in out and "data: 7 train" in out
    ck = torch.load(tmp_path / "run2" / "ckpt.pt", weights_only=False)
    assert ck["step"] == 3 and ck["args"]["train"] == f"{a},{b}"


def test_resample_matches_eval_mapping(tmp_path):
    """Resampling to half size: nearest depth x0 + ((2x + 1)·cw) // (2W), zone centres mapped
    with pixel centres at integers, and a separate cache per size."""
    root = write_recording(tmp_path / "rec", n=2)
    full = data.load_recording(root)
    half = data.load_recording(root, size=(H // 2, W // 2))
    assert half.rgb.shape == (2, H // 2, W // 2, 3) and half.depth_mm.shape == (2, H // 2, W // 2)
    assert np.array_equal(half.depth_mm, full.depth_mm[:, 1::2][:, :, 1::2])
    # centre (6, 9) → (6.5·0.5 − 0.5, 9.5·0.5 − 0.5) = (2.75, 4.25) → pixel (3, 4)
    assert tuple(half.zone_px[0]) == (3, 4)
    assert (root / f".depthor-train-cache-{H // 2}x{W // 2}.npz").exists()
    again = data.load_recording(root, size=(H // 2, W // 2))
    assert np.array_equal(again.rgb, half.rgb)
    assert data.load_recording(root, size=(H, W)).rgb.shape == full.rgb.shape
    # another aspect ratio: centred crop
    assert data._centre_crop(40, 60, 20, 20) == (0, 10, 40, 40)


def test_prior_stage_trains_only_the_prior_then_depthor_starts_from_it(tmp_path):
    """`--stage prior` moves the prior's weights (and its BN statistics) and nothing else, logs
    the affine-invariant loss alone, and the `depthor` stage can `--init` from its weights."""
    rec_dir = write_recording(tmp_path / "rec", n=5)
    T.main(_args(rec_dir, tmp_path / "init", "--steps", "1", "--max-lr", "1e-9"))
    start = torch.load(tmp_path / "init" / "model_final.pt")
    T.main(_args(rec_dir, tmp_path / "prior", "--stage", "prior",
                 "--init", str(tmp_path / "init" / "model_final.pt")))
    after = torch.load(tmp_path / "prior" / "model_final.pt")
    moved = {k for k in start if not torch.equal(start[k], after[k])}
    assert moved and all(k.startswith("prior.") for k in moved), sorted(moved)[:5]
    assert any(k.endswith(".weight") for k in moved)
    with (tmp_path / "prior" / "train.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert rows and all(r["silog"] == "" and float(r["loss"]) == float(r["prior"]) for r in rows)
    with (tmp_path / "prior" / "eval.csv").open() as f:
        assert float(list(csv.DictReader(f))[-1]["prior_ssi"]) > 0.0
    T.main(_args(rec_dir, tmp_path / "main", "--init", str(tmp_path / "prior" / "model_final.pt")))
    final = torch.load(tmp_path / "main" / "model_final.pt")
    assert any(not torch.equal(after[k], final[k]) for k in after if not k.startswith("prior."))


def test_prefetch_trains_the_same_batches(tmp_path):
    """`--prefetch` (next batch assembled in a thread) gives the weights of a plain run."""
    rec_dir = write_recording(tmp_path / "rec", n=5)
    T.main(_args(rec_dir, tmp_path / "plain", "--augment"))
    T.main(_args(rec_dir, tmp_path / "pre", "--augment", "--prefetch"))
    a = torch.load(tmp_path / "plain" / "model_final.pt")
    b = torch.load(tmp_path / "pre" / "model_final.pt")
    for k in a:
        assert torch.equal(a[k], b[k]), k
