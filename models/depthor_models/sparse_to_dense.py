"""A learned baseline at mcu_lite's budget: a plain encoder–decoder on RGB + sparse depth +
validity, in the manner of Ma & Karaman's sparse-to-dense (issue 39, item 4).

No monocular prior, no bins, no guidance, no refinement: the five input channels
cat(RGB in [0,1], sparse depth / 10 m, validity = sparse > 0) go through a MobileNet-like
encoder (a strided 3×3 stem, then inverted-residual stages down to 1/32), a U-Net decoder
(bilinear upsampling to each skip's size, concatenation, 3×3 conv-BN-relu) up to 1/2, a 3×3
conv to one channel, a bilinear upsampling to full resolution and a bounded log-depth output
d = exp(log 0.1 + log(100)·σ(x)) metres (0.1 … 10 m, the sensor's range). The sparse input is
what DEPTHOR gets (`data.batch`: one pixel per valid zone, metres, 0 = none), so the training
recipe of `train.py` runs unchanged (`--arch sparse_to_dense`: SILog, AdamW + OneCycle, clip,
flips, photometric augmentation, the same (seed, step) batches; no prior, so no prior loss).

MACs are counted as `budget.py` counts a variant: the body is written in docs/graph.md ops,
recorded by `ops.recording` and summed with `graph_export.node_macs` (conv2d, upsample; the
input concatenation, the scaling of the sparse channel and the output mapping are element-wise
and count 0).

    python -m depthor_models.sparse_to_dense macs
    python -m depthor_models.train --arch sparse_to_dense --train A,B --test T --out R ...
    python -m depthor_models.sparse_to_dense eval --weights R/model_final.pt --recording REC \
        --eval-json summary.json [--variant mcu_lite --variant-weights W]

`eval` prints per-image mean RMSE of the network(s) on a recording and, with `--eval-json`
(`depthor eval --json` of the same recording), each over the best classical baseline there
(the best of nearest, bilinear and joint bilateral, as `zone_gate.evaluate` takes it).
Figures: docs/results/models_learned_baseline.md.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import Tensor, nn

from . import data, graph_export, ops
from .train import predict
from .blocks import ConvBNAct, InvertedResidual, SepConv

MCU_LITE_MACS = 21_224_184  # budget.budget("mcu_lite")["macs"]; the test recounts it


@dataclass(frozen=True)
class S2DConfig:
    """Input size, widths and output range. `enc_widths`: the stem (1/2) and the stages at
    1/4 … 1/32; `enc_blocks`: inverted residuals per stage (the first one strided);
    `expand`: the stages' expansion ratios; `dec_widths`: decoder outputs at 1/16 … 1/2 (each a
    1×1 conv-BN-relu then a `dec_kernel` depthwise conv-BN-relu, FastDepth's decoder)."""

    variant: str = "sparse_to_dense"
    height: int = 120
    width: int = 160
    enc_widths: tuple[int, ...] = (12, 24, 32, 48, 64)
    enc_blocks: tuple[int, ...] = (1, 2, 2, 2)
    expand: tuple[int, ...] = (2, 3, 3, 3)
    dec_widths: tuple[int, ...] = (48, 32, 24, 12)
    dec_kernel: int = 3
    min_depth_m: float = 0.1
    max_depth_m: float = 10.0


