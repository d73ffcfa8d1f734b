"""A learned per-pixel gate between the network and two classical zone interpolations (issue 39,
item 3: "a gated path from robustly interpolated zones"). Float prototype, not in the graph.

The network's output does not follow good zones (its sparse input only reaches the depth
encoder; the refinement starts from the bins head). The gate keeps the network and adds a path
from the zones: per pixel it blends three candidates, `net`, a joint bilateral upsampling of the
zones (`joint_bilateral`, the host baseline's definition) and a bilinear interpolation of the zone
grid (`train.zone_baselines`), with softmax weights that a small CNN predicts at 1/4 resolution
from the candidates' log depths, their log differences to `net` and the RGB. Trained on rendered
measurement-mix frames only; it learns where zones agree with the image and the network (trust
the interpolation) and where they do not (keep the network).

    python -m depthor_models.zone_gate features --recording R [--frames N] --out F.npz
    python -m depthor_models.zone_gate train --features A.npz,B.npz --out gate.pt [--steps 1500]
    python -m depthor_models.zone_gate eval --gate gate.pt --features F.npz [--int8-dir D]
        [--eval-json summary.json]
    python -m depthor_models.zone_gate export --gate gate.pt --out zone_gate.bin
        [--golden-features F.npz --golden-out zone_gate_golden.bin]

`features` runs the float network (default: the shipped mcu_lite weights; `--variant
phone_lite --weights phone_lite/train/model_final.pt` for the phone) and the two interpolations
on a recording, resampled to the network's input as `depthor eval` resamples it; `eval` scores
net, gate and the interpolations, optionally with the int8 engine's depth PNGs (`depthor eval
--save-depth`) as the net candidate and the best baseline RMSE of `depthor eval --json` as the
reference. Figures: docs/results/models_zone_gate.md (mcu_lite, and the "phone_lite" section).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from . import data

CANDIDATES = ("net", "joint_bilateral", "bilinear")
SIGMA_RGB = 20.0  # range σ of the joint bilateral filter, RGB levels (host/src/baselines.rs)
SHIPPED = Path(__file__).resolve().parents[1] / "mcu_lite" / "train" / "model_final.pt"


def joint_bilateral(rgb: np.ndarray, sparse: np.ndarray) -> np.ndarray:
    """Joint bilateral upsampling of the valid points of `sparse` [H,W] (metres, 0 = none)
    guided by `rgb` [H,W,3] uint8: each pixel averages the points within two point spacings
    (spacing = sqrt(H·W / points)), weighted by a spatial Gaussian (σ = one spacing) times a range
    Gaussian on the RGB difference to the point's pixel (σ = 20 levels); pixels with no point in
    reach take the nearest point; no point at all gives 1 m everywhere. float32 [H,W].
    Each point is splatted over the window of its reach (cost points × reach², not pixels ×
    points)."""
    h, w = sparse.shape
    ys, xs = np.nonzero(sparse > 0)
    if len(ys) == 0:
        return np.ones((h, w), np.float32)
    z = sparse[ys, xs].astype(np.float64)
    spacing = math.sqrt(h * w / len(ys))
    r = int(math.floor(2 * spacing))
    dy, dx = np.mgrid[-r:r + 1, -r:r + 1]
    d2 = (dy * dy + dx * dx).ravel()
    keep = d2 <= 4 * spacing**2
    dy, dx, d2 = dy.ravel()[keep], dx.ravel()[keep], d2[keep]
    py, px = ys[:, None] + dy[None], xs[:, None] + dx[None]  # [points, window]
    inside = (py >= 0) & (py < h) & (px >= 0) & (px < w)
    colour = rgb.astype(np.float64)
    pix = np.where(inside, py * w + px, 0)
    r2 = ((colour.reshape(-1, 3)[pix] - colour[ys, xs][:, None]) ** 2).sum(-1)
    wt = np.exp(-d2[None] / (2 * spacing**2) - r2 / (2 * SIGMA_RGB**2)) * inside
    num = np.bincount(pix.ravel(), (wt * z[:, None]).ravel(), h * w)
    den = np.bincount(pix.ravel(), wt.ravel(), h * w)
    out = np.empty(h * w)
    ok = den > 1e-12
    out[ok] = num[ok] / den[ok]
    if not ok.all():  # no point in reach (or weights underflowed): the nearest point
        yy, xx = np.divmod(np.flatnonzero(~ok), w)
        near = ((yy[:, None] - ys[None]) ** 2 + (xx[:, None] - xs[None]) ** 2).argmin(1)
        out[~ok] = z[near]
    return out.reshape(h, w).astype(np.float32)


class ZoneGate(nn.Module):
    """Softmax weights over the candidates [B,K,H,W] (metres) from a 4-layer CNN at 1/4
    resolution (3×3 convolutions, dilations 1, 2, 4, 1), upsampled bilinearly; starts out
    preferring `net` (weight 0.79 with three candidates)."""

    def __init__(self, channels: int = 16, candidates: int = len(CANDIDATES)):
        super().__init__()
        k = candidates
        widths = [2 * k + 2, channels, channels, channels]
        self.convs = nn.ModuleList(
            nn.Conv2d(a, b, 3, padding=d, dilation=d)
            for a, b, d in zip(widths[:-1], widths[1:], (1, 2, 4)))
        self.out = nn.Conv2d(channels, k, 3, padding=1)
        nn.init.zeros_(self.out.weight)
        with torch.no_grad():
            self.out.bias.copy_(torch.tensor([2.0] + [0.0] * (k - 1)))

    @staticmethod
    def features(cand: torch.Tensor, rgb: torch.Tensor) -> torch.Tensor:
        """Log depths, log differences to the first candidate and RGB in [0,1], at 1/4 size."""
        log_d = torch.log(cand.clamp(min=0.1))
        f = torch.cat([log_d, log_d[:, :1] - log_d[:, 1:], rgb], 1)
        return F.avg_pool2d(f, 4)

    def forward(self, cand: torch.Tensor, rgb: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(blended depth [B,1,H,W], weights [B,K,H,W]) for candidates [B,K,H,W] and RGB
        [B,3,H,W] in [0,1]; H and W multiples of 4."""
        x = self.features(cand, rgb)
        for conv in self.convs:
            x = F.leaky_relu(conv(x), 0.1)
        logits = F.interpolate(self.out(x), size=cand.shape[2:], mode="bilinear",
                               align_corners=False)
        w = torch.softmax(logits, 1)
        return (w * cand).sum(1, keepdim=True), w

    def macs(self, height: int, width: int) -> int:
        """Multiply-accumulates of the CNN at the given input size (the blend not counted)."""
        px = (height // 4) * (width // 4)
        return px * sum(c.in_channels * c.out_channels * 9 for c in [*self.convs, self.out])


def image_rmse(pred: torch.Tensor, gt: torch.Tensor, max_depth: float = 10.0) -> torch.Tensor:
    """RMSE per image [B] over pixels with 0 < gt ≤ max_depth."""
    m = (gt > 0) & (gt <= max_depth)
    e = ((pred - gt) ** 2 * m).sum((1, 2, 3)) / m.sum((1, 2, 3)).clamp(min=1)
    return e.clamp(min=1e-12).sqrt()


def features(recording: str, frames: int, out: str | Path, weights: str | Path = SHIPPED,
             variant: str = "mcu_lite", seed: int = 0) -> None:
    """Candidates of `frames` frames drawn without replacement (seeded; 0 = every frame, in
    order) of `recording`, saved as npz: rgb, gt (m), sparse (m), cand [N,3,H,W], ids. Frames
    are resampled to the network's input size the way `depthor eval` resamples them (a no-op
    when the recording is already at that size, e.g. mcu frames or `depthor sim --width/--height`
    output)."""
    from .export import build_trained
    from .train import zone_baselines

    net = build_trained(variant, weights)
    reader = data.FrameReader(recording, size=(net.cfg.height, net.cfg.width))
    if frames <= 0 or frames >= len(reader):
        idx = np.arange(len(reader))
    else:
        idx = np.sort(np.random.default_rng(seed).choice(len(reader), frames, replace=False))
    rec = reader.recording(idx)
    all_idx = np.arange(len(rec))
    sparse = data.sparse_maps(rec, all_idx)
    bilinear = zone_baselines(rec, all_idx)["bilinear"]
    cand = np.empty((len(rec), len(CANDIDATES), rec.height, rec.width), np.float32)
    for i in all_idx:
        rgb = torch.from_numpy(rec.rgb[i].astype(np.float32).transpose(2, 0, 1)[None] / 255)
        with torch.no_grad():
            d = net(rgb, torch.from_numpy(sparse[i][None, None]))
        cand[i, 0] = d[0, 0].numpy()
        cand[i, 1] = joint_bilateral(rec.rgb[i], sparse[i])
        cand[i, 2] = bilinear[i]
    np.savez(out, rgb=rec.rgb, gt=rec.depth_mm.astype(np.float32) / 1000, sparse=sparse,
             cand=cand, ids=np.array(rec.ids))


def _load(paths: list[str]) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    parts = [np.load(p) for p in paths]
    cand = torch.from_numpy(np.concatenate([z["cand"] for z in parts]))
    rgb = torch.from_numpy(np.concatenate([z["rgb"] for z in parts])).permute(0, 3, 1, 2)
    gt = torch.from_numpy(np.concatenate([z["gt"] for z in parts]))[:, None]
    return cand, rgb.float() / 255, gt


def train(cand: torch.Tensor, rgb: torch.Tensor, gt: torch.Tensor, steps: int,
          channels: int = 16, batch: int = 16, lr: float = 1e-3, seed: int = 1,
          log_every: int = 0, norm: str = "net") -> ZoneGate:
    """Trains a gate on candidate tensors: AdamW, one-cycle schedule, random left-right flips;
    loss = mean over the batch of (gate RMSE) / (reference RMSE + 2 cm), so that near and far
    scenes weigh alike; the reference is the network's (`norm="net"`) or the best candidate's
    on that frame (`norm="best"`: frames where the network fails weigh as much as the others,
    and the loss reads as the figure the evaluation grid reports)."""
    if norm not in ("net", "best"):
        raise ValueError(f"norm: {norm!r} is not 'net' or 'best'")
    torch.manual_seed(seed)
    gate = ZoneGate(channels, cand.shape[1])
    opt = torch.optim.AdamW(gate.parameters(), lr, weight_decay=1e-4)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, lr, total_steps=steps)
    rng = np.random.default_rng(seed)
    for s in range(steps):
        i = torch.from_numpy(rng.choice(len(cand), min(batch, len(cand)), replace=False))
        c, r, g = cand[i], rgb[i], gt[i]
        if rng.random() < 0.5:
            c, r, g = c.flip(3), r.flip(3), g.flip(3)
        with torch.no_grad():
            if norm == "net":
                ref = image_rmse(c[:, :1], g) + 0.02
            else:
                ref = torch.stack([image_rmse(c[:, k:k + 1], g)
                                   for k in range(c.shape[1])]).min(0).values + 0.02
        loss = (image_rmse(gate(c, r)[0], g) / ref).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        if log_every and s % log_every == 0:
            print(f"step {s} loss {loss.item():.4f}", flush=True)
    return gate.eval()


