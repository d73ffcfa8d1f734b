"""graph.json checks: the contract's structure, weights.bin round trip, budgets, and the numpy
interpreter reproducing PyTorch (the spec the Rust engine implements)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from depthor_models import golden, graph_export, interp
from depthor_models.graph_export import ALIGN

VARIANTS = ("mcu", "phone")
GRAPH_OPS = {
    "conv2d", "batch_norm", "relu", "leaky_relu", "sigmoid", "add", "mul", "concat",
    "upsample_bilinear", "pixel_shuffle", "global_avg_pool", "global_max_pool", "channel_mean",
    "channel_max", "linear", "minmax_norm", "reciprocal", "bins_head", "refine",
}


@pytest.mark.parametrize("variant", VARIANTS)
def test_forward_shape_and_range(nets, traced, variant):
    cfg = nets[variant].cfg
    depth = traced[variant].values["depth"]
    assert depth.shape == (1, 1, cfg.height, cfg.width)
    assert torch.isfinite(depth).all()
    assert cfg.min_depth_m <= depth.min().item() and depth.max().item() <= cfg.max_depth_m
    with torch.no_grad():
        again = nets[variant](traced[variant].values["rgb"], traced[variant].values["sparse"])
    assert torch.equal(again, depth)  # recording does not change the computation


@pytest.mark.parametrize("variant", VARIANTS)
def test_graph_structure(traced, variant):
    g = traced[variant].graph
    assert g["format"] == "depthor-graph/1" and g["outputs"] == ["depth"]
    defined = {i["name"] for i in g["inputs"]}
    names = set()
    by_output = {}
    for n in g["nodes"]:
        assert n["op"] in GRAPH_OPS, n["op"]
        assert n["name"] not in names
        names.add(n["name"])
        assert all(i in defined for i in n["inputs"]), n["name"]  # topological order
        assert n["output"] not in defined  # produced once
        defined.add(n["output"])
        by_output[n["output"]] = n
        for p in n["params"].values():
            assert p in g["tensors"]
    assert "depth" in defined
    users = {}
    for n in g["nodes"]:
        for i in n["inputs"]:
            users.setdefault(i, []).append(n)
    for n in g["nodes"]:
        if n["op"] == "batch_norm":  # conv2d(activation none) -> batch_norm -> activation
            prod = by_output[n["inputs"][0]]
            assert prod["op"] == "conv2d" and prod["attrs"]["activation"] == "none"
            assert len(users[prod["output"]]) == 1
            assert [u["op"] for u in users[n["output"]]] in (["relu"], ["leaky_relu"])
            assert set(n["params"]) == {"gamma", "beta", "mean", "var"}
    prior = [n for n in g["nodes"] if n["name"].startswith("prior.")]
    assert prior and all(n["op"] != "refine" for n in prior)
    refine = [n for n in g["nodes"] if n["op"] == "refine"]
    assert len(refine) == 1 and refine[0]["output"] == "depth"
    assert refine[0]["attrs"]["iterations"] % 2 == 0 and len(refine[0]["attrs"]["sigma"]) == 3
    bins = [n for n in g["nodes"] if n["op"] == "bins_head"]
    assert len(bins) == 1 and bins[0]["attrs"]["n_bins"] == 128


@pytest.mark.parametrize("variant", VARIANTS)
def test_weights_round_trip(tmp_path, traced, variant):
    t = traced[variant]
    gpath, wpath = graph_export.write(t, tmp_path)
    graph, weights = graph_export.load(gpath, wpath)
    for name, info in graph["tensors"].items():
        assert info["offset"] % ALIGN == 0
        assert np.array_equal(weights[name], t.params[name].numpy())


@pytest.mark.parametrize("variant", VARIANTS)
def test_depth_input_normalises_before_the_reciprocal(traced, variant):
    """Depth-encoder input: n = minmax_norm(D_inv), D_rel = minmax_norm(1/(n + 0.1)), concat
    (n, D_rel, sparse). The reciprocal reads the normalised map, so its output stays within
    [1/1.1, 10] whatever the prior's scale (int8-friendly), also where the prior's relu is 0."""
    t = traced[variant]
    nodes = t.graph["nodes"]
    by_output = {n["output"]: n for n in nodes}
    recs = [n for n in nodes if n["op"] == "reciprocal"]
    assert len(recs) == 1
    rec = recs[0]
    assert rec["attrs"]["eps"] == pytest.approx(0.1)
    norm = by_output[rec["inputs"][0]]
    assert norm["op"] == "minmax_norm"
    prior_out = by_output[norm["inputs"][0]]
    assert prior_out["name"].startswith("prior.") and prior_out["op"] == "relu"
    users = [n for n in nodes if rec["output"] in n["inputs"]]
    assert [u["op"] for u in users] == ["minmax_norm"]
    cat = [n for n in nodes if n["op"] == "concat" and users[0]["output"] in n["inputs"]]
    assert len(cat) == 1
    assert cat[0]["inputs"] == [norm["output"], users[0]["output"], "sparse"]
    r = t.values[rec["output"]]
    assert 1.0 / 1.1 - 1e-5 <= r.min().item() and r.max().item() <= 10.0 + 1e-4


def test_depth_input_bounded_when_prior_is_zero():
    """A prior output that is 0 everywhere (dead relu) gives finite, bounded depth input."""
    from depthor_models import ops

    n = ops.minmax_norm(torch.zeros(1, 1, 4, 5), 1e-6)
    r = ops.reciprocal(n, 0.1)
    assert torch.equal(n, torch.zeros_like(n))
    assert torch.allclose(r, torch.full_like(r, 10.0))
    assert torch.isfinite(ops.minmax_norm(r, 1e-6)).all()


def test_budgets(traced):
    mcu = graph_export.count(traced["mcu"])
    phone = graph_export.count(traced["phone"])
    # docs/design.md: mcu weights ≤ 512 KiB int8 (≈ 450 k parameters after BN folding)
    assert mcu["params_deployed"] <= 450_000
    # docs/design.md: phone ≲ 1.5 GMAC at 320×240
    assert phone["macs"] <= 1.5e9
    assert 0 < mcu["params_prior"] < mcu["params_deployed"]


def _interpreter_check(traced_variant, tmp_path):
    gpath, wpath = graph_export.write(traced_variant, tmp_path)
    graph, weights = graph_export.load(gpath, wpath)
    v = traced_variant.values
    env = interp.run(graph, weights, {"rgb": v["rgb"].numpy(), "sparse": v["sparse"].numpy()},
                     keep_all=True)
    depth_diff = float(np.abs(env["depth"] - v["depth"][0].numpy()).max())
    return env, depth_diff


@pytest.mark.parametrize("variant", VARIANTS)
def test_interpreter_reproduces_pytorch(tmp_path, traced, variant):
    env, depth_diff = _interpreter_check(traced[variant], tmp_path)
    print(f"{variant}: max |interp - torch| on depth = {depth_diff:.3g} m")
    assert depth_diff <= 1e-4
    # the golden intermediates agree too, relative to their magnitude (f32 vs f64 drift grows
    # through the depth encoder)
    for name in golden.intermediate_names(traced[variant].graph):
        ref = traced[variant].values[name][0].numpy()
        assert np.abs(env[name] - ref).max() <= 1e-3 * max(1.0, np.abs(ref).max()), name


@pytest.mark.parametrize("variant", VARIANTS)
def test_every_node_matches_pytorch_on_its_own_inputs(traced, variant):
    """Node by node, fed PyTorch's own input values: isolates each op's semantics."""
    t = traced[variant]
    graph, weights = t.graph, interp.cast_weights({k: v.numpy() for k, v in t.params.items()})
    worst = (0.0, "")
    for node in graph["nodes"]:
        xs = [t.values[i][0].double().numpy() for i in node["inputs"]]
        ref = t.values[node["output"]][0].double().numpy()
        err = np.abs(interp.eval_node(node, weights, xs) - ref).max() / max(1.0, np.abs(ref).max())
        worst = max(worst, (float(err), node["name"]))
    print(f"{variant}: worst per-node relative error {worst[0]:.3g} at {worst[1]}")
    assert worst[0] <= 2e-5, worst


def test_golden_round_trip(tmp_path, traced):
    t = traced["mcu"]
    idx = golden.write(t, tmp_path, seed=1)
    back = golden.read(idx)
    assert {"rgb", "sparse", "depth", "bins_head", "bins_fc2"} <= set(back)
    for name, arr in back.items():
        assert np.array_equal(arr, t.values[name].numpy())


@pytest.mark.parametrize("variant", VARIANTS)
def test_committed_artefacts_match_the_code(traced, variant):
    """models/<variant>/graph.json, weights.bin (and mcu's golden) are what the code exports now
    (from the trained weights that summary.json's `weights_path` names, relative to models/, or
    the seeded random network); re-run the export command when this fails after a deliberate
    change."""
    import json
    from pathlib import Path

    import torch

    from depthor_models.export import build_trained
    from depthor_models.net import random_inputs

    models = Path(__file__).resolve().parents[1]
    root = models / variant
    graph, weights = graph_export.load(root / "graph.json")
    trained = json.loads((root / "summary.json").read_text()).get("weights_path")
    if trained:
        net = build_trained(variant, models / trained)
        t = graph_export.trace(net, *random_inputs(net.cfg, torch.Generator().manual_seed(1)))
    else:
        t = traced[variant]
    assert graph["nodes"] == t.graph["nodes"]
    assert set(weights) == set(t.params)
    for name, arr in weights.items():
        assert np.allclose(arr, t.params[name].numpy(), rtol=0, atol=1e-6), name
    if variant == "mcu":
        g = golden.read(root / "golden" / "index.json")
        # torch's bilinear upsampling (random_inputs) and its conv kernels round differently per
        # CPU (AVX-512 vs AVX2): the rgb may differ by an ulp and the depth by a few, not more.
        assert np.allclose(g["rgb"], t.values["rgb"].numpy(), rtol=0, atol=1e-6)
        assert np.array_equal(g["sparse"], t.values["sparse"].numpy())
        assert np.abs(g["depth"] - t.values["depth"].numpy()).max() <= 1e-4