class SparseToDense(nn.Module):
    """forward(rgb [B,3,H,W] in [0,1], sparse [B,1,H,W] m, 0 = none) → depth [B,1,H,W] m."""

    def __init__(self, cfg: S2DConfig | None = None):
        super().__init__()
        self.cfg = cfg = cfg or S2DConfig()
        e, d = cfg.enc_widths, cfg.dec_widths
        self.stem = ConvBNAct(5, e[0], 3, 2)
        stages = []
        for cin, cout, n, x in zip(e[:-1], e[1:], cfg.enc_blocks, cfg.expand):
            blocks = [InvertedResidual(cin, cout, 2, x)]
            blocks += [InvertedResidual(cout, cout, 1, x) for _ in range(n - 1)]
            stages.append(nn.Sequential(*blocks))
        self.stages = nn.ModuleList(stages)
        # decoder level k fuses the upsampled deeper features with the skip at 1/16, 1/8, 1/4, 1/2
        ups, cin = [], e[-1]
        for skip, cout in zip(e[-2::-1], d):
            ups.append(SepConv(cin + skip, cout, 1, cfg.dec_kernel, order="pw_dw"))
            cin = cout
        self.dec = nn.ModuleList(ups)
        self.head = ops.Conv(cin, 1, 3)

    def inputs(self, rgb: Tensor, sparse: Tensor) -> Tensor:
        """cat(rgb, sparse / max depth, validity) [B,5,H,W]."""
        return torch.cat([rgb, sparse / self.cfg.max_depth_m, (sparse > 0).to(rgb.dtype)], 1)

    def body(self, x: Tensor) -> Tensor:
        """Output logits [B,1,H,W] from the 5-channel input (graph ops only)."""
        skips = [self.stem(x)]
        for stage in self.stages:
            skips.append(stage(skips[-1]))
        y = skips[-1]
        for conv, skip in zip(self.dec, skips[-2::-1]):
            y = conv(ops.concat([ops.upsample_bilinear(y, skip.shape[2], skip.shape[3]), skip]))
        return ops.upsample_bilinear(self.head(y), x.shape[2], x.shape[3])

    def forward(self, rgb: Tensor, sparse: Tensor) -> Tensor:
        lo, hi = math.log(self.cfg.min_depth_m), math.log(self.cfg.max_depth_m)
        return torch.exp(lo + (hi - lo) * torch.sigmoid(self.body(self.inputs(rgb, sparse))))

    @torch.no_grad()
    def macs(self) -> int:
        """Multiply-accumulates at the configured input size, counted as `budget.py` counts a
        DEPTHOR variant (`graph_export.node_macs` over the recorded docs/graph.md ops)."""
        was = self.training
        self.eval()
        x = torch.zeros(1, 5, self.cfg.height, self.cfg.width)
        with ops.recording(self) as rec:
            rec.add_input("x", x)
            self.body(x)
        self.train(was)
        shapes = {k: tuple(v.shape) for k, v in rec.values.items()}
        g = {"tensors": {n: {"shape": list(t.shape)} for n, t in rec.params.items()}}
        return sum(graph_export.node_macs(n.to_json(), shapes, g) for n in rec.nodes)


def build(seed: int = 0, **overrides) -> SparseToDense:
    """A fresh network (default PyTorch init, seeded), train mode."""
    torch.manual_seed(seed)
    return SparseToDense(S2DConfig(**overrides)).train()


def load(weights: str | Path) -> SparseToDense:
    """The trained network (eval mode) from a `train.py` run's model_final.pt or ckpt.pt."""
    from .train import load_weights

    net = SparseToDense()
    net.load_state_dict(load_weights(weights))
    return net.eval()


def image_rmse(pred: np.ndarray, gt: np.ndarray, hi: float = 10.0) -> np.ndarray:
    """RMSE per image over the images that have valid pixels, as `depthor eval --aggregate
    image` computes it (core/src/metrics.rs: reference in (1 mm, hi) m, predictions clamped to
    [1 mm, hi])."""
    lo = 1e-3
    m = (gt > lo) & (gt < hi)
    p = np.clip(np.nan_to_num(pred, nan=lo, posinf=hi), lo, hi)
    n = m.sum((1, 2))
    e = ((p - gt) ** 2 * m).sum((1, 2)) / np.maximum(n, 1)
    return np.sqrt(e[n > 0])


def evaluate(nets: dict[str, nn.Module], recording: str | Path,
             eval_json: str | Path | None = None) -> dict:
    """Per-image mean RMSE of each network on `recording` (at the nets' 120×160 input, as
    `depthor eval` runs mcu_lite); with `eval_json` also the best classical baseline's RMSE
    there and each network over it."""
    rec = data.load_recordings(str(recording), size=(120, 160))
    gt = rec.depth_mm.astype(np.float32) / 1000
    out: dict = {"frames": len(rec)}
    for name, net in nets.items():
        out[name] = float(image_rmse(predict(net, rec, np.arange(len(rec)), 4), gt).mean())
    if eval_json is not None:
        methods = json.loads(Path(eval_json).read_text())["methods"]
        base = {k: v["rmse"] for k, v in methods.items() if k not in ("int8", "float", "prior")}
        best = min(base, key=base.get)
        out["best_baseline"], out["best_baseline_name"] = base[best], best
        if "int8" in methods:
            out["int8_engine"] = methods["int8"]["rmse"]
        out["ratio"] = {k: out[k] / base[best] for k in (*nets, *(("int8_engine",)
                        if "int8" in methods else ()))}
    return out


