"""Starting weights for a variant with fewer blocks (the depth ablations of issue 16): every
tensor of the smaller network is copied from a trained one of the same name and shape; the
removed blocks' tensors are dropped.

    python -m depthor_models.shrink --weights B.pt --variant mcu_lite --set n_bins=16 \\
        --set "prior.blocks=(0,0,0,2)" --set "rgb_blocks=(0,0,0,2,0)" --out W.pt

(B.pt: the 32-bin mcu_lite of 2026-12-05, `mcu_lite/train/d32/model_final.pt`, rebinned to 16
by `rebin.py`; this is how today's mcu_lite started, models/mcu_lite/train/data_generation.txt.)

Blocks are numbered within their stage (`enc.<stage>.<block>`), so removing the last inverted
residual of a stage leaves every other name in place. An inverted residual computes
`x + f(x)`: without it the network is the trained one less that block's correction, which
fine-tuning absorbs (`train --init W.pt` with the same `--set`s). A tensor of the smaller network
that the trained one lacks, or has in another shape, is an error.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import torch
from torch import Tensor

from .net import build, parse_overrides
from .train import load_weights


def shrink(state: dict[str, Tensor], target: dict[str, Tensor]) -> tuple[dict[str, Tensor], list[str]]:
    """`state`'s tensors for every name of `target` (a smaller network's state dict), and the
    names of `state` left out."""
    out = {}
    for name, want in target.items():
        if name not in state:
            raise KeyError(f"{name}: not in the trained weights (only blocks can be removed)")
        if state[name].shape != want.shape:
            raise ValueError(f"{name}: trained shape {tuple(state[name].shape)}, "
                             f"the smaller network's {tuple(want.shape)}")
        out[name] = state[name].clone()
    return out, sorted(set(state) - set(target))


def main(argv: list[str] | None = None) -> int:
    """CLI entry point (see module doc)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--weights", required=True, help="trained checkpoint or state dict")
    ap.add_argument("--variant", required=True, help="variant of the smaller network")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="NetConfig overrides of the smaller network (as for train/export)")
    ap.add_argument("--out", required=True, help="state-dict file to write")
    a = ap.parse_args(argv)
    target = build(a.variant, seed=0, calibrate_bn=False, **parse_overrides(a.set)).state_dict()
    kept, dropped = shrink(load_weights(a.weights), target)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    torch.save({"model": kept}, a.out)
    blocks = sorted({".".join(n.split(".")[:4]) for n in dropped})
    print(f"wrote {a.out}: {len(kept)} tensors kept, {len(dropped)} dropped ({', '.join(blocks)})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
