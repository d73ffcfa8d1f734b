"""A small pure-numpy interpreter of graph.json (depthor-graph/1): the executable spec of the
docs/graph.md ops that the Rust core engine implements. It shares no code with the PyTorch ops, and
refine is written with explicit index bounds instead of padding, so agreement with PyTorch is a
real check of graph.json.

Tensors are [C, H, W] (N = 1 dropped); computation in float64 by default.
"""

from __future__ import annotations

import math

import numpy as np


def _act(x: np.ndarray, kind: str, alpha: float) -> np.ndarray:
    if kind == "none":
        return x
    if kind == "relu":
        return np.maximum(x, 0.0)
    if kind == "leaky_relu":
        return np.where(x >= 0.0, x, alpha * x)
    if kind == "sigmoid":
        return 1.0 / (1.0 + np.exp(-x))
    raise ValueError(f"unknown activation {kind!r}")


def conv2d(x, w, b, stride=1, dilation=1, padding=(0, 0), groups=1):
    """Direct im2col convolution, symmetric zero padding. x [C,H,W], w [O, C/g, kh, kw]."""
    c, h, wd = x.shape
    o, cg, kh, kw = w.shape
    ph, pw = padding
    ho = (h + 2 * ph - dilation * (kh - 1) - 1) // stride + 1
    wo = (wd + 2 * pw - dilation * (kw - 1) - 1) // stride + 1
    xp = np.pad(x, ((0, 0), (ph, ph), (pw, pw)))
    cols = np.empty((c, kh, kw, ho, wo), dtype=x.dtype)
    for i in range(kh):
        for j in range(kw):
            y0, x0 = i * dilation, j * dilation
            cols[:, i, j] = xp[:, y0 : y0 + stride * (ho - 1) + 1 : stride,
                               x0 : x0 + stride * (wo - 1) + 1 : stride]
    og = o // groups
    out = np.empty((o, ho * wo), dtype=x.dtype)
    for g in range(groups):
        cg_cols = cols[g * cg : (g + 1) * cg].reshape(cg * kh * kw, ho * wo)
        out[g * og : (g + 1) * og] = w[g * og : (g + 1) * og].reshape(og, -1) @ cg_cols
    if b is not None:
        out += b[:, None]
    return out.reshape(o, ho, wo)


def _interp_matrix(n_out: int, n_in: int, dtype) -> np.ndarray:
    """Row i holds the align_corners=True bilinear weights of output i over the inputs."""
    m = np.zeros((n_out, n_in), dtype=dtype)
    scale = (n_in - 1) / (n_out - 1) if n_out > 1 else 0.0
    for i in range(n_out):
        src = i * scale
        i0 = min(int(math.floor(src)), n_in - 1)
        i1 = min(i0 + 1, n_in - 1)
        f = src - i0
        m[i, i0] += 1.0 - f
        m[i, i1] += f
    return m


def upsample_bilinear(x, out_h, out_w):
    """Bilinear resize, align_corners = true."""
    ry = _interp_matrix(out_h, x.shape[1], x.dtype)
    rx = _interp_matrix(out_w, x.shape[2], x.dtype)
    return (ry @ x) @ rx.T


