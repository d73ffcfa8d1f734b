"""The refinement's start from the zones (issue 39, item 3: "the refinement's start from
them"). Float prototype, not in the graph contract yet.

The lite network's refinement propagates `D_0`, the bins head's depth, which the sparse zones
reach only through the depth encoder; with clean zones its output stays as blurry as with bad
ones. Here `D_0` is blended with an interpolation of the zones before the refinement:

    Z   = normalised Gaussian splat of the zone points at D_0's size (σ = one zone spacing)
    ρ   = the splat's weight sum, scaled to 1 at a regular grid's density (0 far from zones)
    g   = sigmoid(conv3x3([guidance features, clamp(ln Z − ln D_0, ±2), ρ]))
    D_0' = D_0 + g · (Z − D_0)

so the learned affinities propagate from the zones where `g` trusts them and from the network
elsewhere. `g` starts low (bias −2, zero weights: 0.12), so a network initialised from trained
weights starts near where they were; the gate learns at 100 × the network's rate
(`train.make_optim`). Cost at the refinement's size (h × w): the splat's points × its
window, a 3×3 conv of (C + 2) → 1 channels and a blend per pixel.

    python -m depthor_models.train ... --set zone_prior=True --init <trained weights>   (training)
    python -m depthor_models.zone_prior eval --weights W --features F.npz[,…] [--eval-json-dir D]

`eval` reads the features files of `zone_gate features` (RGB, points, ground truth and the
network alone) and, optionally, the `depthor eval --json` of each recording for the best
classical baseline. Figures: docs/results/models_zone_gate.md.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

import torch
import torch.nn.functional as F
from torch import Tensor, nn

# The splat's window reaches this many σ.
REACH_SIGMAS = 2.0
# Bias of the gate's conv at initialisation: sigmoid(−2) ≈ 0.12.
GATE_BIAS0 = -2.0


def splat(sparse: Tensor, h: int, w: int) -> tuple[Tensor, Tensor]:
    """`sparse` [B,1,H,W] metres (0 = no point) → (Z [B,1,h,w] metres, ρ [B,1,h,w]):
    each point moved to the pixel of (h, w) its centre falls in, then a Gaussian of σ = one
    point spacing (sqrt(h·w / points)) splats value and weight; Z = Σ w·z / Σ w where Σ w >
    1e-6 (else 0), ρ = Σ w / 2π (≈ 1 inside a regular grid of points, → 0 far outside)."""
    b, _, hh, ww = sparse.shape
    valid = (sparse > 0).to(sparse.dtype)
    ys = torch.arange(hh, device=sparse.device)
    xs = torch.arange(ww, device=sparse.device)
    ty = ((ys.to(torch.float32) + 0.5) * h / hh).floor().clamp(0, h - 1).long()
    tx = ((xs.to(torch.float32) + 0.5) * w / ww).floor().clamp(0, w - 1).long()
    idx = (ty[:, None] * w + tx[None, :]).reshape(-1)
    z_out, rho_out = [], []
    for i in range(b):
        v = (sparse[i, 0] * valid[i, 0]).reshape(-1)
        m = valid[i, 0].reshape(-1)
        sv = torch.zeros(h * w, dtype=sparse.dtype, device=sparse.device).index_add_(0, idx, v)
        sm = torch.zeros(h * w, dtype=sparse.dtype, device=sparse.device).index_add_(0, idx, m)
        n = float(m.sum())
        if n == 0:
            z_out.append(torch.zeros(1, h, w, dtype=sparse.dtype, device=sparse.device))
            rho_out.append(torch.zeros(1, h, w, dtype=sparse.dtype, device=sparse.device))
            continue
        sigma = math.sqrt(h * w / n)
        r = max(1, int(math.floor(REACH_SIGMAS * sigma)))
        t = torch.arange(-r, r + 1, dtype=sparse.dtype, device=sparse.device)
        k = torch.exp(-(t * t) / (2 * sigma * sigma))
        both = torch.stack([sv.view(h, w), sm.view(h, w)])[:, None]  # [2,1,h,w]
        both = F.conv2d(F.pad(both, (r, r, 0, 0)), k.view(1, 1, 1, -1))
        both = F.conv2d(F.pad(both, (0, 0, r, r)), k.view(1, 1, -1, 1))
        num, den = both[0], both[1]
        z = torch.where(den > 1e-6, num / den.clamp_min(1e-6), torch.zeros_like(den))
        z_out.append(z)
        rho_out.append(den / (2 * math.pi))
    return torch.stack(z_out), torch.stack(rho_out)


class ZonePrior(nn.Module):
    """The gate and blend of the module doc: `forward(d0, guidance, sparse) → D_0'`."""

    def __init__(self, guidance_channels: int):
        super().__init__()
        self.gate = nn.Conv2d(guidance_channels + 2, 1, 3, padding=1)
        nn.init.zeros_(self.gate.weight)
        nn.init.constant_(self.gate.bias, GATE_BIAS0)
        self.last_gate: Tensor | None = None  # the last forward's g (for inspection)

    def forward(self, d0: Tensor, guidance: Tensor, sparse: Tensor) -> Tensor:
        h, w = int(d0.shape[2]), int(d0.shape[3])
        z, rho = splat(sparse, h, w)
        have = z > 0
        zr = torch.where(have, z, d0)
        diff = (torch.log(zr.clamp_min(1e-3)) - torch.log(d0.clamp_min(1e-3))).clamp(-2, 2)
        g = torch.sigmoid(self.gate(torch.cat([guidance, diff, rho.clamp(0, 4)], 1)))
        g = g * have.to(g.dtype)
        self.last_gate = g.detach()
        return d0 + g * (zr - d0)


def evaluate(weights: str | Path, variant: str, features: str | Path,
             eval_json: str | Path | None = None) -> dict:
    """Image-mean RMSE of the network with the zone prior (`weights`, trained with
    `--set zone_prior=True`) on a `zone_gate features` file (its RGB, sparse points and ground
    truth; its `net` candidate is the network without the prior), and, with `eval_json`
    (`depthor eval --json` of the same recording), both over the best classical baseline's."""
    from .export import build_trained
    from .zone_gate import image_rmse

    z = np.load(features)
    net = build_trained(variant, weights, zone_prior=True)
    gt = torch.from_numpy(z["gt"])[:, None]
    preds, gates = [], []
    for i in range(len(gt)):
        rgb = torch.from_numpy(z["rgb"][i].astype(np.float32).transpose(2, 0, 1)[None] / 255)
        with torch.no_grad():
            preds.append(net(rgb, torch.from_numpy(z["sparse"][i][None, None])))
        gates.append(float(net.zone_prior.last_gate.mean()))
    out = {
        "net": image_rmse(torch.from_numpy(z["cand"][:, :1]), gt).mean().item(),
        "zone_prior": image_rmse(torch.cat(preds), gt).mean().item(),
        "gate_mean": float(np.mean(gates)),
    }
    if eval_json is not None:
        methods = json.loads(Path(eval_json).read_text())["methods"]
        best = min(v["rmse"] for k, v in methods.items() if k not in ("int8", "float", "prior"))
        out["best_baseline"] = best
        out["ratio"] = {k: out[k] / best for k in ("net", "zone_prior")}
    return out


