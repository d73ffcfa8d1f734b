"""MACs and int8 weight bytes of a variant, in total and per part of the network (issue 16
budgets: `mcu` class ≤ 40 M MACs at 120×160 and ≤ 256 KiB of int8 weights).

    python -m depthor_models.budget --variant mcu_lite [--variant mcu] [--json]

MACs follow `graph_export.count` (conv2d = out elements × I/g × kh × kw, linear = O × I,
bins_head = h·w·N·(C+1), refine = T·H·W·Σ(n_k + 1), upsample = 4 per output; BN folded,
element-wise ops 0). Weight bytes: `weights_int8` counts one byte per conv/linear/bins-head
weight (what the 256 KiB budget names); `blob_param_bytes` adds what the blob stores per output
channel besides (int32 bias + f32 scale, 8 bytes), i.e. the weight part of the int8 blob.
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import torch

from . import graph_export
from .net import build, parse_overrides, random_inputs

MAC_BUDGET = {"mcu_lite": 40e6}
WEIGHT_BUDGET_BYTES = {"mcu_lite": 256 * 1024}

# name prefixes → report group (first match wins; order matters)
GROUPS = (
    ("prior.enc", "prior / RGB encoder (shared, 1/2…1/16)"),
    ("prior.", "prior decoder + D_inv head"),
    ("rgb_top", "RGB encoder 1/32"),
    ("rgb_enc", "RGB encoder"),
    ("depth_enc", "depth encoder"),
    ("dec", "decoder"),
    ("bins", "bins MLP + head"),
    ("guide", "guidance (CBAM + conv)"),
    ("aff", "affinity heads"),
    ("kmix", "affinity heads"),
    ("tmix", "affinity heads"),
    ("refine", "refine"),
)


def group_of(name: str) -> str:
    """The report group of a node name (module path)."""
    for prefix, group in GROUPS:
        if name.startswith(prefix):
            return group
    return "top-level upsamples (decoder inputs, final depth)"


def budget(variant: str, **overrides) -> dict:
    """Traces `variant` (seeded random weights) and returns MACs / weight bytes, total and per
    group, plus the depthwise share and the budgets when the variant has them."""
    net = build(variant, seed=0, **overrides)
    rgb, sparse = random_inputs(net.cfg, torch.Generator().manual_seed(1))
    traced = graph_export.trace(net, rgb, sparse)
    g = traced.graph
    shapes = {k: tuple(v.shape) for k, v in traced.values.items()}
    seen: set[str] = set()
    groups: dict[str, dict] = {}
    total = {"macs": 0, "weights_int8": 0, "blob_param_bytes": 0}
    dw_macs = 0
    for node in g["nodes"]:
        grp = groups.setdefault(group_of(node["name"]),
                                {"macs": 0, "weights_int8": 0, "blob_param_bytes": 0})
        m = graph_export.node_macs(node, shapes, g)
        grp["macs"] += m
        total["macs"] += m
        a = node["attrs"]
        if node["op"] == "conv2d" and a["groups"] > 1 and a["groups"] == a["out_channels"]:
            dw_macs += m
        if node["op"] in ("conv2d", "linear", "bins_head"):
            wname = node["params"]["weight"]
            if wname in seen:
                continue
            seen.add(wname)
            shape = g["tensors"][wname]["shape"]
            nw = int(np.prod(shape))
            for d in (grp, total):
                d["weights_int8"] += nw
                d["blob_param_bytes"] += nw + 8 * shape[0]
    out = {"variant": variant, "height": net.cfg.height, "width": net.cfg.width, **total,
           "depthwise_macs": dw_macs, "groups": groups,
           "count": {k: v for k, v in graph_export.count(traced).items() if k != "macs_by_op"}}
    if variant in MAC_BUDGET:
        out["mac_budget"] = MAC_BUDGET[variant]
        out["weight_budget_bytes"] = WEIGHT_BUDGET_BYTES[variant]
    return out


def table(b: dict) -> str:
    """A plain-text table of `budget()`'s result."""
    lines = [f"{b['variant']} at {b['height']}x{b['width']}",
             f"{'part':<46} {'MACs (M)':>9} {'share':>6} {'int8 weights':>13}"]
    for name, d in sorted(b["groups"].items(), key=lambda kv: -kv[1]["macs"]):
        lines.append(f"{name:<46} {d['macs'] / 1e6:9.3f} {100 * d['macs'] / b['macs']:5.1f}% "
                     f"{d['weights_int8']:13d}")
    lines.append(f"{'total':<46} {b['macs'] / 1e6:9.3f} {100.0:5.1f}% {b['weights_int8']:13d}")
    lines.append(f"depthwise convs: {b['depthwise_macs'] / 1e6:.3f} M MACs; weight part of the "
                 f"blob (int8 + int32 bias + f32 scale): {b['blob_param_bytes']} B "
                 f"({b['blob_param_bytes'] / 1024:.1f} KiB)")
    if "mac_budget" in b:
        ok_m = b["macs"] <= b["mac_budget"]
        ok_w = b["weights_int8"] <= b["weight_budget_bytes"]
        lines.append(f"budget: MACs {b['macs'] / 1e6:.2f} M ≤ {b['mac_budget'] / 1e6:.0f} M "
                     f"{'ok' if ok_m else 'OVER'}; int8 weights {b['weights_int8'] / 1024:.1f} "
                     f"KiB ≤ {b['weight_budget_bytes'] / 1024:.0f} KiB {'ok' if ok_w else 'OVER'}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """CLI entry point (see module doc)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", action="append", help="variant(s) (default: mcu_lite)")
    ap.add_argument("--json", action="store_true", help="print JSON instead of the table")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="NetConfig override (int/float/tuple literal), e.g. refine_scale=1")
    a = ap.parse_args(argv)
    torch.set_num_threads(1)
    overrides = parse_overrides(a.set)
    for v in a.variant or ["mcu_lite"]:
        b = budget(v, **overrides)
        print(json.dumps(b, indent=1) if a.json else table(b))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