def evaluate(gate: ZoneGate, path: str | Path, int8_dir: str | Path | None = None,
             eval_json: str | Path | None = None) -> dict:
    """Image-mean RMSE of every candidate and of the gate on a features file; with `int8_dir`
    (`<dir>/<id>.png`, millimetres) the int8 depth replaces the float net; with `eval_json`
    (`depthor eval --json`) every figure is also given over the best baseline's RMSE there."""
    z = np.load(path)
    cand = torch.from_numpy(z["cand"])
    rgb = torch.from_numpy(z["rgb"]).permute(0, 3, 1, 2).float() / 255
    gt = torch.from_numpy(z["gt"])[:, None]
    if int8_dir is not None:
        from PIL import Image
        cand[:, 0] = torch.from_numpy(np.stack([
            np.asarray(Image.open(Path(int8_dir) / f"{fid}.png"), np.float32) / 1000
            for fid in z["ids"]]))
    with torch.no_grad():
        fused, w = gate(cand, rgb)
    out = {name: image_rmse(cand[:, k:k + 1], gt).mean().item()
           for k, name in enumerate(CANDIDATES)}
    out["gate"] = image_rmse(fused, gt).mean().item()
    out["net_weight"] = w[:, 0].mean().item()
    if eval_json is not None:
        methods = json.loads(Path(eval_json).read_text())["methods"]
        best = min(v["rmse"] for k, v in methods.items() if k not in ("int8", "float", "prior"))
        out["best_baseline"] = best
        out["ratio"] = {k: out[k] / best for k in (*CANDIDATES, "gate")}
    return out