def main(argv: list[str] | None = None) -> None:
    """`eval --weights W --features F1.npz,F2.npz [--eval-json-dir D]`: one line per file
    (D/<file stem>.json or D/<file stem>/summary.json is its `depthor eval --json`), then the
    means."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    e = sub.add_parser("eval")
    e.add_argument("--weights", required=True)
    e.add_argument("--variant", default="phone_lite")
    e.add_argument("--features", required=True, help="comma-separated zone_gate features files")
    e.add_argument("--eval-json-dir", default=None)
    a = p.parse_args(argv)
    rows = []
    for f in a.features.split(","):
        ej = None
        if a.eval_json_dir:
            d, stem = Path(a.eval_json_dir), Path(f).stem
            ej = next((j for j in (d / f"{stem}.json", d / stem / "summary.json") if j.exists()),
                      None)
        r = evaluate(a.weights, a.variant, f, ej)
        rows.append(r)
        ratio = r.get("ratio", {})
        print(f"{Path(f).stem:32s} net {r['net']:.4f} m  zone_prior {r['zone_prior']:.4f} m  "
              f"ratio {ratio.get('net', float('nan')):.3f} -> {ratio.get('zone_prior', float('nan')):.3f}"
              f"  gate {r['gate_mean']:.3f}", flush=True)
    rs = [r["ratio"] for r in rows if "ratio" in r]
    if rs:
        for k in ("net", "zone_prior"):
            v = [r[k] for r in rs]
            print(f"{k}: mean ratio {np.mean(v):.3f}, max {np.max(v):.3f} over {len(v)} cells")


if __name__ == "__main__":
    main()