def pixel_shuffle(x, r):
    """[C·r², H, W] → [C, H·r, W·r] (PyTorch semantics)."""
    c, h, w = x.shape
    return x.reshape(c // (r * r), r, r, h, w).transpose(0, 3, 1, 4, 2).reshape(
        c // (r * r), h * r, w * r)


def _softmax0(x):
    e = np.exp(x - x.max(axis=0, keepdims=True))
    return e / e.sum(axis=0, keepdims=True)


def bins_head(feat, bin_logits, weight, bias, min_d, max_d):
    """docs/graph.md bins_head."""
    wi = np.maximum(bin_logits.reshape(-1), 0.0) + 0.1
    wi = wi / wi.sum()
    width = (max_d - min_d) * wi
    centre = min_d + np.concatenate([[0.0], np.cumsum(width)[:-1]]) + width / 2
    c, h, w = feat.shape
    logits = (weight @ feat.reshape(c, h * w) + bias[:, None])
    p = _softmax0(logits)
    return (centre @ p).reshape(1, h, w)


def offsets(size: int, neighbourhood: str = "window"):
    """(dy, dx) over the size×size window in raster order, centre skipped; "dilated" keeps those
    whose coordinates are multiples of the radius (the 3×3 ring dilated by size // 2)."""
    r = size // 2
    every = [(dy, dx) for dy in range(-r, r + 1) for dx in range(-r, r + 1) if (dy, dx) != (0, 0)]
    if neighbourhood == "window":
        return every
    if neighbourhood == "dilated":
        return [(dy, dx) for dy, dx in every if dy % r == 0 and dx % r == 0]
    raise ValueError(f"refine: unknown neighbourhood {neighbourhood!r}")


def _neighbour(a, dy, dx):
    """out[y, x] = a[y+dy, x+dx] inside the image, 0 outside; also the inside mask."""
    h, w = a.shape
    out = np.zeros_like(a)
    mask = np.zeros_like(a)
    ys, ye = max(0, -dy), min(h, h - dy)
    xs, xe = max(0, -dx), min(w, w - dx)
    if ys < ye and xs < xe:  # else the shift leaves the image entirely
        out[ys:ye, xs:xe] = a[ys + dy : ye + dy, xs + dx : xe + dx]
        mask[ys:ye, xs:xe] = 1.0
    return out, mask


def refine(d0, affs, kmix, tmix, iterations, sigmas, neighbourhood="window"):
    """docs/graph.md refine (three kernels 3/5/7)."""
    d0 = d0[0]
    weights = []
    for size, aff, sigma in zip((3, 5, 7), affs, sigmas):
        offs = offsets(size, neighbourhood)
        if aff.shape[0] != len(offs):
            raise ValueError(f"refine: aff{size} has {aff.shape[0]} channels, needs {len(offs)}")
        rs = []
        for c, (dy, dx) in enumerate(offs):
            g = math.exp(-(dx * dx + dy * dy) / (2.0 * sigma * sigma))
            _, inside = _neighbour(d0, dy, dx)
            rs.append(np.maximum(aff[c], 0.0) * g * inside)
        total = 1.0 + sum(rs)
        wj = [r / total for r in rs]
        wc = 1.0 - sum(wj)
        weights.append((offs, wj, wc))
    ks, ts = _softmax0(kmix), _softmax0(tmix)
    keep = (0, iterations // 2, iterations)
    state = [d0, d0, d0]
    out = np.zeros_like(d0)
    for t in range(iterations + 1):
        if t > 0:
            new = []
            for (offs, wj, wc), d in zip(weights, state):
                acc = wc * d
                for (dy, dx), w in zip(offs, wj):
                    acc = acc + w * _neighbour(d, dy, dx)[0]
                new.append(acc)
            state = new
        if t in keep:
            out = out + ts[keep.index(t)] * sum(ks[k] * state[k] for k in range(3))
    return out[None]


def eval_node(node: dict, weights: dict, xs: list[np.ndarray]) -> np.ndarray:
    """Evaluates one graph.json node on its input values ([C,H,W] arrays)."""
    op, a, p, W = node["op"], node["attrs"], node["params"], weights
    x = xs[0]
    if op == "conv2d":
        y = conv2d(x, W[p["weight"]], W.get(p.get("bias")), a["stride"], a["dilation"],
                   tuple(a["padding"]), a["groups"])
        return _act(y, a["activation"], a.get("alpha", 0.1))
    if op == "batch_norm":
        s = W[p["gamma"]] / np.sqrt(W[p["var"]] + a["eps"])
        return (x - W[p["mean"]][:, None, None]) * s[:, None, None] + W[p["beta"]][:, None, None]
    if op == "relu":
        return np.maximum(x, 0.0)
    if op == "leaky_relu":
        return np.where(x >= 0.0, x, a["alpha"] * x)
    if op == "sigmoid":
        return 1.0 / (1.0 + np.exp(-x))
    if op == "add":
        return xs[0] + xs[1]
    if op == "mul":
        return xs[0] * xs[1]
    if op == "concat":
        return np.concatenate(xs, axis=0)
    if op == "upsample_bilinear":
        return upsample_bilinear(x, a["out_h"], a["out_w"])
    if op == "pixel_shuffle":
        return pixel_shuffle(x, a["factor"])
    if op == "global_avg_pool":
        return x.mean(axis=(1, 2), keepdims=True)
    if op == "global_max_pool":
        return x.max(axis=(1, 2), keepdims=True)
    if op == "channel_mean":
        return x.mean(axis=0, keepdims=True)
    if op == "channel_max":
        return x.max(axis=0, keepdims=True)
    if op == "linear":
        y = W[p["weight"]] @ x.reshape(-1) + W[p["bias"]]
        return _act(y, a["activation"], a.get("alpha", 0.1)).reshape(-1, 1, 1)
    if op == "minmax_norm":
        lo, hi = x.min(), x.max()
        return (x - lo) / (hi - lo + a["eps"])
    if op == "reciprocal":
        return 1.0 / (x + a["eps"])
    if op == "bins_head":
        return bins_head(x, xs[1], W[p["weight"]], W[p["bias"]], a["min_depth_m"],
                         a["max_depth_m"])
    if op == "refine":
        return refine(xs[0], xs[1:4], xs[4], xs[5], a["iterations"], a["sigma"],
                      a.get("neighbourhood", "window"))
    raise ValueError(f"node {node['name']}: unknown op {op!r}")


def cast_weights(weights: dict, dtype=np.float64) -> dict:
    """The weights as arrays of `dtype`."""
    return {k: np.asarray(v, dtype=dtype) for k, v in weights.items()}


def run(graph: dict, weights: dict, inputs: dict, dtype=np.float64, keep_all: bool = False):
    """Executes graph.json nodes in order. `inputs` maps input names to [1,C,H,W] or [C,H,W]
    arrays; returns {value name: [C,H,W] array} holding the outputs (all values if keep_all)."""
    env = {}
    for spec in graph["inputs"]:
        a = np.asarray(inputs[spec["name"]], dtype=dtype)
        env[spec["name"]] = a[0] if a.ndim == 4 else a
    w = cast_weights(weights, dtype)
    for node in graph["nodes"]:
        y = eval_node(node, w, [env[i] for i in node["inputs"]])
        env[node["output"]] = y.astype(dtype, copy=False)
    if keep_all:
        return env
    return {name: env[name] for name in graph["outputs"]}
