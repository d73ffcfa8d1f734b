"""graph.json + weights.bin exporter (docs/graph.md, format `depthor-graph/1`) and MAC counting.

The graph is recorded while the network runs one forward pass inside :func:`ops.recording`
(forward hooks give every op its module scope), so nodes come out in execution order = a
topological order, with BN parameters unfused and refine's σ as constants.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from . import ops
from .net import Depthor

FORMAT = "depthor-graph/1"
ALIGN = 64


@dataclass
class Traced:
    """A recorded forward pass: graph.json dict (offsets filled by :func:`pack_weights`),
    parameter tensors by name, and every value tensor by name."""

    graph: dict
    params: dict[str, Tensor]
    values: dict[str, Tensor]


@torch.no_grad()
def trace(net: Depthor, rgb: Tensor, sparse: Tensor) -> Traced:
    """Runs `net` once on (rgb, sparse) recording docs/graph.md nodes; the output value is `depth`."""
    if net.training:
        raise RuntimeError("trace needs the network in eval mode")
    if getattr(net.cfg, "sparse_input", "points") != "points":
        # the nearest-zone fill runs in PyTorch, outside the graph contract's ops
        raise ValueError("only sparse_input = 'points' exports (the fill is not a graph op)")
    with ops.recording(net) as rec:
        rec.add_input("rgb", rgb)
        rec.add_input("sparse", sparse)
        out = net(rgb, sparse)
        rec.rename(rec.value_name(out), "depth")
    cfg = net.cfg
    graph = {
        "format": FORMAT,
        "variant": cfg.variant,
        "height": cfg.height,
        "width": cfg.width,
        "inputs": [{"name": "rgb", "channels": 3}, {"name": "sparse", "channels": 1}],
        "outputs": ["depth"],
        "tensors": {name: {"shape": list(t.shape), "offset": None} for name, t in rec.params.items()},
        "nodes": [n.to_json() for n in rec.nodes],
    }
    return Traced(graph, dict(rec.params), dict(rec.values))


def pack_weights(traced: Traced) -> bytes:
    """Concatenates the parameters as little-endian f32 at 64-byte aligned offsets, filling in
    graph["tensors"][name]["offset"]; returns the weights.bin bytes."""
    buf = bytearray()
    for name, t in traced.params.items():
        pad = (-len(buf)) % ALIGN
        buf += b"\0" * pad
        traced.graph["tensors"][name]["offset"] = len(buf)
        buf += np.ascontiguousarray(t.cpu().numpy(), dtype="<f4").tobytes()
    return bytes(buf)


def write(traced: Traced, out_dir: str | Path) -> tuple[Path, Path]:
    """Writes `graph.json` and `weights.bin` into out_dir; returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    blob = pack_weights(traced)
    wpath, gpath = out / "weights.bin", out / "graph.json"
    wpath.write_bytes(blob)
    gpath.write_text(json.dumps(traced.graph, indent=1) + "\n")
    return gpath, wpath


def load(graph_path: str | Path, weights_path: str | Path | None = None):
    """Reads graph.json and its weights.bin → (graph dict, {param name: float32 ndarray})."""
    gpath = Path(graph_path)
    graph = json.loads(gpath.read_text())
    if graph.get("format") != FORMAT:
        raise ValueError(f"{gpath}: format {graph.get('format')!r}, expected {FORMAT!r}")
    blob = Path(weights_path or gpath.with_name("weights.bin")).read_bytes()
    weights = {}
    for name, info in graph["tensors"].items():
        n = int(np.prod(info["shape"])) if info["shape"] else 1
        off = info["offset"]
        if off % ALIGN or off + 4 * n > len(blob):
            raise ValueError(f"tensor {name}: bad offset {off}")
        weights[name] = np.frombuffer(blob, "<f4", n, off).reshape(info["shape"])
    return graph, weights


# ---------------------------------------------------------------------------------------------
# Counting
# ---------------------------------------------------------------------------------------------

def node_macs(node: dict, shapes: dict[str, tuple[int, ...]], graph: dict) -> int:
    """Multiply-accumulates of one node (conv/linear/bins_head/refine/upsample; 0 for the
    elementwise and pooling ops and for batch_norm, which the quantizer folds)."""
    op, a = node["op"], node["attrs"]
    out = shapes[node["output"]]
    numel = int(np.prod(out))
    if op == "conv2d":
        w = graph["tensors"][node["params"]["weight"]]["shape"]
        return numel * w[1] * w[2] * w[3]
    if op == "linear":
        w = graph["tensors"][node["params"]["weight"]]["shape"]
        return w[0] * w[1]
    if op == "bins_head":
        c = shapes[node["inputs"][0]][1]
        return numel * a["n_bins"] * (c + 1)
    if op == "refine":
        nb = a.get("neighbourhood", "window")
        per_iter = sum(len(ops.neighbour_offsets(s, nb)) + 1 for s in (3, 5, 7))
        return numel * a["iterations"] * per_iter
    if op == "upsample_bilinear":
        return 4 * numel
    return 0


def count(traced: Traced) -> dict:
    """Parameter and MAC counts of a traced graph.

    `params_graph`: every tensor in graph.json (BN statistics included); `params_deployed`: after
    BN folding (conv/linear/bins_head weights plus one bias per output channel).
    """
    g = traced.graph
    shapes = {k: tuple(v.shape) for k, v in traced.values.items()}
    macs_by_op: dict[str, int] = {}
    prior_macs = 0
    for node in g["nodes"]:
        m = node_macs(node, shapes, g)
        macs_by_op[node["op"]] = macs_by_op.get(node["op"], 0) + m
        if node["name"].startswith("prior."):
            prior_macs += m
    deployed, prior_params = 0, 0
    for node in g["nodes"]:
        if node["op"] in ("conv2d", "linear", "bins_head"):
            w = g["tensors"][node["params"]["weight"]]["shape"]
            n = int(np.prod(w)) + w[0]
            if node["name"] not in _first_use(g, node["params"]["weight"]):
                continue
            deployed += n
            if node["name"].startswith("prior."):
                prior_params += n
    return {
        "params_graph": sum(int(np.prod(t["shape"])) for t in g["tensors"].values()),
        "params_deployed": deployed,
        "params_prior": prior_params,
        "macs": sum(macs_by_op.values()),
        "macs_prior": prior_macs,
        "macs_by_op": macs_by_op,
    }


def _first_use(graph: dict, param: str) -> set[str]:
    for node in graph["nodes"]:
        if param in node["params"].values():
            return {node["name"]}
    return set()