GRID_CONDITIONS = ("preset", "clean", "noise_5pct", "outliers_10pct", "blank_30pct",
                   "misreg_1zone", "bg_shift_2zone", "est_median")


def _merge(base: dict, over: dict) -> dict:
    """`over` merged into `base` field by field (objects recursively), as the simulator merges
    partial configurations (docs/sim.md)."""
    out = dict(base)
    for k, v in over.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def condition_config(grid_dir: str | Path, name: str) -> dict | None:
    """A grid condition's simulator configuration from `host/eval_grid/manifest.json`: the base
    (clean.json) with the condition's file merged over it; None for a condition off the base
    without a file (`preset`: the sensor preset as it is)."""
    grid_dir = Path(grid_dir)
    man = json.loads((grid_dir / "manifest.json").read_text())
    cond = next(c for c in man["conditions"] if c["name"] == name)
    cfg: dict = {}
    if cond.get("on_base", True):
        cfg = json.loads((grid_dir / man["base"]).read_text())
    if "file" in cond:
        cfg = _merge(cfg, json.loads((grid_dir / cond["file"]).read_text()))
    return cfg if cfg or "file" in cond or cond.get("on_base", True) else None


def render(depthor: str, sets: dict[str, str], conditions: list[str], out: str | Path,
           grid_dir: str | Path, sim_args: list[str]) -> None:
    """Every (set, condition) cell: `depthor sim --preset mcu [--config <merged>] --recording
    <set> <sim_args> --out <out>/recs/<set>/<condition>` and `depthor eval --model mcu_lite
    --json --no-float` of it (<out>/evals/<set>/<condition>.json); cells already done are kept."""
    import subprocess

    out = Path(out)
    for c in conditions:
        cfg = condition_config(grid_dir, c)
        cfg_path = None
        if cfg is not None:
            cfg_path = out / "configs" / f"{c}.json"
            cfg_path.parent.mkdir(parents=True, exist_ok=True)
            cfg_path.write_text(json.dumps(cfg, indent=1) + "\n")
        for name, src in sets.items():
            rec, ev = out / "recs" / name / c, out / "evals" / name / f"{c}.json"
            if ev.exists():
                continue
            rec.parent.mkdir(parents=True, exist_ok=True)
            ev.parent.mkdir(parents=True, exist_ok=True)
            cmd = [depthor, "sim", "--preset", "mcu", "--recording", src, "--out", str(rec),
                   "--overwrite", *sim_args]
            if cfg_path is not None:
                cmd += ["--config", str(cfg_path)]
            subprocess.run(cmd, check=True, capture_output=True)
            js = subprocess.run([depthor, "eval", "--model", "mcu_lite", "--recording", str(rec),
                                 "--json", "--no-float", "--mosaics", "0", "--overwrite",
                                 "--out", str(out / "eval_out" / name / c)],
                                check=True, capture_output=True, text=True).stdout
            ev.write_text(js)
            print(f"{name} {c}: int8 / best baseline "
                  f"{json.loads(js)['int8_vs_best_baseline']['rmse_ratio']:.3f}", flush=True)


def grid(cells: str | Path, nets: dict[str, nn.Module], out: str | Path) -> dict:
    """Evaluates `nets` on every rendered cell of `render` (<cells>/recs/<set>/<condition>
    with its eval json); writes and returns {set: {condition: evaluate(...)}}."""
    cells = Path(cells)
    res: dict = {}
    for ev in sorted((cells / "evals").glob("*/*.json")):
        name, c = ev.parent.name, ev.stem
        r = evaluate(nets, cells / "recs" / name / c, ev)
        res.setdefault(name, {})[c] = r
        print(f"{name} {c}: {json.dumps(r['ratio'])}", flush=True)
    Path(out).write_text(json.dumps(res, indent=1) + "\n")
    return res


