"""The docs/graph.md ops (depthor-graph/1) as PyTorch functions, plus the recorder that turns a forward
pass into graph.json nodes.

Every op here is plain PyTorch written in a form that torch-to-nnef exports and tract runs fast
(softmax as exp(x - amax) / sum exp, refinement as F.pad + shifted slices, interpolation sizes as
Python ints). When a :class:`Recorder` is active, each call appends one node named after the module
that owns it (``owner``) or after the module scope it runs in. Nothing is recorded otherwise, so the
same code is what torch-to-nnef traces.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass, field

import torch
import torch.nn.functional as F
from torch import Tensor, nn

# ---------------------------------------------------------------------------------------------
# Recorder
# ---------------------------------------------------------------------------------------------

_ACTIVE: "Recorder | None" = None
_FAKE_QUANT = None  # a qat.FakeQuant while a quantisation-aware forward pass runs


@dataclass
class Node:
    """One graph.json node: op name, unique node name, input value names, output value name."""

    op: str
    name: str
    inputs: list[str]
    output: str
    attrs: dict = field(default_factory=dict)
    params: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        """The node as graph.json writes it."""
        return {
            "op": self.op,
            "name": self.name,
            "inputs": list(self.inputs),
            "output": self.output,
            "attrs": dict(self.attrs),
            "params": dict(self.params),
        }


class Recorder:
    """Records docs/graph.md ops while a network runs forward (see :func:`recording`).

    Values are tracked by tensor identity; every tensor an op consumes must come from a graph
    input or an earlier recorded op, so a forgotten (unrecorded) torch op fails loudly.
    """

    def __init__(self, root: nn.Module):
        self.root = root
        self.nodes: list[Node] = []
        self.params: dict[str, Tensor] = {}
        self.values: dict[str, Tensor] = {}
        self._by_id: dict[int, tuple[Tensor, str]] = {}
        self._module_names = {m: n for n, m in root.named_modules()}
        self._scope: list[str] = []
        self._used: set[str] = set()
        self._hooks: list = []

    # -- values ---------------------------------------------------------------------------
    def add_input(self, name: str, t: Tensor) -> None:
        """Declares a graph input value."""
        self._bind(name, t)

    def value_name(self, t: Tensor) -> str:
        """The value name of a tensor produced by a recorded op or a graph input."""
        hit = self._by_id.get(id(t))
        if hit is None or hit[0] is not t:
            raise RuntimeError("tensor was not produced by a recorded graph op")
        return hit[1]

    def rename(self, old: str, new: str) -> None:
        """Renames a value (used to call the final output `depth`)."""
        t = self.values.pop(old)
        self.values[new] = t
        self._by_id[id(t)] = (t, new)
        for n in self.nodes:
            n.inputs = [new if i == old else i for i in n.inputs]
            if n.output == old:
                n.output = new

    def _bind(self, name: str, t: Tensor) -> None:
        if name in self.values:
            raise RuntimeError(f"value {name!r} produced twice")
        self.values[name] = t
        self._by_id[id(t)] = (t, name)

    # -- naming ---------------------------------------------------------------------------
    def _unique(self, base: str) -> str:
        name, k = base, 1
        while name in self._used:
            name = f"{base}_{k}"
            k += 1
        self._used.add(name)
        return name

    def node_name(self, op: str, owner: nn.Module | None) -> str:
        """A unique node name: the owner's module path, else `<scope>.<op>`."""
        if owner is not None:
            return self._unique(self._module_names[owner])
        scope = self._scope[-1] if self._scope else ""
        return self._unique(f"{scope}.{op}" if scope else op)

    def param_name(self, owner: nn.Module, attr: str) -> str:
        """The tensors-table name of a module parameter/buffer, registered on first use."""
        path = self._module_names[owner]
        name = f"{path}.{attr}" if path else attr
        t = getattr(owner, attr)
        if name not in self.params:
            self.params[name] = t.detach().clone().float()
        return name

    # -- hooks ----------------------------------------------------------------------------
    def __enter__(self) -> "Recorder":
        global _ACTIVE
        if _ACTIVE is not None:
            raise RuntimeError("a Recorder is already active")
        for m, n in self._module_names.items():
            self._hooks.append(m.register_forward_pre_hook(self._push(n)))
            self._hooks.append(m.register_forward_hook(self._pop))
        _ACTIVE = self
        return self

    def __exit__(self, *exc) -> None:
        global _ACTIVE
        _ACTIVE = None
        for h in self._hooks:
            h.remove()
        self._hooks.clear()

    def _push(self, name: str):
        def hook(_module, _args):
            self._scope.append(name)

        return hook

    def _pop(self, _module, _args, _out):
        self._scope.pop()

    # -- recording --------------------------------------------------------------------------
    def record(
        self,
        op: str,
        inputs: list[Tensor],
        out: Tensor,
        attrs: dict | None = None,
        params: dict[str, str] | None = None,
        owner: nn.Module | None = None,
    ) -> None:
        """Appends one node; `params` maps docs/graph.md param keys to `owner` attribute names."""
        name = self.node_name(op, owner)
        in_names = [self.value_name(t) for t in inputs]
        pmap = {}
        for key, attr in (params or {}).items():
            if owner is None:
                raise RuntimeError("params need an owner module")
            if getattr(owner, attr, None) is not None:
                pmap[key] = self.param_name(owner, attr)
        self._bind(name, out)
        self.nodes.append(Node(op, name, in_names, name, dict(attrs or {}), pmap))


