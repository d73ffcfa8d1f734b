"""bench_onnx: the shipped mcu network through ONNX Runtime f32 and static int8, in its
`--smoke` mode (2 random calibration frames, 2 timed runs), offline; plus its helpers."""

from __future__ import annotations

import json
import math

import numpy as np
import onnx

from depthor_models import bench_onnx


def test_smoke_run_exports_quantises_and_times(no_network, tmp_path, capsys):
    assert bench_onnx.main(["--variant", "mcu", "--smoke", "--profile", "--out",
                            str(tmp_path)]) == 0
    text = capsys.readouterr().out
    print(text)
    res = json.loads((tmp_path / "bench.json").read_text())
    summary = json.loads((bench_onnx.MODELS / "mcu" / "summary.json").read_text())
    assert res["weights"] == f"models/{summary['weights_path']}"
    assert res["macs_per_frame"] == summary["macs"]
    assert res["calibration"]["source"] == "random" and res["calibration"]["frames"] == 2
    f32, int8 = res["rows"]
    assert (f32["model"], int8["model"]) == ("ORT f32", "ORT int8")
    for r in (f32, int8):
        assert r["runs"] == 2 and 0 < r["min_ms"] <= r["median_ms"]
        assert math.isclose(r["gmac_per_s"], summary["macs"] / r["median_ms"] / 1e6)
        assert f"{r['model']:<9} {r['runs']:>4} {r['median_ms']:>10.2f}" in text
        assert sum(r["profile"]["by_scope_ms"].values()) > 0
    # ORT f32 is the same network as PyTorch; int8 is close to it even on 2 calibration frames
    assert f32["sqnr_db"] > 80 and f32["max_abs_err_m"] < 1e-3
    assert 15 < int8["sqnr_db"] < f32["sqnr_db"]
    census = int8["op_census"]
    assert census["int8"]["QLinearConv"] > 0
    assert "Mul" in census["float_kept"]  # refine stays f32 by default
    for name in ("depthor_f32.onnx", "depthor_int8.onnx", "int8_ort_optimised.onnx"):
        assert (tmp_path / name).is_file()
    m = onnx.load(str(tmp_path / "depthor_f32.onnx"), load_external_data=False)
    assert [o.version for o in m.opset_import if o.domain in ("", "ai.onnx")] == [17]
    dims = [[d.dim_value for d in i.type.tensor_type.shape.dim] for i in m.graph.input]
    assert dims == [[1, 3, 120, 160], [1, 1, 120, 160]]


def test_sqnr_by_hand():
    # as host quantize::check: signal 3² + 4² = 25, noise 0.5² → 20 dB; centred: Σ(r − 3.5)² = 0.5
    ref, test = np.array([3.0, 4.0]), np.array([3.5, 4.0])
    assert math.isclose(bench_onnx.sqnr_db(ref, test), 20.0)
    assert math.isclose(bench_onnx.sqnr_db(ref, test, centred=True), 10 * math.log10(2))
    assert bench_onnx.sqnr_db(ref, ref) == math.inf


def test_f32_nodes_take_the_scopes_and_what_lies_between():
    h = onnx.helper
    nodes = [h.make_node("Relu", ["x"], ["a"], name="/enc/Relu"),
             h.make_node("Exp", ["a"], ["b"], name="/bins_head/Exp"),
             h.make_node("Resize", ["b"], ["c"], name="/Resize"),
             h.make_node("Relu", ["a"], ["d"], name="/aff3/Relu"),
             h.make_node("Mul", ["c", "d"], ["y"], name="/refine/Mul")]
    vi = [h.make_tensor_value_info(n, onnx.TensorProto.FLOAT, [1]) for n in ("x", "y")]
    model = h.make_model(h.make_graph(nodes, "g", vi[:1], vi[1:]))
    assert bench_onnx.f32_nodes(model) == ["/bins_head/Exp", "/Resize", "/refine/Mul"]


def test_every_variant_has_a_preset_and_the_lite_network_runs(no_network, tmp_path):
    from depthor_models.net import VARIANTS

    assert set(bench_onnx.PRESETS) == set(VARIANTS)
    assert bench_onnx.PRESETS["phone_lite"] == "phone" and bench_onnx.PRESETS["mcu_lite"] == "mcu"
    assert bench_onnx.main(["--variant", "mcu_lite", "--smoke", "--out", str(tmp_path)]) == 0
    res = json.loads((tmp_path / "bench.json").read_text())
    f32, int8 = res["rows"]
    assert f32["sqnr_db"] > 80 and 15 < int8["sqnr_db"] < f32["sqnr_db"]
    assert "Mul" in int8["op_census"]["float_kept"]  # the lite refine stays f32 too