def table(res: dict, conditions: tuple[str, ...] = GRID_CONDITIONS) -> str:
    """Markdown: per condition (rows) the mean over the sets of each method's RMSE / best
    baseline RMSE, per-set means and the grid mean (over every cell)."""
    methods = list(next(iter(next(iter(res.values())).values()))["ratio"])
    conds = [c for c in conditions if any(c in v for v in res.values())]
    lines = ["| | " + " | ".join(methods) + " |", "|---" * (len(methods) + 1) + "|"]

    def row(label: str, cells: list[dict]) -> str:
        vals = [np.mean([x["ratio"][m] for x in cells]) for m in methods]
        return f"| {label} | " + " | ".join(f"{v:.3f}" for v in vals) + " |"

    for c in conds:
        lines.append(row(c, [v[c] for v in res.values() if c in v]))
    for name, v in res.items():
        lines.append(row(f"set {name}", list(v.values())))
    lines.append(row("**grid mean**", [x for v in res.values() for x in v.values()]))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Command line: macs, eval (see the module docstring)."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("macs", help="MACs of the baseline and of mcu_lite at 120×160")
    e = sub.add_parser("eval", help="per-image RMSE on a recording, over the best baseline")
    e.add_argument("--weights", required=True, help="the baseline's model_final.pt / ckpt.pt")
    e.add_argument("--recording", required=True)
    e.add_argument("--eval-json", help="`depthor eval --json` of the same recording")
    e.add_argument("--variant", action="append", default=[],
                   help="also evaluate this DEPTHOR variant (float) ...")
    e.add_argument("--variant-weights", action="append", default=[], help="... with these weights")
    e.add_argument("--threads", type=int, default=1)
    r = sub.add_parser("render", help="render the grid's cells and `depthor eval` them")
    r.add_argument("--depthor", required=True, help="the depthor binary")
    r.add_argument("--set", action="append", required=True, metavar="NAME=DIR")
    r.add_argument("--condition", action="append", default=[],
                   help=f"default: {' '.join(GRID_CONDITIONS)}")
    r.add_argument("--grid-dir", default=str(Path(__file__).resolve().parents[2] / "host"
                                              / "eval_grid"))
    r.add_argument("--sim-args", default="", help="more `depthor sim` arguments, e.g. "
                   "'--width 160 --height 120 --seed 0'")
    r.add_argument("--out", required=True)
    g = sub.add_parser("grid", help="evaluate networks on rendered cells, print the table")
    g.add_argument("--cells", required=True, help="a `render` --out folder")
    g.add_argument("--weights", required=True, help="the baseline's model_final.pt / ckpt.pt")
    g.add_argument("--variant-weights", action="append", default=[], metavar="NAME=WEIGHTS",
                   help="also mcu_lite (float) with these weights, reported as NAME")
    g.add_argument("--out", required=True, help="JSON of every cell")
    g.add_argument("--threads", type=int, default=1)
    a = p.parse_args(argv)
    torch.set_num_threads(getattr(a, "threads", 1))
    if a.cmd == "render":
        sets = dict(x.split("=", 1) for x in a.set)
        render(a.depthor, sets, a.condition or list(GRID_CONDITIONS), a.out, a.grid_dir,
               a.sim_args.split())
        return
    if a.cmd == "grid":
        from .export import build_trained

        nets = {"learned_baseline": load(a.weights)}
        for x in a.variant_weights:
            name, w = x.split("=", 1)
            nets[name] = build_trained("mcu_lite", w).eval()
        print(table(grid(a.cells, nets, a.out)))
        return
    if a.cmd == "macs":
        from .budget import budget

        ours, ref = build().macs(), budget("mcu_lite")["macs"]
        print(json.dumps({"sparse_to_dense": ours, "mcu_lite": ref, "ratio": ours / ref}))
        return
    from .export import build_trained

    nets: dict[str, nn.Module] = {"learned_baseline": load(a.weights)}
    for k, (v, w) in enumerate(zip(a.variant, a.variant_weights)):
        nets[f"{v}_float" if k == 0 else f"{v}_float_{k}"] = build_trained(v, w).eval()
    print(json.dumps(evaluate(nets, a.recording, a.eval_json)))


if __name__ == "__main__":
    main()
