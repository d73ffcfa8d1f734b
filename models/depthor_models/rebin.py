"""Starting weights for a variant with fewer depth bins (the `n_bins` ablation of issue 16):
every `k` adjacent bins of a trained network merged into one.

    python -m depthor_models.rebin --weights mcu_lite/train/model_final.pt --bins 32 --out W.pt

Bin widths come from `bins_fc2` as `relu(l) + 0.1`: a merged bin's width is the sum of its
members' widths, so its row is the sum of their rows (and `0.1·(k − 1)` more bias, exact where the
members' logits are positive). Bin probabilities come from `bins_head`'s logits by softmax: a merged
bin's probability is the sum of its members', which the mean of their logits gives up to a
constant where they are close. Everything else is copied. Train the result with
`train --init W.pt --set n_bins=N`.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import torch
from torch import Tensor

from .train import load_weights


def merge_bins(state: dict[str, Tensor], bins: int) -> dict[str, Tensor]:
    """`state` with `bins_fc2` and `bins_head` reduced to `bins` outputs (a divisor of theirs)."""
    old = state["bins_head.weight"].shape[0]
    if bins <= 0 or old % bins:
        raise ValueError(f"{bins} bins do not divide the trained {old}")
    k = old // bins
    out = dict(state)

    def groups(t: Tensor) -> Tensor:
        return t.reshape(bins, k, *t.shape[1:])

    out["bins_fc2.weight"] = groups(state["bins_fc2.weight"]).sum(1)
    out["bins_fc2.bias"] = groups(state["bins_fc2.bias"]).sum(1) + 0.1 * (k - 1)
    out["bins_head.weight"] = groups(state["bins_head.weight"]).mean(1)
    out["bins_head.bias"] = groups(state["bins_head.bias"]).mean(1)
    return out


def main(argv: list[str] | None = None) -> int:
    """CLI entry point (see module doc)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--weights", required=True, help="trained checkpoint or state dict")
    ap.add_argument("--bins", type=int, required=True, help="bins of the new network")
    ap.add_argument("--out", required=True, help="state-dict file to write")
    a = ap.parse_args(argv)
    merged = merge_bins(load_weights(a.weights), a.bins)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    torch.save({"model": merged}, a.out)
    print(f"wrote {a.out}: {merged['bins_head.weight'].shape[0]} bins")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
