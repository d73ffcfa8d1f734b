"""Batch-norm population statistics recomputed over training frames.

    python -m depthor_models.bn_recalibrate --variant phone_lite --weights W.pt \
        --train DIR[,DIR…] --frames 400 --out W_bn.pt

A training run's running statistics are an exponential moving average (momentum 0.1) over its
last batches: with small, augmented batches the final values depend on which few batches came
last. This replaces every batch norm's running mean and variance by their average over `--frames`
training frames (clean RGB, not flipped; fixed order from `--seed`), in batches of `--batch`, with
every weight unchanged. Training frames only: the statistics are a property of the training data.
"""

from __future__ import annotations

import argparse

import numpy as np
import torch
from torch import nn

from . import data
from .train import load_weights, make_model, parse_overrides


@torch.no_grad()
def recalibrate(net: nn.Module, rec: data.Recording, frames: int, batch: int, seed: int) -> int:
    """Recomputes `net`'s batch-norm statistics (cumulative average) over `frames` frames of
    `rec`; returns how many batch norms were updated. Leaves `net` in eval mode."""
    bns = [m for m in net.modules() if isinstance(m, nn.BatchNorm2d)]
    saved = [m.momentum for m in bns]
    for m in bns:
        m.reset_running_stats()
        m.momentum = None  # cumulative moving average: the plain mean over batches
    order = np.random.default_rng(seed).permutation(len(rec))[:frames]
    net.train()
    for k in range(0, len(order), batch):
        rgb, sp, _ = data.batch(rec, order[k:k + batch])
        net(rgb, sp)
    for m, mom in zip(bns, saved):
        m.momentum = mom
    net.eval()
    return len(bns)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--variant", required=True)
    ap.add_argument("--weights", required=True, help="state dict or checkpoint")
    ap.add_argument("--train", required=True, help="training recording folder(s), comma-separated")
    ap.add_argument("--frames", type=int, default=400)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE")
    ap.add_argument("--out", required=True, help="where the state dict goes")
    a = ap.parse_args(argv)
    if a.frames < 1 or a.batch < 1:
        ap.error("--frames and --batch must be >= 1")
    torch.set_num_threads(a.threads)
    net = make_model(a.variant, 0, parse_overrides(a.set))
    net.load_state_dict(load_weights(a.weights))
    size = (net.cfg.height, net.cfg.width)
    rec = data.load_recordings(a.train, size=size)
    n = recalibrate(net, rec, min(a.frames, len(rec)), a.batch, a.seed)
    torch.save(net.state_dict(), a.out)
    print(f"{n} batch norms recomputed over {min(a.frames, len(rec))} frames of {a.train}; "
          f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