def active() -> Recorder | None:
    """The recorder of the enclosing :func:`recording` block, if any."""
    return _ACTIVE


@contextlib.contextmanager
def recording(root: nn.Module):
    """Context in which graph ops executed by `root` (and its submodules) are recorded."""
    with Recorder(root) as rec:
        yield rec


def set_fake_quant(fq) -> None:
    """Installs (or with None removes) the int8 rounding of :mod:`depthor_models.qat`."""
    global _FAKE_QUANT
    _FAKE_QUANT = fq


def _rec(op, inputs, out, attrs=None, params=None, owner=None) -> Tensor:
    if _ACTIVE is not None:
        _ACTIVE.record(op, inputs, out, attrs, params, owner)
    elif _FAKE_QUANT is not None:
        out = _FAKE_QUANT.value(op, out)
    return out


def _w(weight: Tensor) -> Tensor:
    """A parametrised op's weight as the forward pass uses it (int8-rounded under QAT)."""
    return weight if _FAKE_QUANT is None else _FAKE_QUANT.weight(weight)


# ---------------------------------------------------------------------------------------------
# Ops (docs/graph.md names)
# ---------------------------------------------------------------------------------------------

ACTIVATIONS = ("none", "relu", "leaky_relu", "sigmoid")


def apply_activation(x: Tensor, activation: str, alpha: float = 0.1) -> Tensor:
    """The fused activation of conv2d/linear."""
    if activation == "none":
        return x
    if activation == "relu":
        return F.relu(x)
    if activation == "leaky_relu":
        return F.leaky_relu(x, alpha)
    if activation == "sigmoid":
        return torch.sigmoid(x)
    raise ValueError(f"unknown activation {activation!r}")


def relu(x: Tensor, owner: nn.Module | None = None) -> Tensor:
    """Elementwise max(x, 0) (`owner`: the module whose path names the node)."""
    return _rec("relu", [x], F.relu(x), owner=owner)


def leaky_relu(x: Tensor, alpha: float = 0.1, owner: nn.Module | None = None) -> Tensor:
    """Elementwise leaky ReLU with slope `alpha` for x < 0."""
    return _rec("leaky_relu", [x], F.leaky_relu(x, alpha), {"alpha": alpha}, owner=owner)


def sigmoid(x: Tensor) -> Tensor:
    """Elementwise logistic function."""
    return _rec("sigmoid", [x], torch.sigmoid(x))


def add(a: Tensor, b: Tensor) -> Tensor:
    """a + b, same shape."""
    if a.shape != b.shape:
        raise ValueError(f"add: shapes differ {tuple(a.shape)} vs {tuple(b.shape)}")
    return _rec("add", [a, b], a + b)


def mul(a: Tensor, b: Tensor) -> Tensor:
    """a * b where b is [1,1,H,W] (broadcast over channels) or [1,C,1,1] (over space)."""
    ok = (b.shape[1] == 1 and b.shape[2:] == a.shape[2:]) or (
        b.shape[1] == a.shape[1] and b.shape[2] == 1 and b.shape[3] == 1
    )
    if not ok:
        raise ValueError(f"mul: cannot broadcast {tuple(b.shape)} onto {tuple(a.shape)}")
    return _rec("mul", [a, b], a * b)


def concat(xs: list[Tensor]) -> Tensor:
    """Channel concatenation."""
    return _rec("concat", list(xs), torch.cat(xs, dim=1))


def upsample_bilinear(x: Tensor, out_h: int, out_w: int) -> Tensor:
    """Bilinear resize with align_corners=True to an explicit size."""
    out_h, out_w = int(out_h), int(out_w)
    y = F.interpolate(x, size=(out_h, out_w), mode="bilinear", align_corners=True)
    return _rec("upsample_bilinear", [x], y, {"out_h": out_h, "out_w": out_w})


