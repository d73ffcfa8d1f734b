"""Starting weights for refine's dilated neighbourhood (the neighbours ablation of issue 16):
each affinity head of a trained network keeps the output channels of its window's dilated ring.

    python -m depthor_models.dilate --weights mcu_lite/train/model_final.pt --out W.pt

Channel c of `aff{s}` is the c-th neighbour of `ops.neighbour_offsets(s)`; the dilated ring
(`ops.neighbour_offsets(s, "dilated")`, 8 per window) is a subset of the window, so its channels'
weights and biases are copied as they are. Everything else is copied. The propagation then
normalises over 8 neighbours instead of s² − 1, so the result needs fine-tuning: `train --init
W.pt --set refine_neighbourhood=dilated`.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import torch
from torch import Tensor

from . import ops
from .train import load_weights


def dilated_heads(state: dict[str, Tensor]) -> dict[str, Tensor]:
    """`state` with the affinity heads of windows 3, 5, 7 cut to their dilated rings' channels."""
    out = dict(state)
    for size in ops.Refine.SIZES:
        window = ops.neighbour_offsets(size)
        keep = [window.index(o) for o in ops.neighbour_offsets(size, "dilated")]
        for part in ("weight", "bias"):
            key = f"aff{size}.{part}"
            if key not in state:
                raise KeyError(f"{key} missing: not a DEPTHOR network's weights")
            if state[key].shape[0] != len(window):
                raise ValueError(f"{key} has {state[key].shape[0]} outputs, the window "
                                 f"{len(window)}: already dilated?")
            out[key] = state[key][keep].clone()
    return out


def main(argv: list[str] | None = None) -> int:
    """CLI entry point (see module doc)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--weights", required=True, help="trained checkpoint or state dict")
    ap.add_argument("--out", required=True, help="state-dict file to write")
    a = ap.parse_args(argv)
    cut = dilated_heads(load_weights(a.weights))
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    torch.save({"model": cut}, a.out)
    sizes = [cut[f"aff{s}.weight"].shape[0] for s in ops.Refine.SIZES]
    print(f"wrote {a.out}: affinity heads {sizes}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
