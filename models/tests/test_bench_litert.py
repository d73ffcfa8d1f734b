"""bench_litert: the backbone cut (`net.Backbone`) and its MAC count, the CumSum replacement for
onnx2tf and the XNNPACK node census, in models/.venv; the whole LiteRT run (`--smoke` on
mcu_lite) only where models/.venv-litert exists."""

from __future__ import annotations

import json
import math

import numpy as np
import onnx
import pytest
import torch

from depthor_models import bench_litert, bench_onnx, graph_export
from depthor_models.net import Backbone, build, random_inputs


@pytest.mark.parametrize("variant", ["mcu_lite", "mcu"])
def test_backbone_is_the_bins_head_input_and_exports(variant, no_network, tmp_path):
    import onnxruntime as ort

    net = build(variant, seed=0)
    rgb, sparse = random_inputs(net.cfg, torch.Generator().manual_seed(3))
    seen = {}
    hook = net.bins_head.register_forward_hook(lambda m, args, out: seen.update(args=args))
    with torch.no_grad():
        net(rgb, sparse)
        f_unet, bin_logits = Backbone(net)(rgb, sparse)
    hook.remove()
    torch.testing.assert_close(f_unet, seen["args"][0], rtol=0, atol=0)
    torch.testing.assert_close(bin_logits, seen["args"][1], rtol=0, atol=0)

    path = bench_onnx.export_onnx(Backbone(net), (rgb.numpy(), sparse.numpy()),
                                  tmp_path / "backbone.onnx", output_names=("f_unet", "bin_logits"))
    model = onnx.load(str(path))
    assert [o.name for o in model.graph.output] == ["f_unet", "bin_logits"]
    assert not [n.name for n in model.graph.node
                if n.name.startswith(("/net/bins_head/", "/net/refine/", "/net/guide"))]
    got = ort.InferenceSession(str(path)).run(None, {"rgb": rgb.numpy(), "sparse": sparse.numpy()})
    np.testing.assert_allclose(got[0], f_unet.numpy(), atol=1e-4)
    np.testing.assert_allclose(got[1], bin_logits.numpy(), atol=1e-4)


def test_backbone_macs_are_the_bins_head_ancestors():
    net = build("phone_lite", seed=0)
    rgb, sparse = random_inputs(net.cfg)
    with torch.no_grad():
        traced = graph_export.trace(net, rgb, sparse)
    full = graph_export.count(traced)["macs"]
    back = bench_litert.backbone_macs(traced)
    assert 0 < back < full
    # the tail: bins head, guidance, affinity heads, refine and the last upsampling
    g = traced.graph
    shapes = {k: tuple(v.shape) for k, v in traced.values.items()}
    tail_names = ("bins_head", "guide_", "aff", "kmix", "tmix", "refine", "upsample_bilinear_4",
                  "concat_6", "prior.upsample_bilinear_3")
    tail = sum(graph_export.node_macs(n, shapes, g) for n in g["nodes"]
               if n["name"].startswith(tail_names))
    assert back == full - tail


def test_cumsum_fix_transposes_around_a_channel_cumsum(tmp_path):
    h = onnx.helper
    axis = h.make_tensor("axis", onnx.TensorProto.INT32, [], [1])
    nodes = [h.make_node("CumSum", ["x", "axis"], ["y"], name="/bins_head/CumSum")]
    x = h.make_tensor_value_info("x", onnx.TensorProto.FLOAT, [1, 4, 1, 1])
    y = h.make_tensor_value_info("y", onnx.TensorProto.FLOAT, [1, 4, 1, 1])
    onnx.save(h.make_model(h.make_graph(nodes, "g", [x], [y], [axis])), tmp_path / "c.onnx")
    ops = bench_litert.cumsum_fix(tmp_path / "c.onnx")["operations"]
    assert ops == [
        {"op_name": "/bins_head/CumSum", "param_target": "inputs", "param_name": "x",
         "pre_process_transpose_perm": [0, 3, 1, 2]},
        {"op_name": "/bins_head/CumSum", "param_target": "outputs", "param_name": "y",
         "post_process_transpose_perm": [0, 2, 3, 1]}]
    relu = [h.make_node("Relu", ["x"], ["y"], name="/r")]
    onnx.save(h.make_model(h.make_graph(relu, "g", [x], [y])), tmp_path / "r.onnx")
    assert bench_litert.cumsum_fix(tmp_path / "r.onnx") is None


class _Wrapper:
    """Stands in for LiteRT's interpreter wrapper: nodes (name, inputs, outputs)."""

    def __init__(self, nodes, outputs):
        self.nodes, self.outputs = nodes, outputs

    def NumNodes(self):  # noqa: N802 (the wrapper's names)
        return len(self.nodes)

    def NodeName(self, i):  # noqa: N802
        return self.nodes[i][0]

    def NodeInputs(self, i):  # noqa: N802
        return self.nodes[i][1]

    def NodeOutputs(self, i):  # noqa: N802
        return self.nodes[i][2]

    def OutputIndices(self):  # noqa: N802
        return self.outputs


def test_xnnpack_census_counts_the_replaced_nodes():
    # conv (0 → 1), add (1 → 2), cumsum (2 → 3); XNNPACK took conv and add: DELEGATE (0 → 2)
    nodes = [("CONV_2D", [0, 9], [1]), ("ADD", [1, 1], [2]), ("CUMSUM", [2], [3]),
             ("DELEGATE", [0, 9], [2])]

    class It:
        _interpreter = _Wrapper(nodes, [3])

    assert bench_litert.xnnpack_census(It()) == {
        "nodes": 3, "delegated": 2, "partitions": 1, "not_delegated": {"CUMSUM": 1}}


@pytest.mark.slow
@pytest.mark.skipif(not bench_litert.litert_python().exists(),
                    reason="no models/.venv-litert (requirements-litert.txt)")
def test_smoke_run_converts_checks_and_times(no_network, tmp_path, capsys):
    assert bench_litert.main(["--variant", "mcu_lite", "--smoke", "--out", str(tmp_path)]) == 0
    print(capsys.readouterr().out)
    res = json.loads((tmp_path / "bench.json").read_text())
    rows = {r["model"]: r for r in res["rows"]}
    assert list(rows) == ["LiteRT f32", "LiteRT int8", "LiteRT f32 backbone",
                          "LiteRT int8 backbone"]
    for r in rows.values():
        assert r["runs"] == 2 and 0 < r["min_ms"] <= r["median_ms"]
        assert math.isclose(r["gmac_per_s"],
                            res["macs_per_frame"][r["graph"]] / r["median_ms"] / 1e6)
        assert 0 < r["xnnpack"]["delegated"] <= r["xnnpack"]["nodes"]
    # f32 is the PyTorch network (the CumSum fix in place: without it depth is off by metres)
    assert rows["LiteRT f32"]["check"]["depth"]["max_abs_diff"] < 1e-3
    for o in ("f_unet", "bin_logits"):
        assert rows["LiteRT f32 backbone"]["check"][o]["max_abs_diff"] < 1e-3
    assert 5 < rows["LiteRT int8"]["check"]["depth"]["sqnr_db"] < 80