def pixel_shuffle(x: Tensor, factor: int) -> Tensor:
    """[C*r*r, H, W] -> [C, H*r, W*r] (PyTorch semantics)."""
    return _rec("pixel_shuffle", [x], F.pixel_shuffle(x, factor), {"factor": int(factor)})


def global_avg_pool(x: Tensor) -> Tensor:
    """[C,H,W] -> [C,1,1] mean."""
    return _rec("global_avg_pool", [x], x.mean(dim=(2, 3), keepdim=True))


def global_max_pool(x: Tensor) -> Tensor:
    """[C,H,W] -> [C,1,1] max."""
    return _rec("global_max_pool", [x], x.amax(dim=(2, 3), keepdim=True))


def channel_mean(x: Tensor) -> Tensor:
    """[C,H,W] -> [1,H,W] mean over channels."""
    return _rec("channel_mean", [x], x.mean(dim=1, keepdim=True))


def channel_max(x: Tensor) -> Tensor:
    """[C,H,W] -> [1,H,W] max over channels."""
    return _rec("channel_max", [x], x.amax(dim=1, keepdim=True))


def minmax_norm(x: Tensor, eps: float = 1e-6) -> Tensor:
    """(x - min x) / (max x - min x + eps) over the whole tensor."""
    lo = x.amin(dim=(1, 2, 3), keepdim=True)
    hi = x.amax(dim=(1, 2, 3), keepdim=True)
    return _rec("minmax_norm", [x], (x - lo) / (hi - lo + eps), {"eps": eps})


def reciprocal(x: Tensor, eps: float = 1e-3) -> Tensor:
    """1 / (x + eps)."""
    return _rec("reciprocal", [x], 1.0 / (x + eps), {"eps": eps})


def channel_softmax(x: Tensor) -> Tensor:
    """Softmax over channels written as exp(x - amax) / sum exp (fast in tract). Not a graph op."""
    e = torch.exp(x - x.amax(dim=1, keepdim=True))
    return e / e.sum(dim=1, keepdim=True)


def bin_centres(bin_logits: Tensor, min_depth: float, max_depth: float) -> Tensor:
    """docs/graph.md bins: w = relu(l) + 0.1 normalised; centre_i = min + sum_{j<i} width_j + width_i/2.

    `bin_logits` is [1, N, 1, 1]; returns centres [1, N, 1, 1] in metres.
    """
    w = F.relu(bin_logits) + 0.1
    w = w / w.sum(dim=1, keepdim=True)
    width = (max_depth - min_depth) * w
    return min_depth + torch.cumsum(width, dim=1) - 0.5 * width


def bins_head_math(
    feat: Tensor, bin_logits: Tensor, weight: Tensor, bias: Tensor, min_depth: float, max_depth: float
) -> Tensor:
    """docs/graph.md bins_head semantics: sum_i softmax_i(W F + b) * centre_i -> [1,1,h,w] metres."""
    centres = bin_centres(bin_logits, min_depth, max_depth)
    logits = F.conv2d(feat, weight[:, :, None, None], bias)
    e = torch.exp(logits - logits.amax(dim=1, keepdim=True))
    return (e * centres).sum(dim=1, keepdim=True) / e.sum(dim=1, keepdim=True)


NEIGHBOURHOODS = ("window", "dilated")


def neighbour_offsets(size: int, neighbourhood: str = "window") -> list[tuple[int, int]]:
    """(dy, dx) of the s*s window's neighbours in raster order, centre skipped (channel c <-> c-th
    entry): every pixel ("window", s*s - 1) or the 3×3 ring dilated by s // 2 ("dilated", 8)."""
    if neighbourhood not in NEIGHBOURHOODS:
        raise ValueError(f"refine: neighbourhood must be one of {NEIGHBOURHOODS}")
    r = size // 2
    step = r if neighbourhood == "dilated" and r > 0 else 1
    return [(dy, dx) for dy in range(-r, r + 1, step) for dx in range(-r, r + 1, step)
            if (dy, dx) != (0, 0)]


