"""Quantisation-aware training: the int8 rounding of the core's engine simulated in the forward pass.

The host quantizer (docs/blob.md, `host/src/quantize`) turns the float network into the int8 blob:
batch norm folded into the conv before it, a ReLU / LeakyReLU reading only that conv fused into it,
weights per output channel symmetric on ±127, every other value per tensor asymmetric on
[−128, 127] with its range widened to include 0; `minmax_norm` and `sigmoid` outputs on [0, 1];
`upsample_bilinear` / `pixel_shuffle` keep their input's parameters; `bins_head` and `refine` (and
what is computed from their f32 outputs) stay f32. :class:`FakeQuant` applies the same rounding
while the network trains, with straight-through gradients, so the weights learn to live with it:

* weights: per output channel, `scale = max|w| / 127` (folding a batch norm multiplies each output
  channel by one factor, which scales that channel's grid with it: rounding the unfolded weights
  per channel is the same rounding);
* values: the node outputs the blob stores in int8 (the plan is read off one recorded forward
  pass, :func:`int8_values`), ranges tracked as an exponential moving average of each batch's
  min / max while training, frozen in eval mode;
* batch norm runs on its running statistics (what gets folded), so it is put in eval mode on every
  forward.

The quantizer calibrates its own ranges from frames when the blob is made unless it is given the
ones tracked here (:meth:`FakeQuant.ranges_by_name`, written by train.py as `qat_ranges.json`,
read by `depthor quantize --ranges-file`, docs/blob.md): then the blob rounds as the network
trained.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from . import ops

_FUSED_ACTS = ("relu", "leaky_relu")
_UNIT_RANGE = ("minmax_norm", "sigmoid")
_KEEPS_INPUT = ("upsample_bilinear", "pixel_shuffle")
_F32_OPS = ("bins_head", "refine")


def int8_values(nodes: list[ops.Node]) -> list[str]:
    """Per recorded node (call order), how the quantizer stores its output: "int8" (own range),
    "unit" ([0, 1]), "same" (its input's parameters: not rounded again), "fused" (folded into a
    later node: never stored) or "f32"."""
    readers: dict[str, list[int]] = {}
    for i, n in enumerate(nodes):
        for v in n.inputs:
            readers.setdefault(v, []).append(i)

    def sole_reader(i: int) -> int | None:
        r = readers.get(nodes[i].output, [])
        return r[0] if len(r) == 1 else None

    kind = ["int8"] * len(nodes)
    f32_values: set[str] = set()
    for i, n in enumerate(nodes):
        if kind[i] == "fused":
            continue
        if n.op in _F32_OPS or (n.op in _KEEPS_INPUT and n.inputs[0] in f32_values):
            kind[i] = "f32"
            f32_values.add(n.output)
            continue
        if n.op in _UNIT_RANGE or n.attrs.get("activation") == "sigmoid":
            kind[i] = "unit"
        elif n.op in _KEEPS_INPUT:
            kind[i] = "same"
        if n.op == "conv2d" and n.attrs.get("activation") == "none":
            last = i
            j = sole_reader(i)
            if j is not None and nodes[j].op == "batch_norm":
                kind[i], last = "fused", j
            j = sole_reader(last)
            if j is not None and nodes[j].op in _FUSED_ACTS:
                kind[last] = "fused"
    return kind


class FakeQuant:
    """Simulated int8 rounding on `net` (a `Depthor` or `DepthorLite`); see the module doc.

    `FakeQuant(net, example_rgb, example_sparse).attach()` adds forward hooks to `net`; while
    attached, `net(rgb, sparse)` is the fake-quantised network (the float one, batch norm still
    on its running statistics, while `enabled` is False). Ranges live in `self.lo` /
    `self.hi` (one entry per recorded node) and in :meth:`state_dict`.
    """

    def __init__(self, net: nn.Module, rgb: Tensor, sparse: Tensor, momentum: float = 0.02):
        self.net = net
        was = net.training
        net.eval()
        with torch.no_grad(), ops.recording(net) as rec:
            rec.add_input("rgb", rgb)
            rec.add_input("sparse", sparse)
            net(rgb, sparse)
        net.train(was)
        self.ops = [n.op for n in rec.nodes]
        self.names = [n.output for n in rec.nodes]
        self.enabled = True
        self.unrounded: set[int] = set()  # node indices left in float (int8_sensitivity.py)
        self.kind = int8_values(rec.nodes)
        self.momentum = momentum
        self.max_depth = float(_max_depth(net))
        dev = next(net.parameters()).device
        self.lo = torch.zeros(len(self.kind), device=dev)
        self.hi = torch.zeros(len(self.kind), device=dev)
        self.seen = [False] * len(self.kind)
        self.index = 0
        self._hooks: list = []

    # -- hooks ------------------------------------------------------------------------------
    def attach(self) -> "FakeQuant":
        """Hooks the rounding into every forward of `net` (inputs, weights and node outputs)."""
        self._hooks.append(self.net.register_forward_pre_hook(self._enter))
        self._hooks.append(self.net.register_forward_hook(self._leave))
        return self

    def detach(self) -> None:
        """Removes the hooks: `net` is the float network again."""
        for h in self._hooks:
            h.remove()
        self._hooks.clear()

    def _enter(self, _module, args):
        for m in self.net.modules():
            if isinstance(m, nn.BatchNorm2d):
                m.eval()
        self.index = 0
        if not self.enabled:
            return None
        ops.set_fake_quant(self)
        rgb, sparse = args
        return (_affine(rgb, 0.0, 1.0), _affine(sparse, 0.0, self.max_depth))

    def _leave(self, _module, _args, out):
        ops.set_fake_quant(None)
        if self.enabled and self.index != len(self.kind):
            raise RuntimeError(f"fake quant: {self.index} nodes ran, the plan has {len(self.kind)}")
        return out

    # -- called from ops ----------------------------------------------------------------------
    def value(self, op: str, out: Tensor) -> Tensor:
        """The stored form of the next node's output (call order)."""
        i = self.index
        self.index += 1
        if i >= len(self.kind) or self.ops[i] != op:
            got = self.ops[i] if i < len(self.ops) else "nothing"
            raise RuntimeError(f"fake quant: node {i} is {op}, the plan says {got}")
        k = self.kind[i]
        if k in ("fused", "same", "f32") or i in self.unrounded:
            return out
        if k == "unit":
            return _affine(out, 0.0, 1.0)
        if self.net.training:
            with torch.no_grad():
                lo, hi = out.detach().amin().float(), out.detach().amax().float()
                if self.seen[i]:
                    m = self.momentum
                    self.lo[i] = (1 - m) * self.lo[i] + m * lo
                    self.hi[i] = (1 - m) * self.hi[i] + m * hi
                else:
                    self.lo[i], self.hi[i] = lo, hi
                    self.seen[i] = True
        if not self.seen[i]:
            return out
        return _affine(out, self.lo[i], self.hi[i])

    @staticmethod
    def weight(w: Tensor) -> Tensor:
        """Per-output-channel symmetric int8 rounding of a conv / linear / bins weight."""
        flat = w.detach().reshape(w.shape[0], -1)
        scale = (flat.abs().amax(dim=1) / 127.0).clamp_min(1e-12).float()
        zp = torch.zeros(w.shape[0], dtype=torch.int32, device=w.device)
        return torch.fake_quantize_per_channel_affine(w, scale, zp, 0, -127, 127)

    # -- state ----------------------------------------------------------------------------
    def state_dict(self) -> dict:
        """The tracked ranges (for checkpoints)."""
        return {"lo": self.lo.cpu(), "hi": self.hi.cpu(), "seen": list(self.seen), "ops": self.ops}

    def set_ranges(self, ranges: dict[str, list[float]]) -> int:
        """Takes the ranges of :meth:`ranges_by_name`'s form (e.g. a run's `qat_ranges.json`);
        returns how many int8 values got one."""
        n = 0
        for i, name in enumerate(self.names):
            if self.kind[i] == "int8" and name in ranges:
                self.lo[i], self.hi[i] = (float(x) for x in ranges[name])
                self.seen[i] = True
                n += 1
        return n

    def ranges_by_name(self) -> dict[str, list[float]]:
        """The tracked range of every value stored with its own int8 range, by graph value name
        (`depthor quantize --ranges-file` takes this, so the blob uses the ranges trained with)."""
        return {self.names[i]: [float(self.lo[i]), float(self.hi[i])]
                for i, k in enumerate(self.kind) if k == "int8" and self.seen[i]}

    def load_state_dict(self, st: dict) -> None:
        """Restores :meth:`state_dict` (the plan must be the same network's)."""
        if list(st["ops"]) != self.ops:
            raise ValueError("fake quant state is of another network")
        dev = self.lo.device
        self.lo, self.hi, self.seen = st["lo"].to(dev), st["hi"].to(dev), list(st["seen"])


def _max_depth(net: nn.Module) -> float:
    for m in net.modules():
        if isinstance(m, ops.BinsHead):
            return m.max_depth
    raise ValueError("fake quant: the network has no bins head")


def _affine(x: Tensor, lo, hi) -> Tensor:
    """Asymmetric int8 rounding of `x` on [lo, hi] widened to include 0 (calibrate.rs
    `affine_params`), straight-through inside the range."""
    lo = torch.as_tensor(lo, dtype=torch.float32, device=x.device).clamp_max(0.0)
    hi = torch.as_tensor(hi, dtype=torch.float32, device=x.device).clamp_min(0.0)
    scale = ((hi - lo).clamp_min(1e-6) / 255.0).reshape(1)
    zp = torch.round(-128.0 - lo / scale).clamp(-128, 127).to(torch.int32).reshape(1)
    if x.dtype != torch.float32:
        return torch.fake_quantize_per_tensor_affine(x.float(), scale, zp, -128, 127).to(x.dtype)
    return torch.fake_quantize_per_tensor_affine(x, scale, zp, -128, 127)