def to_bytes(gate: ZoneGate) -> bytes:
    """The gate in the core's file format (`depthor_core::zone_gate`, `DZG1`, little-endian):
    header (magic, candidates, channels, layers, pooling 4, leaky slope 0.1), then per layer its
    dilation, a reserved 0, the weights [out][in][3][3] and the biases, all f32."""
    layers = [*gate.convs, gate.out]
    b = bytearray(b"DZG1")
    b += np.array([gate.out.out_channels, gate.convs[0].out_channels, len(layers), 4],
                  "<u2").tobytes()
    b += np.array([0.1], "<f4").tobytes()
    for conv in layers:
        b += np.array([conv.dilation[0], 0], "<u2").tobytes()
        b += conv.weight.detach().numpy().astype("<f4").tobytes()
        b += conv.bias.detach().numpy().astype("<f4").tobytes()
    return bytes(b)


def golden_bytes(gate: ZoneGate, cand: np.ndarray, rgb: np.ndarray) -> bytes:
    """A test vector for the core's gate: u32 width, u32 height, the candidates f32 [3][H][W]
    (metres), the RGB u8 [H][W][3] and PyTorch's blend f32 [H][W]."""
    h, w = cand.shape[1:]
    with torch.no_grad():
        fused, _ = gate(torch.from_numpy(cand[None]),
                        torch.from_numpy(rgb.transpose(2, 0, 1)[None].astype(np.float32) / 255))
    return (np.array([w, h], "<u4").tobytes() + cand.astype("<f4").tobytes()
            + rgb.astype(np.uint8).tobytes() + fused[0, 0].numpy().astype("<f4").tobytes())