def _inside_mask(offsets: list[tuple[int, int]], h: int, w: int, dtype, device=None) -> Tensor:
    """[1, n, H, W] with 1 where neighbour (dy, dx) of (y, x) lies inside the image: a product of
    a row mask and a column mask, both small trace-time constants (made on `device`)."""
    rows = [[1.0 if 0 <= y + dy < h else 0.0 for y in range(h)] for dy, _ in offsets]
    cols = [[1.0 if 0 <= x + dx < w else 0.0 for x in range(w)] for _, dx in offsets]
    n = len(offsets)
    return (torch.tensor(rows, dtype=dtype, device=device).view(1, n, h, 1)
            * torch.tensor(cols, dtype=dtype, device=device).view(1, n, 1, w))


def _window_stack(d: Tensor, size: int, h: int, w: int) -> Tensor:
    """All size×size shifts of d with zeros outside: [1, s*s, H, W], channel b*s + a holding
    d[y + a - r, x + b - r] (column-major over the window, centre included). Written as one
    F.pad, s row slices, s column slices and two concats so the traced graph stays small."""
    r = size // 2
    p = F.pad(d, (r, r, r, r))
    rows = torch.cat([p.narrow(2, a, h) for a in range(size)], dim=1)  # [1, s, H, W + 2r]
    return torch.cat([rows.narrow(3, b, w) for b in range(size)], dim=1)


