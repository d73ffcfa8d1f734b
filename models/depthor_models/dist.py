"""Data-parallel training on PyTorch's distributed engine (`torchrun`), as `train.py` uses it.

`setup()` reads the torchrun environment (`RANK`, `WORLD_SIZE`, `LOCAL_RANK`) and joins the
process group: gloo on CPU, nccl on CUDA (one GPU per local rank). Without torchrun it returns
a one-process `Dist` and nothing is initialised, so single-process training stays as it was.

Exactness: a step on N processes computes what one process computes on the whole global batch.
- Each rank runs its slice of the global batch. Losses that couple the batch (SILog pools all
  valid pixels) are computed from summed statistics (`all_reduce_sum`, differentiable: its
  backward is again a sum over ranks), so every rank holds the global loss.
- Batch norm in training mode uses the statistics of the global batch (`sync_batchnorm`).
- DistributedDataParallel averages the ranks' gradients. With every rank holding the global loss
  L and every collective's backward being the sum-adjoint, that average is exactly dL/dθ.
"""

from __future__ import annotations

import datetime
import os
from dataclasses import dataclass

import torch
import torch.distributed as tdist
from torch import Tensor

from . import ops


@dataclass
class Dist:
    """This process's place in the job: rank, world size, local rank, torch device, and (when
    world > 1) a process group for the loss and batch-norm sums and a gloo group for control."""

    rank: int = 0
    world: int = 1
    local_rank: int = 0
    device: torch.device = torch.device("cpu")
    group: object | None = None
    control: object | None = None

    @property
    def main(self) -> bool:
        """True on rank 0 (the one that writes checkpoints, logs and evaluates)."""
        return self.rank == 0


def pick_device(name: str | None) -> str:
    """`cpu` or `cuda`: `name` when given (ValueError for cuda without a GPU), else cuda when
    available."""
    if name is None:
        return "cuda" if torch.cuda.is_available() else "cpu"
    if name not in ("cpu", "cuda"):
        raise ValueError(f"--device {name!r}: expected cpu or cuda")
    if name == "cuda" and not torch.cuda.is_available():
        raise ValueError("--device cuda: torch sees no CUDA device")
    return name


def setup(device: str | None = None, timeout_min: float = 60.0) -> Dist:
    """Joins the torchrun job this process belongs to (see module doc), or returns the
    one-process Dist on `device` (autodetected when None)."""
    kind = pick_device(device)
    world = int(os.environ.get("WORLD_SIZE", "1"))
    rank = int(os.environ.get("RANK", "0"))
    local = int(os.environ.get("LOCAL_RANK", "0"))
    if kind == "cuda":
        torch.cuda.set_device(local)
        dev = torch.device("cuda", local)
    else:
        dev = torch.device("cpu")
    if world == 1:
        return Dist(0, 1, 0, dev)
    backend = "nccl" if kind == "cuda" else "gloo"
    timeout = datetime.timedelta(minutes=timeout_min)
    kw = {"device_id": dev} if kind == "cuda" else {}
    tdist.init_process_group(backend, timeout=timeout, **kw)
    group = tdist.new_group(backend=backend, timeout=timeout)
    control = tdist.new_group(backend="gloo", timeout=timeout)
    return Dist(tdist.get_rank(), tdist.get_world_size(), local, dev, group, control)


def close(d: Dist, wait: bool = True) -> None:
    """Leaves the process group (after every rank got here, when `wait`)."""
    if d.world > 1 and tdist.is_initialized():
        if wait:
            tdist.barrier(group=d.control)
        tdist.destroy_process_group()


class _AllReduceSum(torch.autograd.Function):
    @staticmethod
    def forward(ctx, x: Tensor, group) -> Tensor:
        ctx.group = group
        y = x.detach().clone()
        tdist.all_reduce(y, group=group)
        return y

    @staticmethod
    def backward(ctx, g: Tensor):
        g = g.contiguous().clone()
        tdist.all_reduce(g, group=ctx.group)
        return g, None


def all_reduce_sum(x: Tensor, d: Dist) -> Tensor:
    """Σ over ranks of `x`, differentiable (backward: Σ over ranks of the gradient); `x` itself
    in a one-process job."""
    if d.world == 1:
        return x
    return _AllReduceSum.apply(x, d.group)


def agree(values: list[float], d: Dist) -> list[float]:
    """Σ over ranks of a few control numbers (stop flags, rank 0's clock), on the gloo group."""
    if d.world == 1:
        return list(values)
    t = torch.tensor(values, dtype=torch.float64)
    tdist.all_reduce(t, group=d.control)
    return t.tolist()


class SyncedBatchNorm(ops.BatchNorm):
    """`ops.BatchNorm` whose training-mode statistics are those of the global batch over all
    ranks (mean, then the biased variance about it, two sums); running statistics are updated
    as torch's batch norm updates them (unbiased variance of the global batch). Eval mode is
    `ops.BatchNorm`'s."""

    dist: Dist

    def forward(self, x: Tensor) -> Tensor:
        if not self.training or self.dist.world == 1:
            return super().forward(x)
        c = x.shape[1]
        n_local = x.numel() // c
        s1 = torch.cat([x.sum(dim=(0, 2, 3)), x.new_tensor([float(n_local)])])
        s1 = all_reduce_sum(s1, self.dist)
        n = s1[c].detach()
        mean = s1[:c] / n
        xm = x - mean.view(1, c, 1, 1)
        var = all_reduce_sum((xm * xm).sum(dim=(0, 2, 3)), self.dist) / n
        y = xm * torch.rsqrt(var + self.eps).view(1, c, 1, 1)
        if self.affine:
            y = y * self.weight.view(1, c, 1, 1) + self.bias.view(1, c, 1, 1)
        if self.track_running_stats:
            with torch.no_grad():
                self.num_batches_tracked += 1
                m = self.momentum if self.momentum is not None else \
                    1.0 / float(self.num_batches_tracked)
                nn = float(n)
                self.running_mean.mul_(1 - m).add_(mean.detach(), alpha=m)
                self.running_var.mul_(1 - m).add_(var.detach() * (nn / max(nn - 1, 1.0)), alpha=m)
        return y


def sync_batchnorm(net: torch.nn.Module, d: Dist) -> torch.nn.Module:
    """Turns every `ops.BatchNorm` of `net` into a `SyncedBatchNorm` over `d`'s ranks, in place
    (same parameters and buffers, same state-dict keys); returns `net`. No-op for one process."""
    if d.world == 1:
        return net
    for m in net.modules():
        if isinstance(m, ops.BatchNorm):
            m.__class__ = SyncedBatchNorm
            m.dist = d
    return net
