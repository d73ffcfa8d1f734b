"""Golden tensors for the Rust tests: fixed-seed inputs, the output depth and a few intermediate
values (by graph.json value name) as raw little-endian f32 files plus `index.json`.

index.json: {"format": "depthor-golden/1", "variant", "seed", "graph": "../graph.json",
             "tensors": [{"name": <value name>, "role": "input"|"output"|"intermediate",
                          "file": <file name>, "shape": [1, C, H, W]}]}
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from torch import Tensor

from .graph_export import Traced

FORMAT = "depthor-golden/1"


def intermediate_names(graph: dict) -> list[str]:
    """Value names worth checking layer by layer: the prior's D_inv, a deep conv before and after
    its batch_norm and activation, the deepest CBAM output, the bin logits, d_half, d0 and kmix."""
    nodes = graph["nodes"]
    names = []
    first_mm = next(n for n in nodes if n["op"] == "minmax_norm")
    names.append(first_mm["inputs"][0])  # D_inv
    deep = [n for n in nodes if n["name"].startswith("depth_enc.stages.") and n["op"] == "conv2d"]
    if deep:
        conv = deep[-1]["output"]
        bn = next(n["output"] for n in nodes if n["inputs"] == [conv])
        act = next(n["output"] for n in nodes if n["inputs"] == [bn])
        names += [conv, bn, act]
    cbam = [n["name"] for n in nodes if n["name"].startswith("depth_enc.cbam.") and n["op"] == "mul"]
    names += cbam[-1:]
    refine = next(n for n in nodes if n["op"] == "refine")
    names += ["bins_fc2", "bins_head", refine["inputs"][0], refine["inputs"][4]]
    values = graph_values(graph)
    return [n for n in names if n in values]


def graph_values(graph: dict) -> set[str]:
    """All value names of a graph (inputs and node outputs)."""
    return {i["name"] for i in graph["inputs"]} | {n["output"] for n in graph["nodes"]}


def write(traced: Traced, out_dir: str | Path, seed: int) -> Path:
    """Writes inputs, output and :func:`intermediate_names` values; returns the index path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    entries = []

    def save(name: str, role: str, t: Tensor):
        fname = name.replace("/", "_") + ".f32"
        arr = np.ascontiguousarray(t.detach().cpu().numpy(), dtype="<f4")
        (out / fname).write_bytes(arr.tobytes())
        entries.append({"name": name, "role": role, "file": fname, "shape": list(arr.shape)})

    for spec in traced.graph["inputs"]:
        save(spec["name"], "input", traced.values[spec["name"]])
    for name in traced.graph["outputs"]:
        save(name, "output", traced.values[name])
    for name in intermediate_names(traced.graph):
        save(name, "intermediate", traced.values[name])
    index = {
        "format": FORMAT,
        "variant": traced.graph["variant"],
        "seed": seed,
        "graph": "../graph.json",
        "tensors": entries,
    }
    path = out / "index.json"
    path.write_text(json.dumps(index, indent=1) + "\n")
    return path


def read(index_path: str | Path) -> dict[str, np.ndarray]:
    """Loads every tensor listed in a golden index.json."""
    p = Path(index_path)
    index = json.loads(p.read_text())
    return {
        e["name"]: np.fromfile(p.parent / e["file"], dtype="<f4").reshape(e["shape"])
        for e in index["tensors"]
    }
