"""Nearest-zone fill of a sparse zone map: each pixel takes the depth of the nearest zone point
within 0.75 zone pitch (the pitch estimated from the points' bounding box and count), 0 beyond.

An input representation for the issue-39 ablation (models/README.md "Ablation: zone input"): the
depth encoder sees each zone over its footprint instead of one pixel per zone. Not part of the
graph contract: a variant with `sparse_input = "fill"` applies it in PyTorch before its graph ops.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor

# fill radius in zone pitches: covers a regular grid's cells (half-diagonal 0.707) and stops
# 0.75 pitch outside the grid
RADIUS_PITCH = 0.75


def nearest_fill(sparse: Tensor, chunk: int = 8192) -> Tensor:
    """`sparse` [B,1,H,W] metres (0 = no point) → the nearest-zone fill, same shape."""
    b, _, h, w = sparse.shape
    out = torch.zeros_like(sparse)
    yy, xx = torch.meshgrid(torch.arange(h, device=sparse.device, dtype=torch.float32),
                            torch.arange(w, device=sparse.device, dtype=torch.float32),
                            indexing="ij")
    pix = torch.stack([yy.reshape(-1), xx.reshape(-1)], 1)
    for i in range(b):
        s = sparse[i, 0]
        ys, xs = torch.nonzero(s > 0, as_tuple=True)
        n = int(ys.numel())
        if n == 0:
            continue
        area = float((ys.max() - ys.min() + 1) * (xs.max() - xs.min() + 1))
        r2 = (RADIUS_PITCH * math.sqrt(area / n)) ** 2
        pts = torch.stack([ys, xs], 1).to(torch.float32)
        vals = s[ys, xs]
        flat = out[i, 0].view(-1)
        for c in range(0, h * w, chunk):
            d2 = torch.cdist(pix[c:c + chunk], pts).pow(2)
            dmin, j = d2.min(dim=1)
            flat[c:c + chunk] = torch.where(dmin <= r2, vals[j], torch.zeros_like(dmin))
    return out