def main(argv: list[str] | None = None) -> None:
    """Command line: features, train, eval (see the module docstring)."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    f = sub.add_parser("features", help="candidates of a recording's frames")
    f.add_argument("--recording", required=True)
    f.add_argument("--frames", type=int, default=0)
    f.add_argument("--out", required=True)
    f.add_argument("--weights", default=str(SHIPPED))
    f.add_argument("--variant", default="mcu_lite")
    t = sub.add_parser("train", help="train a gate on features files")
    t.add_argument("--features", required=True, help="comma-separated npz files")
    t.add_argument("--out", required=True)
    t.add_argument("--steps", type=int, default=1500)
    t.add_argument("--channels", type=int, default=16)
    t.add_argument("--threads", type=int, default=1)
    t.add_argument("--norm", choices=("net", "best"), default="net",
                   help="loss reference: the network's RMSE or the best candidate's")
    e = sub.add_parser("eval", help="score a gate on a features file")
    e.add_argument("--gate", required=True)
    e.add_argument("--channels", type=int, default=16)
    e.add_argument("--features", required=True)
    e.add_argument("--int8-dir")
    e.add_argument("--eval-json")
    x = sub.add_parser("export", help="write a gate in the core's file format")
    x.add_argument("--gate", required=True)
    x.add_argument("--channels", type=int, default=16)
    x.add_argument("--out", required=True)
    x.add_argument("--golden-features", help="features npz whose first frame's centre makes "
                   "the test vector")
    x.add_argument("--golden-out")
    x.add_argument("--golden-size", type=int, default=32)
    a = p.parse_args(argv)
    if a.cmd == "features":
        features(a.recording, a.frames, a.out, a.weights, a.variant)
    elif a.cmd == "train":
        torch.set_num_threads(a.threads)
        gate = train(*_load(a.features.split(",")), a.steps, a.channels, log_every=100,
                     norm=a.norm)
        torch.save(gate.state_dict(), a.out)
    else:
        gate = ZoneGate(a.channels)
        gate.load_state_dict(torch.load(a.gate, map_location="cpu"))
        gate.eval()
        if a.cmd == "eval":
            print(json.dumps(evaluate(gate, a.features, a.int8_dir, a.eval_json)))
            return
        Path(a.out).write_bytes(to_bytes(gate))
        if a.golden_features and a.golden_out:
            z = np.load(a.golden_features)
            n = a.golden_size
            h, w = z["cand"].shape[2:]
            y, x = (h - n) // 2 // 4 * 4, (w - n) // 2 // 4 * 4
            Path(a.golden_out).write_bytes(golden_bytes(
                gate, z["cand"][0, :, y:y + n, x:x + n].copy(), z["rgb"][0, y:y + n, x:x + n]))


if __name__ == "__main__":
    main()
