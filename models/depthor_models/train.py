"""Trains a DEPTHOR variant on simulated recordings (paper sec. 3.3 and supplement "Training Setting").

    python -m depthor_models.train --train /work/data/mcu_train --test /work/data/mcu_test \
        --out runs/mcu --steps 2000 [--resume]

Recipe: scaled SILog loss (α = 10, λ = 0.85) on pixels whose reference depth is inside the
sensor's theoretical range (0.1, 10) m; AdamW (weight decay 0.1); gradient l2-norm clipping at 0.1;
OneCycle (initial lr = max/25, final lr = max/100).

Two stages (`--stage`), run in this order:
- `prior`: the monocular prior alone (`net.prior`; every other weight frozen and not run), with
  the scale-and-shift-invariant loss on its inverse depth D_inv (MiDaS style) as the only loss.
- `depthor` (default): the whole network, `--init` from the prior stage's weights. The prior keeps
  the same affine-invariant loss as an auxiliary term (weight `--prior-weight`) and also receives
  the main loss's gradients through the depth encoder input and F_mde.

The run folder holds `ckpt.pt` (model, optimizer, scheduler, step, RNG states, arguments; written
atomically every `--ckpt-every-s` seconds, on SIGTERM/SIGINT and at the end), `train.csv` (one row
per step), `eval.csv` (held-out metrics at every checkpoint, with the zone baselines) and
`loss.png`. Batches are a pure function of (seed, step), so `--resume` continues exactly where the
last checkpoint left off, whatever killed the run.

With `--schedule-s T` the same OneCycle runs over T seconds of training (the summed step times,
kept in the checkpoint) instead of `--steps` steps, and training stops there: on a shared CPU
whose speed is not known in advance the schedule still completes. Batches stay a function of
(seed, step); the learning rate then also depends on the measured step times.

Scale-out (models/README.md "Distributed training"): `torchrun --nproc-per-node N -m
depthor_models.train …` runs data-parallel (DistributedDataParallel; gloo on CPU, nccl on CUDA;
`--device`). `--batch` is the global batch: each process takes an equal slice of the same
(seed, step) plan, and losses and batch-norm statistics are those of the whole batch
(`dist`), so N processes train what one process trains, step for step, and the schedule is a
function of the global step. Rank 0 writes the checkpoint and the logs and evaluates;
`--resume` works with any process count that divides the batch. `--data stream` decodes
frames in DataLoader workers instead of holding the set in memory.

`--prefetch` assembles and augments the next batch in a thread while a step trains (the same
batches), so that on a GPU the CPU side (≈ 67 ms per batch of 64 on a 2-core machine here)
overlaps the step instead of adding to it.

`--qat` trains quantisation-aware (`qat.FakeQuant`: the int8 rounding of the host quantizer in
the forward pass, batch norm on its running statistics); the tracked ranges are kept in the
checkpoint and in `qat_ranges.json` (for `depthor quantize --ranges-file`), `model_final.pt`
stays the float weights the export takes. `--qat-float-p P` trains the float network (batch norm
still on its running statistics) on a share P of the steps, so that the float reference and the
int8 blob stay alike.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import signal
import time
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from . import data, dist, qat
from .net import VARIANTS, Depthor, build, parse_overrides

MIN_DEPTH_M = 0.1
MAX_DEPTH_M = 10.0
TRAIN_FIELDS = ["step", "wall_s", "lr", "loss", "silog", "prior", "kd", "grad_norm"]
STAGES = ("depthor", "prior")
EVAL_FIELDS = ["step", "wall_s", "frames", "prior_ssi", "model_rmse", "model_delta1", "model_rel",
               "bilinear_rmse", "bilinear_delta1", "bilinear_rel",
               "nearest_rmse", "nearest_delta1", "nearest_rel"]


# ----------------------------------------------------------------------------------- losses

def valid_mask(gt: Tensor, lo: float = MIN_DEPTH_M, hi: float = MAX_DEPTH_M) -> Tensor:
    """Pixels whose reference depth lies strictly inside (lo, hi) metres."""
    return (gt > lo) & (gt < hi)


def silog_stats(pred: Tensor, gt: Tensor, lo: float = MIN_DEPTH_M,
                hi: float = MAX_DEPTH_M) -> Tensor:
    """(Σ g², Σ g, count), g = log pred − log gt over the valid pixels: the sums SILog is a
    function of, so that batches split over processes add up (`silog_from_stats`)."""
    m = valid_mask(gt, lo, hi)
    if not bool(m.any()):
        z = pred.sum() * 0.0
        return torch.stack([z, z, z.detach()])
    g = torch.log(pred[m].clamp_min(1e-3)) - torch.log(gt[m])
    return torch.stack([(g * g).sum(), g.sum(), g.new_tensor(float(g.numel()))])


def silog_from_stats(s: Tensor, alpha: float = 10.0, lam: float = 0.85) -> Tensor:
    """α·sqrt(mean g² − λ·(mean g)²) from `silog_stats` sums; 0 (with a graph) for no pixel."""
    n = float(s[2].detach())
    if n == 0:
        return s[0] * 0.0
    d = s[0] / n - lam * (s[1] / n) ** 2
    return alpha * torch.sqrt(d.clamp_min(1e-12))


def silog_loss(pred: Tensor, gt: Tensor, alpha: float = 10.0, lam: float = 0.85,
               lo: float = MIN_DEPTH_M, hi: float = MAX_DEPTH_M) -> Tensor:
    """α·sqrt(mean g² − λ·(mean g)²), g = log pred − log gt over the batch's valid pixels
    (paper eq. loss). Returns 0 (with a graph) when no pixel is valid."""
    return silog_from_stats(silog_stats(pred, gt, lo, hi), alpha, lam)


def _normalise(x: Tensor) -> Tensor:
    t = x.median()
    s = (x - t).abs().mean().clamp_min(1e-6)
    return (x - t) / s


def ssi_stats(d_inv: Tensor, gt: Tensor, lo: float = MIN_DEPTH_M,
              hi: float = MAX_DEPTH_M) -> Tensor:
    """(Σ per-image loss, images) of `ssi_inverse_loss` (see there), summable over processes."""
    losses = []
    for b in range(d_inv.shape[0]):
        m = valid_mask(gt[b], lo, hi)
        if int(m.sum()) < 16:
            continue
        p = _normalise(d_inv[b][m])
        g = _normalise(1.0 / gt[b][m])
        losses.append((p - g).abs().mean())
    if not losses:
        z = d_inv.sum() * 0.0
        return torch.stack([z, z.detach()])
    return torch.stack([torch.stack(losses).sum(), d_inv.new_tensor(float(len(losses)))])


def ssi_from_stats(s: Tensor) -> Tensor:
    """The mean per-image loss from `ssi_stats` sums; 0 (with a graph) for no image."""
    n = float(s[1].detach())
    return s[0] * 0.0 if n == 0 else s[0] / n


def ssi_inverse_loss(d_inv: Tensor, gt: Tensor, lo: float = MIN_DEPTH_M,
                     hi: float = MAX_DEPTH_M) -> Tensor:
    """MiDaS-style affine-invariant loss: per image, the prediction and the reference inverse
    depth 1/gt over valid pixels are each shifted by their median and scaled by their mean
    absolute deviation, then compared with the mean absolute difference; averaged over images
    with at least 16 valid pixels."""
    return ssi_from_stats(ssi_stats(d_inv, gt, lo, hi))


# ---------------------------------------------------------------------------------- metrics

def metrics(pred: np.ndarray, gt: np.ndarray, lo: float = MIN_DEPTH_M,
            hi: float = MAX_DEPTH_M) -> dict[str, float]:
    """Per-image RMSE (m), δ1 (max(p/g, g/p) < 1.25) and Rel over pixels with gt in (lo, hi),
    averaged over the images that have any such pixel. pred, gt: [N, H, W]."""
    rmse, d1, rel = [], [], []
    for p, g in zip(pred, gt):
        m = (g > lo) & (g < hi)
        if not m.any():
            continue
        pm, gm = np.maximum(p[m].astype(np.float64), 1e-3), g[m].astype(np.float64)
        rmse.append(math.sqrt(float(np.mean((pm - gm) ** 2))))
        d1.append(float(np.mean(np.maximum(pm / gm, gm / pm) < 1.25)))
        rel.append(float(np.mean(np.abs(pm - gm) / gm)))
    return {"rmse": float(np.mean(rmse)), "delta1": float(np.mean(d1)), "rel": float(np.mean(rel))}


def zone_baselines(rec: data.Recording, idx: np.ndarray,
                   valid_status: tuple[int, ...] = (5,)) -> dict[str, np.ndarray]:
    """Classical references from the zones alone, [N, H, W] metres each:
    `nearest` = the distance of the nearest valid zone pixel; `bilinear` = bilinear interpolation
    over the zone grid (nodes at the zones' pixels, clamped outside them) using only valid zones
    (weights renormalised), falling back to `nearest` where all four neighbours are invalid.
    A frame without any valid zone gets 1 m everywhere."""
    rows, cols = rec.grid
    h, w = rec.height, rec.width
    px = rec.zone_px.astype(np.float64)
    inside = rec.zone_px[:, 0] >= 0
    yy, xx = np.meshgrid(np.arange(h, dtype=np.float64), np.arange(w, dtype=np.float64),
                         indexing="ij")
    # nearest: each pixel's zones by distance (the closest `k` kept; a frame whose valid zones
    # are all farther falls back to every zone), so a 40×30 grid does not hold H·W·Z distances
    flat_y, flat_x = yy.reshape(-1), xx.reshape(-1)
    k = min(16, len(px))
    order = np.empty((h * w, k), np.int64)
    kth_d2 = np.empty(h * w)  # the k-th smallest distance: a pick below it is exact
    chunk = max(1, 8_000_000 // len(px))
    for a in range(0, h * w, chunk):
        d2 = (flat_y[a:a + chunk, None] - px[None, :, 0]) ** 2 \
            + (flat_x[a:a + chunk, None] - px[None, :, 1]) ** 2
        part = np.argpartition(d2, k - 1, axis=1)[:, :k] if k < len(px) else \
            np.broadcast_to(np.arange(len(px)), d2.shape)
        near_d2 = np.take_along_axis(d2, part, 1)
        sort = np.lexsort((part, near_d2), axis=1)
        order[a:a + chunk] = np.take_along_axis(part, sort, 1)
        kth_d2[a:a + chunk] = near_d2.max(1)
    # bilinear: grid node coordinates per row / column (zones' pixels, averaged along the grid)
    gy = px[:, 0].reshape(rows, cols).mean(axis=1)
    gx = px[:, 1].reshape(rows, cols).mean(axis=0)
    fy = np.interp(yy[:, 0], gy, np.arange(rows, dtype=np.float64))
    fx = np.interp(xx[0], gx, np.arange(cols, dtype=np.float64))
    r0 = np.clip(np.floor(fy).astype(np.int64), 0, max(rows - 2, 0))
    c0 = np.clip(np.floor(fx).astype(np.int64), 0, max(cols - 2, 0))
    ty, tx = fy - r0, fx - c0
    r1, c1 = np.minimum(r0 + 1, rows - 1), np.minimum(c0 + 1, cols - 1)
    corners = [(r0, c0, (1 - ty)[:, None] * (1 - tx)[None, :]),
               (r0, c1, (1 - ty)[:, None] * tx[None, :]),
               (r1, c0, ty[:, None] * (1 - tx)[None, :]),
               (r1, c1, ty[:, None] * tx[None, :])]
    near, bil = [], []
    for i in np.asarray(idx, dtype=np.int64):
        ok = np.isin(rec.status[i], valid_status) & inside & (rec.zone_m[i] > 0)
        if not ok.any():
            near.append(np.ones((h, w), np.float32))
            bil.append(np.ones((h, w), np.float32))
            continue
        z = rec.zone_m[i].astype(np.float64)
        ok_k = ok[order]
        nz = order[np.arange(h * w), ok_k.argmax(1)]
        pick_d2 = (flat_y - px[nz, 0]) ** 2 + (flat_x - px[nz, 1]) ** 2
        miss = ~ok_k.any(1) | (pick_d2 >= kth_d2)
        if miss.any():  # no valid zone among the closest k, or one tied with the k-th: all valid
            d2 = (flat_y[miss, None] - px[None, ok, 0]) ** 2 \
                + (flat_x[miss, None] - px[None, ok, 1]) ** 2
            nz[miss] = np.flatnonzero(ok)[d2.argmin(1)]
        nz = nz.reshape(h, w)
        n_map = z[nz]
        grid_v = z.reshape(rows, cols)
        grid_ok = ok.reshape(rows, cols).astype(np.float64)
        num = np.zeros((h, w))
        den = np.zeros((h, w))
        for rr, cc, wt in corners:
            k = grid_ok[rr[:, None], cc[None, :]] * wt
            num += k * grid_v[rr[:, None], cc[None, :]]
            den += k
        b_map = np.where(den > 1e-9, num / np.maximum(den, 1e-9), n_map)
        near.append(n_map.astype(np.float32))
        bil.append(b_map.astype(np.float32))
    return {"nearest": np.stack(near), "bilinear": np.stack(bil)}


@torch.no_grad()
def predict(net: Depthor, rec: data.Recording, idx: np.ndarray, batch_size: int = 2,
            valid_status: tuple[int, ...] = (5,)) -> np.ndarray:
    """The network's depth [N, H, W] for frames `idx` (eval mode; restores the previous mode)."""
    was_training = net.training
    net.eval()
    p = next(net.parameters())
    out = []
    for s in range(0, len(idx), batch_size):
        rgb, sp, _ = data.batch(rec, idx[s:s + batch_size], None, valid_status)
        depth = net(rgb.to(p.device, p.dtype), sp.to(p.device, p.dtype))[:, 0]
        out.append(depth.float().cpu().numpy())
    net.train(was_training)
    return np.concatenate(out)


@torch.no_grad()
def prior_ssi(net: Depthor, rec: data.Recording, idx: np.ndarray, batch_size: int = 4) -> float:
    """The prior's affine-invariant loss (`ssi_inverse_loss`) on frames `idx`: the batches' losses
    weighted by batch size (eval mode; restores the previous mode)."""
    was_training = net.training
    net.eval()
    p = next(net.parameters())
    total, n = 0.0, 0
    for s in range(0, len(idx), batch_size):
        rgb, _, gt = data.batch(rec, idx[s:s + batch_size], None)
        d_inv, _ = net.prior(rgb.to(p.device, p.dtype))
        total += float(ssi_inverse_loss(d_inv, gt.to(p.device, p.dtype))) * len(rgb)
        n += len(rgb)
    net.train(was_training)
    return total / max(n, 1)


class Evaluator:
    """Held-out evaluation: the zone baselines are computed once, the model at every call."""

    def __init__(self, rec: data.Recording, frames: int, valid_status: tuple[int, ...] = (5,)):
        self.rec = rec
        self.idx = np.arange(min(frames, len(rec)) if frames > 0 else len(rec))
        self.valid_status = valid_status
        self.gt = rec.depth_mm[self.idx].astype(np.float32) / 1000.0
        base = zone_baselines(rec, self.idx, valid_status)
        self.base = {k: metrics(v, self.gt) for k, v in base.items()}

    def __call__(self, net: Depthor) -> dict[str, float]:
        m = metrics(predict(net, self.rec, self.idx, valid_status=self.valid_status), self.gt)
        row = {"frames": len(self.idx),
               "prior_ssi": prior_ssi(net, self.rec, self.idx) if hasattr(net, "prior") else ""}
        for name, res in [("model", m), *self.base.items()]:
            for k, v in res.items():
                row[f"{name}_{k}"] = v
        return row


# ------------------------------------------------------- augmentation and distillation

def _gauss_kernel(sigma: float) -> Tensor:
    r = max(1, int(math.ceil(2.0 * sigma)))
    x = torch.arange(-r, r + 1, dtype=torch.float32)
    k = torch.exp(-x * x / (2.0 * sigma * sigma))
    return k / k.sum()


def _photometric_params(rng: np.random.Generator, p: float) -> dict | None:
    """One image's draws of `photometric`, in the order they are taken (None: left as is)."""
    if rng.random() >= p:
        return None
    prm = {"gain": rng.uniform(0.6, 1.5) * rng.uniform(0.85, 1.15, size=3),
           "contrast": rng.uniform(0.7, 1.3), "saturation": rng.uniform(0.5, 1.4),
           "gamma": float(rng.uniform(0.7, 1.45))}
    prm["vignette"] = rng.uniform(0.1, 0.5) if rng.random() < 0.3 else None
    prm["blur"] = float(rng.uniform(0.4, 1.3)) if rng.random() < 0.3 else None
    prm["jpeg"] = int(rng.integers(30, 90)) if rng.random() < 0.2 else None
    prm["shot"], prm["read"] = rng.uniform(0.0, 0.01), rng.uniform(0.0, 0.02)
    prm["noise_seed"] = int(rng.integers(0, 2**31))
    return prm


def _photometric_apply(x: Tensor, prm: dict) -> Tensor:
    """`photometric` on one image [3,H,W] with its drawn parameters."""
    from io import BytesIO

    from PIL import Image

    _, h, w = x.shape
    x = x * torch.tensor(prm["gain"], dtype=x.dtype).view(3, 1, 1)
    m = x.mean()
    x = (x - m) * prm["contrast"] + m
    grey = (0.299 * x[0] + 0.587 * x[1] + 0.114 * x[2])[None]
    x = (grey + (x - grey) * prm["saturation"]).clamp(0.0, 1.0)
    x = x ** prm["gamma"]
    if prm["vignette"] is not None:
        yy = torch.linspace(-1, 1, h).view(h, 1)
        xx = torch.linspace(-1, 1, w).view(1, w)
        x = x * (1.0 - prm["vignette"] * (yy * yy + xx * xx) / 2.0)
    if prm["blur"] is not None:  # defocus / motion-free blur
        k = _gauss_kernel(prm["blur"])
        r = len(k) // 2
        xp = torch.nn.functional.pad(x[None], (r, r, r, r), mode="replicate")
        xp = torch.nn.functional.conv2d(xp, k.view(1, 1, 1, -1).repeat(3, 1, 1, 1), groups=3)
        x = torch.nn.functional.conv2d(xp, k.view(1, 1, -1, 1).repeat(3, 1, 1, 1), groups=3)[0]
    if prm["jpeg"] is not None:
        arr = (x.clamp(0, 1) * 255).round().byte().permute(1, 2, 0).numpy()
        buf = BytesIO()
        Image.fromarray(arr).save(buf, "JPEG", quality=prm["jpeg"])
        buf.seek(0)
        with Image.open(buf) as im:
            x = torch.from_numpy(np.asarray(im.convert("RGB"), np.float32) / 255.0)
        x = x.permute(2, 0, 1)
    a, b = prm["shot"], prm["read"]  # shot + read noise
    g = torch.Generator().manual_seed(prm["noise_seed"])
    sd = torch.sqrt(a * x.clamp_min(0) + b * b)
    x = x + sd * torch.randn(x.shape, generator=g)
    return (x.clamp(0.0, 1.0) * 255.0).round() / 255.0


def photometric(rgb: Tensor, seed: int, step: int, p: float = 0.8, first: int = 0) -> Tensor:
    """RGB-only photometric / sensor augmentation against the sim-to-real gap, a pure function
    of (seed, step): each image of the batch, with probability `p`, gets exposure gain, white
    balance (per-channel gain), contrast, saturation, gamma, then with their own probabilities
    vignetting, Gaussian blur, JPEG re-encoding and signal-dependent noise; the result is
    rounded to 8 bits as a camera frame is. Sparse input and reference are not touched.
    `rgb` may be the images `first … first + len(rgb) − 1` of a larger batch (one process's
    share of the global batch): they get what they would get in the whole batch."""
    rng = np.random.default_rng([seed, 3_000_000, step])
    out = []
    for b in range(first + len(rgb)):
        prm = _photometric_params(rng, p)
        if b < first:
            continue
        x = rgb[b - first]
        out.append(x if prm is None else _photometric_apply(x, prm))
    return torch.stack(out)


class TeacherCache:
    """Dense depth of a trained teacher network for every training frame (un-flipped, clean
    RGB), computed lazily the first time a frame is drawn and kept as float16; `save`/`load`
    keep it across resumes (`<run>/teacher_cache.npy` + `.done.npy`)."""

    def __init__(self, teacher, rec: data.Recording, path: Path,
                 valid_status: tuple[int, ...] = (5,)):
        self.teacher, self.rec, self.path = teacher.eval(), rec, Path(path)
        self.valid_status = valid_status
        self.done_path = self.path.with_name(self.path.stem + ".done.npy")
        n, h, w = len(rec), rec.height, rec.width
        if self.path.exists() and self.done_path.exists():
            self.depth = np.load(self.path)
            self.done = np.load(self.done_path)
            if self.depth.shape != (n, h, w):
                raise ValueError(f"{self.path}: shape {self.depth.shape}, expected {(n, h, w)}")
        else:
            self.depth = np.zeros((n, h, w), np.float16)
            self.done = np.zeros(n, bool)

    @torch.no_grad()
    def get(self, idx: np.ndarray, flips: np.ndarray | None) -> Tensor:
        """Teacher depth [B,1,H,W] m of frames `idx`, mirrored where `flips`."""
        idx = np.asarray(idx, np.int64)
        todo = np.unique(idx[~self.done[idx]])
        if len(todo):
            rgb, sp, _ = data.batch(self.rec, todo, None, self.valid_status)
            dev = next(self.teacher.parameters()).device
            out = self.teacher(rgb.to(dev), sp.to(dev))[:, 0].cpu().numpy()
            self.depth[todo] = out.astype(np.float16)
            self.done[todo] = True
        d = self.depth[idx].astype(np.float32)
        if flips is not None:
            f = np.asarray(flips, bool)
            d[f] = d[f][:, :, ::-1]
        return torch.from_numpy(np.ascontiguousarray(d[:, None]))

    def save(self) -> None:
        """Writes the cache atomically (depth first, then the done flags)."""
        for arr, p in ((self.depth, self.path), (self.done, self.done_path)):
            tmp = p.with_name(p.stem + ".tmp.npy")
            np.save(tmp, arr)
            os.replace(tmp, p)


def load_teacher(variant: str, weights: str | Path):
    """The distillation teacher: a trained variant (e.g. the shipped `mcu`), eval mode, frozen."""
    net = build(variant, calibrate_bn=False)
    net.load_state_dict(load_weights(weights))
    return net.eval().requires_grad_(False)


# --------------------------------------------------------------------------------- training

def batch_plan(seed: int, step: int, batch_size: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Frame indices and flip flags of training step `step`: epochs are seeded permutations of
    the n frames walked in order; flips are drawn from the (seed, step) stream."""
    k = step * batch_size + np.arange(batch_size)
    epochs, pos = k // n, k % n
    idx = np.empty(batch_size, np.int64)
    for e in np.unique(epochs):
        perm = np.random.default_rng([seed, int(e)]).permutation(n)
        sel = epochs == e
        idx[sel] = perm[pos[sel]]
    flips = np.random.default_rng([seed, 1_000_000, step]).random(batch_size) < 0.5
    return idx, flips


def crop_plan(seed: int, step: int, height: int, width: int,
              crop: tuple[int, int] | None) -> tuple[int, int, int, int]:
    """(y0, x0, h, w) of training step `step`'s random crop (the same window for the whole
    batch), drawn from the (seed, step) stream; the full frame when `crop` is None or not
    smaller than the frame."""
    if crop is None:
        return 0, 0, height, width
    ch, cw = min(crop[0], height), min(crop[1], width)
    rng = np.random.default_rng([seed, 2_000_000, step])
    return int(rng.integers(0, height - ch + 1)), int(rng.integers(0, width - cw + 1)), ch, cw


def parse_crop(text: str | None) -> tuple[int, int] | None:
    """`HxW` (both multiples of 32, the network's total stride) → (H, W); None for no crop."""
    if not text:
        return None
    try:
        h, w = (int(v) for v in text.lower().split("x"))
    except ValueError as e:
        raise ValueError(f"--crop {text!r}: expected HxW, e.g. 224x192") from e
    if h <= 0 or w <= 0 or h % 32 or w % 32:
        raise ValueError(f"--crop {text!r}: H and W must be positive multiples of 32")
    return h, w


ARCHS = ("depthor", "sparse_to_dense")


def make_model(variant: str, seed: int, overrides: dict | None = None,
               arch: str = "depthor") -> torch.nn.Module:
    """A fresh trainable network: default PyTorch init (no random BN calibration), train mode;
    `overrides`: NetConfig fields that differ from the variant's (`--set`). `arch
    "sparse_to_dense"`: the learned baseline of `sparse_to_dense.py` instead of a DEPTHOR
    variant (`variant` ignored, `overrides` are its S2DConfig fields); it has no prior, so the
    prior's loss and evaluation are skipped for it."""
    if arch == "sparse_to_dense":
        from . import sparse_to_dense

        return sparse_to_dense.build(seed, **(overrides or {}))
    if arch != "depthor":
        raise ValueError(f"unknown --arch {arch!r} (one of {ARCHS})")
    net = build(variant, seed=seed, calibrate_bn=False, **(overrides or {}))
    return net.train()


# Learning-rate multiplier of the zone prior's gate (make_optim).
ZONE_PRIOR_LR_SCALE = 100.0


def make_optim(net: Depthor, max_lr: float, steps: int, weight_decay: float = 0.1):
    """AdamW + OneCycle (initial max/25, final max/100, 30 % warm-up, cosine). A zone prior's
    gate (new on trained weights, a handful of parameters) learns at ZONE_PRIOR_LR_SCALE × the
    rate, without weight decay (`lr_scale` in its group)."""
    zp = [p for n, p in net.named_parameters() if n.startswith("zone_prior.")]
    ids = {id(p) for p in zp}
    rest = [p for p in net.parameters() if id(p) not in ids]
    groups = [{"params": rest, "lr_scale": 1.0}]
    if zp:
        groups.append({"params": zp, "lr_scale": ZONE_PRIOR_LR_SCALE, "weight_decay": 0.0})
    opt = torch.optim.AdamW(groups, lr=max_lr / 25.0, weight_decay=weight_decay)
    sched = torch.optim.lr_scheduler.OneCycleLR(
        opt, max_lr=[max_lr * g["lr_scale"] for g in groups], total_steps=steps,
        div_factor=25.0, final_div_factor=4.0)
    return opt, sched


def onecycle_at(progress: float, max_lr: float, pct_start: float = 0.3, div: float = 25.0,
                final_div: float = 4.0, base_beta1: float = 0.85,
                max_beta1: float = 0.95) -> tuple[float, float]:
    """(lr, AdamW β1) of `make_optim`'s OneCycle (cosine phases, momentum cycled like
    torch's OneCycleLR) at `progress` in [0, 1] of the schedule: lr max/25 → max over the first
    `pct_start`, then → max/25/4 (= max/100); β1 0.95 → 0.85 → 0.95."""
    p = min(max(progress, 0.0), 1.0)
    initial = max_lr / div
    final = initial / final_div

    def cos(a: float, b: float, t: float) -> float:
        return b + (a - b) / 2.0 * (1.0 + math.cos(math.pi * t))

    if p <= pct_start:
        t = p / pct_start
        return cos(initial, max_lr, t), cos(max_beta1, base_beta1, t)
    t = (p - pct_start) / (1.0 - pct_start)
    return cos(max_lr, final, t), cos(base_beta1, max_beta1, t)


def load_weights(path: str | Path) -> dict[str, Tensor]:
    """A model state dict from a checkpoint (`{"model": ...}`) or a plain state-dict file."""
    obj = torch.load(path, map_location="cpu", weights_only=False)
    return obj["model"] if isinstance(obj, dict) and "model" in obj else obj


def _atomic_save(obj, path: Path) -> None:
    tmp = path.with_name(path.name + ".tmp")
    torch.save(obj, tmp)
    os.replace(tmp, path)


def _rewrite_csv(path: Path, fields: list[str], keep_below: int) -> None:
    """Creates the CSV with a header, or drops rows at or beyond step `keep_below` (written
    after the checkpoint a resumed run starts from)."""
    rows = []
    if path.exists():
        with path.open() as f:
            rows = [r for r in csv.DictReader(f) if int(r["step"]) < keep_below]
    with path.open("w", newline="") as f:
        wr = csv.DictWriter(f, fields)
        wr.writeheader()
        wr.writerows(rows)


def _append(path: Path, fields: list[str], row: dict) -> None:
    with path.open("a", newline="") as f:
        csv.DictWriter(f, fields).writerow({k: row.get(k, "") for k in fields})


class Stop:
    """Set by SIGTERM/SIGINT: the loop checkpoints and exits at the end of the current step."""

    def __init__(self):
        self.flag = False
        self._old = {s: signal.signal(s, self._set) for s in (signal.SIGTERM, signal.SIGINT)}

    def _set(self, *_):
        self.flag = True

    def close(self) -> None:
        """Puts the previous handlers back."""
        for s, h in self._old.items():
            signal.signal(s, h)


class StepBatches(torch.utils.data.Sampler):
    """Batch sampler of training steps `start … stop − 1`: for each, this rank's share of the
    global batch of `batch_plan` as `(frame, flip)` pairs (rank r of `world` takes the r-th of
    `world` equal contiguous slices), for a DataLoader over `data.FrameDataset`."""

    def __init__(self, seed: int, start: int, stop: int, batch_size: int, n: int,
                 rank: int = 0, world: int = 1):
        if batch_size % world:
            raise ValueError(f"--batch {batch_size}: not a multiple of the {world} processes")
        self.seed, self.start, self.stop, self.batch, self.n = seed, start, stop, batch_size, n
        self.rank, self.world = rank, world

    def __len__(self) -> int:
        return max(self.stop - self.start, 0)

    def share(self, step: int) -> tuple[np.ndarray, np.ndarray]:
        """(frame indices, flips) of this rank's slice of step `step`'s global batch."""
        idx, flips = batch_plan(self.seed, step, self.batch, self.n)
        b = self.batch // self.world
        return idx[self.rank * b:(self.rank + 1) * b], flips[self.rank * b:(self.rank + 1) * b]

    def __iter__(self):
        for step in range(self.start, self.stop):
            idx, flips = self.share(step)
            yield [(int(i), bool(f)) for i, f in zip(idx, flips)]


def _load_data(args, size, d: dist.Dist):
    """(training source, held-out Recording or None): the source is an in-memory Recording
    (`--data memory`, npz cache) or a `data.FrameReader` (`--data stream`); the held-out set
    is loaded on rank 0 only (the first --eval-frames frames when streaming)."""
    if args.data == "stream":
        train_src = data.FrameReader(args.train, size=size)
        test_rec = None
        if d.main:
            reader = data.FrameReader(args.test, size=size)
            k = min(args.eval_frames, len(reader)) if args.eval_frames > 0 else len(reader)
            test_rec = reader.recording(range(k))
        return train_src, test_rec
    # Rank 0 first: it writes the caches the others then read.
    for turn in ((0,), tuple(range(1, d.world))):
        if d.rank in turn:
            train_src = data.load_recordings(args.train, size=size)
            test_rec = data.load_recordings(args.test, size=size) if d.main else None
        if d.world > 1:
            dist.agree([0.0], d)
    return train_src, test_rec


def train(args: argparse.Namespace) -> dict:
    """Runs (or resumes) training as configured by the CLI arguments; returns the last eval row
    (on rank 0; {} on the other ranks of a torchrun job)."""
    torch.set_num_threads(args.threads)
    d = dist.setup(getattr(args, "device", None))
    try:
        row = _train(args, d)
    except BaseException:
        dist.close(d, wait=False)  # torchrun ends the other ranks
        raise
    dist.close(d)
    return row


def float_step(seed: int, step: int, p: float) -> bool:
    """Whether step `step` of a `--qat` run trains the float network (`--qat-float-p`): a
    draw from (seed, step), so a resumed run repeats it."""
    if p <= 0.0:
        return False
    return np.random.default_rng([seed, step, 0x9A7]).random() < p


def _train(args: argparse.Namespace, d: dist.Dist) -> dict:
    say = print if d.main else (lambda *a, **k: None)
    out = Path(args.out)
    if d.main:
        out.mkdir(parents=True, exist_ok=True)
    ckpt_path = out / "ckpt.pt"
    arch = getattr(args, "arch", "depthor")
    net = make_model(args.variant, args.seed, parse_overrides(getattr(args, "set", None) or []),
                     arch)
    has_prior = hasattr(net, "prior")
    prior_only = args.stage == "prior"
    if not has_prior and (prior_only or getattr(args, "qat", False)):
        raise ValueError(f"--arch {arch}: no prior stage and no --qat (float baseline only)")
    trained = net.prior if prior_only else net
    net.requires_grad_(not prior_only)
    trained.requires_grad_(True)
    dtype = getattr(torch, getattr(args, "dtype", "float32"))
    net.to(d.device, dtype)
    opt, sched = make_optim(trained, args.max_lr, args.steps, args.weight_decay)
    step, wall = 0, 0.0
    if args.resume and ckpt_path.exists():
        ck = torch.load(ckpt_path, map_location="cpu", weights_only=False)
        net.load_state_dict(ck["model"])
        opt.load_state_dict(ck["optimizer"])
        sched.load_state_dict(ck["scheduler"])
        step, wall = int(ck["step"]), float(ck["wall_s"])
        torch.set_rng_state(ck["rng"]["torch"])
        saved = {"schedule_s": 0.0, **ck["args"]}  # checkpoints from before --schedule-s
        saved.setdefault("stage", "depthor")  # checkpoints from before --stage
        saved.setdefault("arch", "depthor")  # checkpoints from before --arch
        forced = ("variant", "seed", "batch", "steps", "max_lr", "train", "schedule_s", "crop",
                  "stage", "arch")
        for k in forced:
            if k == "train" and args.switch_train:
                if saved.get(k) != args.train:
                    say(f"resume: training set switched from {saved.get(k)!r} to {args.train!r} "
                        f"(batches from step {step} on are drawn from the new set)")
                continue
            if saved.get(k) != getattr(args, k):
                say(f"resume: using the checkpoint's {k}={saved.get(k)!r} "
                    f"(command line said {getattr(args, k)!r})")
                setattr(args, k, saved.get(k))
        was = int(ck.get("world", 1))
        say(f"resumed from {ckpt_path} at step {step} ({wall:.0f} s trained; written by "
            f"{was} process{'es' if was > 1 else ''}, continued by {d.world})")
    elif args.init:
        missing, unexpected = net.load_state_dict(load_weights(args.init), strict=False)
        new = [k for k in missing if k.startswith("zone_prior.")]
        if unexpected or len(new) != len(missing):
            raise ValueError(f"--init {args.init}: keys missing {sorted(set(missing) - set(new))}, "
                             f"unexpected {sorted(unexpected)}")
        say(f"initialised from {args.init}" + (f" ({len(new)} new zone-prior tensors at their "
                                                "initial values)" if new else ""))
    fq = None
    if getattr(args, "qat", False):
        h, w = net.cfg.height, net.cfg.width
        dev = next(net.parameters()).device
        fq = qat.FakeQuant(net, torch.rand(1, 3, h, w, device=dev, dtype=dtype),
                           torch.zeros(1, 1, h, w, device=dev, dtype=dtype)).attach()
        if args.resume and ckpt_path.exists() and "qat" in ck:
            fq.load_state_dict(ck["qat"])
        say(f"quantisation-aware: {sum(k in ('int8', 'unit') for k in fq.kind)} of "
            f"{len(fq.kind)} node outputs rounded to int8")
    if not args.resume or step == 0:
        torch.manual_seed(args.seed)
    if args.batch % d.world:
        raise ValueError(f"--batch {args.batch}: the global batch must be a multiple of the "
                         f"{d.world} processes")
    if d.main:
        _rewrite_csv(out / "train.csv", TRAIN_FIELDS, step + 1)
        _rewrite_csv(out / "eval.csv", EVAL_FIELDS, step + 1)
        (out / "args.json").write_text(json.dumps(vars(args), indent=1) + "\n")

    crop = parse_crop(args.crop)
    t0 = time.perf_counter()
    size = (net.cfg.height, net.cfg.width)  # frames resampled to the model's input, as in eval
    train_src, test_rec = _load_data(args, size, d)
    evaluator = Evaluator(test_rec, args.eval_frames) if d.main else None
    if d.main:
        say(f"data: {len(train_src)} train / {len(evaluator.idx)} test frames "
            f"({time.perf_counter() - t0:.1f} s, {args.data}); baselines "
            f"{json.dumps(evaluator.base)}")
    if d.world > 1:
        say(f"distributed: {d.world} processes ({d.device.type}), {args.batch // d.world} of "
            f"the global batch {args.batch} each")

    teacher = None
    if args.teacher and not prior_only and args.kd_weight > 0:
        if args.data == "stream":
            raise ValueError("--teacher needs --data memory (its cache covers the frames in "
                             "memory)")
        teacher = TeacherCache(load_teacher(args.teacher_variant, args.teacher).to(d.device),
                               train_src, out / "teacher_cache.npy")
        say(f"distillation from {args.teacher} ({args.teacher_variant}), weight "
            f"{args.kd_weight}; {int(teacher.done.sum())}/{len(train_src)} frames cached")

    captured: dict[str, Tensor] = {}
    if has_prior:
        net.prior.register_forward_hook(lambda _m, _i, o: captured.__setitem__("d_inv", o[0]))
    dist.sync_batchnorm(net, d)
    model = trained
    if d.world > 1:
        from torch.nn.parallel import DistributedDataParallel

        model = DistributedDataParallel(
            trained, device_ids=[d.local_rank] if d.device.type == "cuda" else None,
            broadcast_buffers=False)

    def checkpoint(evaluate: bool) -> dict:
        state = {k: v.cpu() for k, v in net.state_dict().items()}
        _atomic_save({"model": state, "optimizer": opt.state_dict(),
                      "scheduler": sched.state_dict(), "step": step, "wall_s": wall,
                      "rng": {"torch": torch.get_rng_state()}, "args": vars(args),
                      "world": d.world, **({"qat": fq.state_dict()} if fq else {})}, ckpt_path)
        if teacher is not None:
            teacher.save()
        if fq is not None:
            (out / "qat_ranges.json").write_text(json.dumps(fq.ranges_by_name(), indent=1) + "\n")
        row = {}
        if evaluate:
            te = time.perf_counter()
            row = {"step": step, "wall_s": round(wall, 1), **evaluator(net)}
            _append(out / "eval.csv", EVAL_FIELDS, row)
            print(f"step {step}: eval {json.dumps(row)} ({time.perf_counter() - te:.0f} s)",
                  flush=True)
        plot(out)
        return row

    share = StepBatches(args.seed, step, args.steps, args.batch, len(train_src), d.rank, d.world)
    first = d.rank * (args.batch // d.world)
    batches = None
    if args.data == "stream":
        batches = iter(torch.utils.data.DataLoader(
            data.FrameDataset(train_src), batch_sampler=share, num_workers=args.workers,
            prefetch_factor=2 if args.workers > 0 else None))

    def finish_batch(s: int, idx, flips, tensors):
        """Step `s`'s crop and photometric augmentation of its batch (a function of (seed, s))."""
        rgb, sp, gt = tensors
        box = crop_plan(args.seed, s, rgb.shape[2], rgb.shape[3], crop)
        y0, x0, ch, cw = box
        rgb, sp, gt = (t[:, :, y0:y0 + ch, x0:x0 + cw] for t in (rgb, sp, gt))
        if args.augment:
            rgb = photometric(rgb, args.seed, s, args.augment_p, first)
        return idx, flips, box, (rgb, sp, gt)

    def prepare(s: int):
        """Step `s`'s batch from the in-memory set, ready but for the device copy."""
        idx, flips = share.share(s)
        return finish_batch(s, idx, flips, data.batch(train_src, idx, flips))

    # --prefetch: the next step's batch is assembled and augmented in a thread while this one
    # trains (batches are a function of (seed, step), so the result is the same)
    pool = None
    if getattr(args, "prefetch", False) and batches is None:
        from concurrent.futures import ThreadPoolExecutor

        pool = ThreadPoolExecutor(1)
    pending = None

    stop = Stop()
    last_ckpt = time.perf_counter()
    deadline = time.perf_counter() + args.time_limit_s if args.time_limit_s > 0 else math.inf
    stop_at = step + args.stop_after if args.stop_after > 0 else args.steps
    last_row: dict = {}
    net.train()
    by_time = args.schedule_s > 0
    while step < min(args.steps, stop_at):
        # Every rank takes the same decision, on rank 0's clock.
        flag, late, wall = dist.agree([float(stop.flag), float(time.perf_counter() >= deadline),
                                       wall if d.main else 0.0], d)
        if flag or late or (by_time and wall >= args.schedule_s):
            break
        ts = time.perf_counter()
        if batches is None:
            if pending is not None and pending[0] == step:
                idx, flips, (y0, x0, ch, cw), (rgb, sp, gt) = pending[1].result()
            else:
                idx, flips, (y0, x0, ch, cw), (rgb, sp, gt) = prepare(step)
            pending = (step + 1, pool.submit(prepare, step + 1)) if pool is not None else None
        else:
            idx, flips = share.share(step)
            idx, flips, (y0, x0, ch, cw), (rgb, sp, gt) = finish_batch(
                step, idx, flips, next(batches))
        t_depth = None if teacher is None else teacher.get(idx, flips)
        if t_depth is not None:
            t_depth = t_depth[:, :, y0:y0 + ch, x0:x0 + cw].to(d.device, dtype)
        rgb, sp, gt = (t.to(d.device, dtype) for t in (rgb, sp, gt))
        if fq is not None:
            fq.enabled = not float_step(args.seed, step, getattr(args, "qat_float_p", 0.0))
        # Sums over the global batch (one process: the batch's own), then the losses.
        if prior_only:
            parts = [ssi_stats(model(rgb)[0], gt)]
        else:
            pred = model(rgb, sp)
            parts = [silog_stats(pred, gt)]
            if has_prior:
                parts.append(ssi_stats(captured["d_inv"], gt))
            if t_depth is not None:
                parts.append(silog_stats(pred, t_depth))
        sums = dist.all_reduce_sum(torch.cat(parts), d)
        l_kd = None
        if prior_only:
            l_prior = ssi_from_stats(sums)
            l_main, loss = None, l_prior
        else:
            l_main = silog_from_stats(sums[0:3])
            k = 3
            l_prior = None
            loss = l_main
            if has_prior:
                l_prior = ssi_from_stats(sums[3:5])
                loss = loss + args.prior_weight * l_prior
                k = 5
            if t_depth is not None:
                l_kd = silog_from_stats(sums[k:k + 3])
                loss = loss + args.kd_weight * l_kd
        opt.zero_grad(set_to_none=True)
        loss.backward()
        gn = torch.nn.utils.clip_grad_norm_(trained.parameters(), args.clip)
        if by_time:  # OneCycle over training seconds instead of steps
            lr, beta1 = onecycle_at(wall / args.schedule_s, args.max_lr)
            for grp in opt.param_groups:
                grp["lr"] = lr * grp.get("lr_scale", 1.0)
                grp["betas"] = (beta1, grp["betas"][1])
        lr = opt.param_groups[0]["lr"]
        opt.step()
        if not by_time:
            sched.step()
        step += 1
        wall += time.perf_counter() - ts
        if not d.main:
            continue
        _append(out / "train.csv", TRAIN_FIELDS, {
            "step": step, "wall_s": round(wall, 2), "lr": f"{lr:.3e}", "loss": f"{loss.item():.5f}",
            "silog": "" if l_main is None else f"{l_main.item():.5f}",
            "prior": "" if l_prior is None else f"{l_prior.item():.5f}",
            "kd": "" if l_kd is None else f"{l_kd.item():.5f}", "grad_norm": f"{float(gn):.4f}"})
        if step % 10 == 0:
            silog = "-" if l_main is None else f"{l_main.item():.4f}"
            kd = "" if l_kd is None else f" kd {l_kd.item():.4f}"
            prior = "-" if l_prior is None else f"{l_prior.item():.4f}"
            print(f"step {step} loss {loss.item():.4f} silog {silog} "
                  f"prior {prior}{kd} lr {lr:.2e} ({wall:.0f} s)", flush=True)
        if fq is not None:
            fq.enabled = True  # in-run checks and the saved ranges are the int8 network's
        if time.perf_counter() - last_ckpt >= args.ckpt_every_s:
            last_row = checkpoint(evaluate=True) or last_row
            last_ckpt = time.perf_counter()
    stop.close()
    if pool is not None:
        pool.shutdown(wait=True, cancel_futures=True)
    del batches
    if not d.main:
        return {}
    last_row = checkpoint(evaluate=True) or last_row
    torch.save({k: v.cpu() for k, v in net.state_dict().items()}, out / "model_final.pt")
    print(f"stopped at step {step}/{args.steps}; checkpoint {ckpt_path}", flush=True)
    if by_time and step >= args.steps and wall < args.schedule_s:
        print(f"warning: --steps {args.steps} ended the run after {wall:.0f} s of the "
              f"{args.schedule_s:.0f} s schedule, before its learning rate annealed; "
              f"pass a larger --steps with --schedule-s", flush=True)
    return last_row


# ------------------------------------------------------------------------------------- plot

def _read_csv(path: Path) -> list[dict]:
    if not path.exists():
        return []
    with path.open() as f:
        return list(csv.DictReader(f))


def plot(run_dir: str | Path, width: int = 900, height: int = 600) -> Path | None:
    """Writes `<run>/loss.png`: training loss per step (grey) with a moving average (blue) on a
    log scale, and held-out RMSE of the model (red) vs the bilinear zone baseline (green)."""
    from PIL import Image, ImageDraw

    run = Path(run_dir)
    tr, ev = _read_csv(run / "train.csv"), _read_csv(run / "eval.csv")
    if not tr:
        return None
    steps = np.array([int(r["step"]) for r in tr], np.float64)
    loss = np.array([float(r["loss"]) for r in tr], np.float64)
    im = Image.new("RGB", (width, height), "white")
    dr = ImageDraw.Draw(im)
    panels = [(50, 30, width - 20, height // 2 - 20), (50, height // 2 + 30, width - 20, height - 30)]
    xmax = max(float(steps.max()), 1.0)

    def axes(box, title, ylo, yhi, log):
        x0, y0, x1, y1 = box
        dr.rectangle(box, outline="black")
        dr.text((x0 + 5, y0 - 14), title, fill="black")
        for t in range(5):
            v = ylo + (yhi - ylo) * t / 4
            yy = y1 - (y1 - y0) * t / 4
            dr.text((2, yy - 6), f"{(10 ** v if log else v):.3g}", fill="black")
        for t in range(5):
            xx = x0 + (x1 - x0) * t / 4
            dr.text((xx - 10, y1 + 3), f"{xmax * t / 4:.0f}", fill="black")

    def line(box, xs, ys, ylo, yhi, colour, w=1):
        x0, y0, x1, y1 = box
        if len(xs) == 0:
            return
        px = x0 + (x1 - x0) * xs / xmax
        py = y1 - (y1 - y0) * (np.clip(ys, ylo, yhi) - ylo) / max(yhi - ylo, 1e-9)
        pts = list(zip(px.tolist(), py.tolist()))
        if len(pts) == 1:
            dr.ellipse([pts[0][0] - 2, pts[0][1] - 2, pts[0][0] + 2, pts[0][1] + 2], fill=colour)
        else:
            dr.line(pts, fill=colour, width=w)
            for p in pts if len(pts) < 60 else []:
                dr.ellipse([p[0] - 2, p[1] - 2, p[0] + 2, p[1] + 2], fill=colour)

    ll = np.log10(np.maximum(loss, 1e-6))
    k = max(1, min(50, len(ll) // 10))
    smooth = np.convolve(ll, np.ones(k) / k, mode="valid")
    lo, hi = float(np.percentile(ll, 1)) - 0.05, float(np.percentile(ll, 99.5)) + 0.05
    what = "SILog + prior aux" if any(r.get("silog") for r in tr) else "prior affine-invariant"
    axes(panels[0], f"train loss ({what}), log10; grey = per step, blue = moving avg",
         lo, hi, True)
    line(panels[0], steps, ll, lo, hi, (170, 170, 170))
    line(panels[0], steps[k - 1:], smooth, lo, hi, (20, 60, 220), 2)
    if ev:
        es = np.array([int(r["step"]) for r in ev], np.float64)
        mr = np.array([float(r["model_rmse"]) for r in ev])
        br = np.array([float(r["bilinear_rmse"]) for r in ev])
        top = float(max(mr.max(), br.max())) * 1.1
        axes(panels[1], "held-out RMSE (m): red = model, green = bilinear zones", 0.0, top, False)
        line(panels[1], es, mr, 0.0, top, (220, 30, 30), 2)
        line(panels[1], es, br, 0.0, top, (20, 160, 60), 2)
    path = run / "loss.png"
    im.save(path)
    return path


def main(argv: list[str] | None = None) -> int:
    """CLI entry point (see module doc)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", default="mcu", choices=sorted(VARIANTS))
    ap.add_argument("--arch", default="depthor", choices=ARCHS,
                    help="depthor (the variant) or sparse_to_dense (the learned baseline of "
                         "sparse_to_dense.py, issue 39 item 4; --set sets its S2DConfig fields)")
    ap.add_argument("--train", help="training recording folder(s), comma-separated "
                    "(required to train)")
    ap.add_argument("--test", help="held-out recording folder (required to train or evaluate)")
    ap.add_argument("--out", default="runs/mcu", help="run folder (checkpoint, logs, plot)")
    ap.add_argument("--stage", default="depthor", choices=STAGES,
                    help="prior: the monocular prior alone on its affine-invariant loss (run "
                         "first); depthor: the whole network (--init from the prior stage)")
    ap.add_argument("--steps", type=int, default=2000, help="OneCycle length (total steps)")
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--max-lr", type=float, default=3e-4, help="OneCycle peak (paper: 3e-4)")
    ap.add_argument("--weight-decay", type=float, default=0.1)
    ap.add_argument("--clip", type=float, default=0.1, help="gradient l2-norm clip")
    ap.add_argument("--prior-weight", type=float, default=1.0, help="weight of the prior's aux loss")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--ckpt-every-s", type=float, default=180.0)
    ap.add_argument("--eval-frames", type=int, default=0, help="held-out frames (0 = all)")
    ap.add_argument("--time-limit-s", type=float, default=0.0, help="stop after this long (0 = no limit)")
    ap.add_argument("--schedule-s", type=float, default=0.0,
                    help="run the OneCycle schedule over this many seconds of training (step "
                         "time, evaluation excluded) instead of --steps steps, and stop there; "
                         "--steps stays an upper bound. For a CPU share whose speed is unknown "
                         "in advance (0 = by steps)")
    ap.add_argument("--stop-after", type=int, default=0,
                    help="leave after this many steps in this invocation (0 = run to the end)")
    ap.add_argument("--crop", default=None, metavar="HxW",
                    help="train on a random HxW window of each batch (multiples of 32; "
                         "evaluation stays on whole frames)")
    ap.add_argument("--teacher", default=None, metavar="WEIGHTS",
                    help="distil from these trained weights (e.g. mcu/train/model_final.pt):"
                         " SILog of the prediction against the teacher's dense depth, weight "
                         "--kd-weight, on top of the reference loss (depthor stage only)")
    ap.add_argument("--teacher-variant", default="mcu", choices=sorted(VARIANTS))
    ap.add_argument("--kd-weight", type=float, default=1.0)
    ap.add_argument("--augment", action="store_true",
                    help="photometric/sensor augmentation of the RGB (`photometric`)")
    ap.add_argument("--augment-p", type=float, default=0.8,
                    help="share of training images that get the photometric augmentation")
    ap.add_argument("--device", default=None, choices=("cpu", "cuda"),
                    help="where to train (default: cuda when torch sees a GPU, else cpu); under "
                         "torchrun each process takes the GPU of its LOCAL_RANK")
    ap.add_argument("--dtype", default="float32", choices=("float32", "float64"),
                    help="training precision; float64 is for numerical equivalence checks "
                         "(e.g. N processes against one), several times slower")
    ap.add_argument("--data", default="memory", choices=("memory", "stream"),
                    help="memory: decode every training frame once and keep it in RAM (npz "
                         "cache in the recording); stream: decode frames as batches need them "
                         "(DataLoader workers, memory bounded by the batch, no cache)")
    ap.add_argument("--workers", type=int, default=2,
                    help="DataLoader worker processes per training process with --data stream "
                         "(0 = decode in the training process)")
    ap.add_argument("--prefetch", action="store_true",
                    help="assemble and augment the next batch in a thread while a step trains "
                         "(same batches; for GPU runs)")
    ap.add_argument("--qat", action="store_true",
                    help="quantisation-aware training (int8 rounding simulated; see qat.py)")
    ap.add_argument("--qat-float-p", type=float, default=0.0,
                    help="with --qat: the share of steps (drawn from (seed, step)) that train the "
                         "float network instead, so that float and int8 stay alike")
    ap.add_argument("--resume", action="store_true", help="continue from <out>/ckpt.pt")
    ap.add_argument("--switch-train", action="store_true",
                    help="with --resume: keep the schedule but draw the remaining batches from "
                         "--train instead of the checkpoint's training set (e.g. once more "
                         "generated frames are ready)")
    ap.add_argument("--init", default=None, help="start from these weights with a fresh schedule")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="NetConfig override of the variant (ablations), e.g. n_bins=32; "
                         "export with the same --set")
    ap.add_argument("--plot-only", action="store_true", help="only redraw <out>/loss.png")
    ap.add_argument("--eval-only", default=None, metavar="WEIGHTS",
                    help="only evaluate these weights on --test (first --eval-frames) and exit")
    a = ap.parse_args(argv)
    if a.plot_only:
        print(plot(a.out))
        return 0
    if not a.test or not (a.train or a.eval_only):
        ap.error("--test is required, and --train unless --eval-only is given")
    if a.eval_only:
        torch.set_num_threads(a.threads)
        net = make_model(a.variant, a.seed, parse_overrides(a.set), a.arch)
        net.load_state_dict(load_weights(a.eval_only))
        net.to(dist.pick_device(a.device))
        size = (net.cfg.height, net.cfg.width)
        print(json.dumps(Evaluator(data.load_recordings(a.test, size=size), a.eval_frames)(net)))
        return 0
    row = train(a)
    if int(os.environ.get("RANK", "0")) == 0:
        print(json.dumps(row))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