def refine_math(
    d0: Tensor,
    affs: list[Tensor],
    kmix: Tensor,
    tmix: Tensor,
    sigmas: Tensor,
    sizes: tuple[int, ...] = (3, 5, 7),
    iterations: int = 6,
    neighbourhood: str = "window",
) -> Tensor:
    """docs/graph.md refine semantics with F.pad + shifted slices (neighbours outside the image add 0).

    `sigmas` is a 1-D tensor [σ3, σ5, σ7] (learnable in training, constants in the graph);
    `neighbourhood` picks each window's neighbours (`neighbour_offsets`); window pixels that are
    not neighbours get weight 0.
    """
    if iterations % 2 != 0:
        raise ValueError("refine: iterations must be even")
    h, w = int(d0.shape[2]), int(d0.shape[3])
    kernels = []
    for k, (size, aff) in enumerate(zip(sizes, affs)):
        offs = neighbour_offsets(size, neighbourhood)
        if aff.shape[1] != len(offs):
            raise ValueError(f"refine: aff{size} needs {len(offs)} channels, got {aff.shape[1]}")
        d2 = torch.tensor([float(dy * dy + dx * dx) for dy, dx in offs], dtype=d0.dtype,
                          device=d0.device)
        g = torch.exp(-d2 / (2.0 * sigmas[k] * sigmas[k])).view(1, -1, 1, 1)
        rj = F.relu(aff) * g * _inside_mask(offs, h, w, d0.dtype, d0.device)
        wj = rj / (1.0 + rj.sum(dim=1, keepdim=True))
        wc = 1.0 - wj.sum(dim=1, keepdim=True)
        # weights in _window_stack's channel order (column-major, centre included)
        r = size // 2
        full = []
        zero = torch.zeros_like(wc)
        for b in range(size):
            for a in range(size):
                dy, dx = a - r, b - r
                if (dy, dx) == (0, 0):
                    full.append(wc)
                elif (dy, dx) in offs:
                    full.append(wj.narrow(1, offs.index((dy, dx)), 1))
                else:
                    full.append(zero)
        kernels.append((size, torch.cat(full, dim=1)))
    ksm = channel_softmax(kmix)
    tsm = channel_softmax(tmix)
    keep = (0, iterations // 2, iterations)
    mixed = []
    state = [d0 for _ in sizes]
    for t in range(iterations + 1):
        if t > 0:
            state = [(wk * _window_stack(d, size, h, w)).sum(dim=1, keepdim=True)
                     for (size, wk), d in zip(kernels, state)]
        if t in keep:
            mixed.append(sum(ksm.narrow(1, k, 1) * state[k] for k in range(len(sizes))))
    return sum(tsm.narrow(1, i, 1) * mixed[i] for i in range(len(keep)))


# ---------------------------------------------------------------------------------------------
# Parametrised ops as modules (the owner names their node and parameters)
# ---------------------------------------------------------------------------------------------


class Conv(nn.Conv2d):
    """docs/graph.md conv2d with symmetric zero padding and a fused activation."""

    def __init__(
        self,
        cin: int,
        cout: int,
        kernel: int = 3,
        stride: int = 1,
        dilation: int = 1,
        padding: int | None = None,
        groups: int = 1,
        bias: bool = True,
        activation: str = "none",
        alpha: float = 0.1,
    ):
        if padding is None:
            padding = dilation * (kernel // 2)
        super().__init__(cin, cout, kernel, stride, padding, dilation, groups, bias)
        if activation not in ACTIVATIONS:
            raise ValueError(f"unknown activation {activation!r}")
        self.activation = activation
        self.alpha = alpha

    def forward(self, x: Tensor) -> Tensor:
        y = apply_activation(F.conv2d(x, _w(self.weight), self.bias, self.stride, self.padding,
                                      self.dilation, self.groups), self.activation, self.alpha)
        attrs = {
            "out_channels": self.out_channels,
            "kernel": list(self.kernel_size),
            "stride": self.stride[0],
            "dilation": self.dilation[0],
            "padding": list(self.padding),
            "groups": self.groups,
            "activation": self.activation,
            "alpha": self.alpha,
        }
        return _rec("conv2d", [x], y, attrs, {"weight": "weight", "bias": "bias"}, self)


class BatchNorm(nn.BatchNorm2d):
    """docs/graph.md batch_norm (inference: running statistics; the quantizer folds it)."""

    def forward(self, x: Tensor) -> Tensor:
        y = super().forward(x)
        params = {"gamma": "weight", "beta": "bias", "mean": "running_mean", "var": "running_var"}
        return _rec("batch_norm", [x], y, {"eps": self.eps}, params, self)


class Linear(nn.Linear):
    """docs/graph.md linear on a [1, I, 1, 1] vector with a fused activation."""

    def __init__(self, cin: int, cout: int, activation: str = "none", alpha: float = 0.1):
        super().__init__(cin, cout)
        self.activation = activation
        self.alpha = alpha

    def forward(self, x: Tensor) -> Tensor:
        y = F.conv2d(x, _w(self.weight)[:, :, None, None], self.bias)
        y = apply_activation(y, self.activation, self.alpha)
        attrs = {"activation": self.activation, "alpha": self.alpha}
        return _rec("linear", [x], y, attrs, {"weight": "weight", "bias": "bias"}, self)


class BinsHead(nn.Module):
    """docs/graph.md bins_head: per-pixel 1×1 logits, softmax over N bins, expectation of bin centres."""

    def __init__(self, cin: int, n_bins: int, min_depth: float, max_depth: float):
        super().__init__()
        self.n_bins, self.min_depth, self.max_depth = n_bins, float(min_depth), float(max_depth)
        self.weight = nn.Parameter(torch.empty(n_bins, cin))
        self.bias = nn.Parameter(torch.zeros(n_bins))
        nn.init.kaiming_uniform_(self.weight, a=math.sqrt(5))

    def forward(self, feat: Tensor, bin_logits: Tensor) -> Tensor:
        y = bins_head_math(feat, bin_logits, _w(self.weight), self.bias, self.min_depth,
                           self.max_depth)
        attrs = {"n_bins": self.n_bins, "min_depth_m": self.min_depth, "max_depth_m": self.max_depth}
        return _rec("bins_head", [feat, bin_logits], y, attrs,
                    {"weight": "weight", "bias": "bias"}, self)


class Refine(nn.Module):
    """docs/graph.md refine: 3/5/7 affinity propagation, T iterations, per-pixel kernel/time mixing;
    each window's neighbours as `neighbourhood` says (`neighbour_offsets`)."""

    SIZES = (3, 5, 7)

    def __init__(self, iterations: int = 6, sigmas: tuple[float, float, float] = (1.0, 2.0, 3.0),
                 neighbourhood: str = "window"):
        super().__init__()
        if iterations % 2 != 0 or iterations < 2:
            raise ValueError("refine: iterations must be even and >= 2")
        if neighbourhood not in NEIGHBOURHOODS:
            raise ValueError(f"refine: neighbourhood must be one of {NEIGHBOURHOODS}")
        self.iterations = iterations
        self.neighbourhood = neighbourhood
        self.sigma = nn.Parameter(torch.tensor(sigmas, dtype=torch.float32))

    def neighbours(self) -> list[int]:
        """Affinity channels of the three branches."""
        return [len(neighbour_offsets(s, self.neighbourhood)) for s in self.SIZES]

    def forward(self, d0, aff3, aff5, aff7, kmix, tmix) -> Tensor:
        y = refine_math(d0, [aff3, aff5, aff7], kmix, tmix, self.sigma, self.SIZES, self.iterations,
                        self.neighbourhood)
        if _ACTIVE is None:
            return _rec("refine", [], y)
        attrs = {"iterations": self.iterations,
                 "sigma": [float(s) for s in self.sigma.detach().cpu()]}
        if self.neighbourhood != "window":
            attrs["neighbourhood"] = self.neighbourhood
        return _rec("refine", [d0, aff3, aff5, aff7, kmix, tmix], y, attrs, None, self)
