"""ONNX Runtime baseline: the shipped network in ORT f32 and ORT static int8, one thread.

    cd models && PYTHONPATH=. .venv/bin/python -m depthor_models.bench_onnx --variant mcu \
        [--runs 20] [--out DIR] [--calib sim|random] [--method minmax|entropy] [--int8-heads] \
        [--profile]

1. Builds the variant with the trained weights its export used (`<variant>/summary.json`
   `weights_path`, the file the model card cites) and exports it to ONNX (opset 17, fixed
   1×3×H×W / 1×1×H×W inputs, TorchScript exporter: BN folded into the convs).
2. Quantises it with `onnxruntime.quantization.quantize_static`: QDQ, per-channel QInt8
   weights, QUInt8 activations, MinMax (or Entropy) ranges over `--calib-frames` (16) frames.
   `sim` frames: `depthor sim --preset <preset> --scenes N+1 --seed 0` rendered at the
   model's size (the scene generator and sensor preset the host quantizer calibrates with),
   loaded as training loads them (`data.batch`); frame N is held out for the SQNR. `random`:
   `net.random_inputs`. The recordings under shared/data/real are never read. By default the
   bins head, the d0 upsampling and refine stay f32 (excluded nodes), as in the core's blob
   (docs/blob.md "Quantisation": why the bins head and refine are f32); `--int8-heads` quantises every
   node ORT can.
3. Times both models in ORT on one thread (intra/inter op 1, sequential, all graph
   optimisations): `--warmup` (1) runs each, then `--runs` (20) timed runs of one frame, f32
   and int8 taking turns. Prints the median ms/frame and GMAC/s (MACs per frame from
   `graph_export.count`, as in summary.json, or `--macs`), the depth SQNR of ORT int8 and ORT
   f32 against PyTorch f32 on the held-out input, which ops the int8 session still runs in
   float, and with `--profile` ORT's kernel time by module scope and by op.

Files go to `--out` (default models/.onnx_cache/<variant>, git-ignored): depthor_f32.onnx,
depthor_int8.onnx, the optimised int8 graph ORT runs (int8_ort_optimised.onnx), bench.json.
`--smoke`: 2 random calibration frames, 2 timed runs (tests/test_bench_onnx.py).
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from functools import partial
from pathlib import Path

if __package__ in (None, ""):  # `python models/depthor_models/bench_onnx.py …`
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np
import torch

from depthor_models import data, graph_export
from depthor_models.bench_common import cpu_name, loadavg, sqnr_db, time_interleaved
from depthor_models.export import build_trained
from depthor_models.net import Depthor, build, random_inputs

MODELS = Path(__file__).resolve().parents[1]
REPO = MODELS.parent
OPSET = 17
INPUTS = ("rgb", "sparse")
# Module scopes kept in f32 by default: the core's blob computes these in f32 too.
F32_SCOPES = ("bins_head", "refine")
ENTROPY_BINS = 512  # histogram bins for --method entropy (128 quantised bins)


# ---------------------------------------------------------------------------------------------
# Network and inputs
# ---------------------------------------------------------------------------------------------


def shipped_weights(variant: str) -> Path:
    """The trained weights `<variant>/summary.json` says the shipped export used."""
    summary = json.loads((MODELS / variant / "summary.json").read_text())
    rel = summary.get("weights_path")
    if not rel:
        raise ValueError(f"{variant}/summary.json names no weights_path (random export?)")
    return MODELS / rel


def load_net(variant: str, weights: str | None) -> tuple[Depthor, str]:
    """(network in eval mode, description of its weights). `weights`: None = the shipped ones,
    "random" = the seeded random build (seed 0), else a checkpoint / state-dict path."""
    if weights == "random":
        return build(variant, seed=0), "random init, seed 0"
    path = Path(weights) if weights else shipped_weights(variant)
    return build_trained(variant, path), str(path.resolve().relative_to(REPO)
                                             if path.resolve().is_relative_to(REPO) else path)


def default_cli() -> Path:
    """The depthor CLI used for `sim` calibration frames ($DEPTHOR_CLI or target/release)."""
    return Path(os.environ.get("DEPTHOR_CLI", REPO / "target" / "release" / "depthor"))


# The sensor preset each variant's inputs come from (host/src/models.rs `PRESETS`).
PRESETS = {"mcu": "mcu", "mcu_lite": "mcu", "phone": "phone", "phone_lite": "phone"}


def sim_frames(variant: str, height: int, width: int, count: int, seed: int,
               cli: Path) -> list[tuple[np.ndarray, np.ndarray]]:
    """`count` simulated frames (rgb [1,3,H,W] in [0,1], sparse [1,1,H,W] m) from
    `depthor sim --preset <the variant's preset> --seed <seed>` rendered at the model's size."""
    if not cli.exists():
        raise FileNotFoundError(f"{cli}: no depthor CLI (cargo build --release -p depthor-host, "
                                "or --calib random)")
    with tempfile.TemporaryDirectory(prefix="depthor-bench-onnx-") as tmp:
        out = Path(tmp) / "rec"
        cmd = [str(cli), "sim", "--preset", PRESETS[variant], "--scenes", str(count),
               "--seed", str(seed), "--width", str(width), "--height", str(height),
               "--out", str(out)]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        rec = data.load_recording(out, cache=False)
        if (rec.height, rec.width) != (height, width):
            raise RuntimeError(f"sim wrote {rec.height}x{rec.width}, expected {height}x{width}")
        rgb, sparse, _gt = data.batch(rec, np.arange(count))
    return [(rgb[i:i + 1].numpy(), sparse[i:i + 1].numpy()) for i in range(count)]


def random_frames(net: Depthor, count: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """`count` frames of `net.random_inputs` (smooth rgb, 64 sparse points), seeds seed..+count."""
    out = []
    for k in range(count):
        rgb, sparse = random_inputs(net.cfg, torch.Generator().manual_seed(seed + k))
        out.append((rgb.numpy(), sparse.numpy()))
    return out


def bench_frames(net: Depthor, source: str, count: int, seed: int,
                 cli: Path) -> list[tuple[np.ndarray, np.ndarray]]:
    """`count` frames at `net`'s size from `source`: "sim" (`sim_frames` of its variant) or
    "random" (`random_frames`)."""
    cfg = net.cfg
    if source == "sim":
        return sim_frames(cfg.variant, cfg.height, cfg.width, count, seed, cli)
    if source == "random":
        return random_frames(net, count, seed)
    raise ValueError(f"unknown frame source {source!r}")


def feeds(frame: tuple[np.ndarray, np.ndarray]) -> dict[str, np.ndarray]:
    """ORT input dict of one frame."""
    return {name: np.ascontiguousarray(x, dtype=np.float32) for name, x in zip(INPUTS, frame)}


# ---------------------------------------------------------------------------------------------
# Export and quantisation
# ---------------------------------------------------------------------------------------------


def export_onnx(net: torch.nn.Module, frame, path: Path, opset: int = OPSET,
                output_names: tuple[str, ...] = ("depth",)) -> Path:
    """Exports `net` (a `Depthor`, or `net.Backbone` with its two outputs named in
    `output_names`) at the frame's fixed size; eval mode folds BN into the convs. TorchScript
    exporter (`dynamo=False`): the dynamo one needs onnxscript, which requirements.txt does not
    pin, and the TorchScript node names (`/refine/Mul_3`) carry the module scopes that
    `f32_nodes` and `profile` read."""
    path.parent.mkdir(parents=True, exist_ok=True)
    args = tuple(torch.from_numpy(x) for x in frame)
    with warnings.catch_warnings(), torch.no_grad():
        warnings.simplefilter("ignore")
        torch.onnx.export(net.eval(), args, str(path), input_names=list(INPUTS),
                          output_names=list(output_names), opset_version=opset, dynamo=False,
                          do_constant_folding=True)
    return path


def f32_nodes(model, scopes=F32_SCOPES) -> list[str]:
    """Names of the nodes to keep in f32: those under the module `scopes` (TorchScript names
    `/bins_head/…`, `/refine/…`) and every node between the first scope and the last (the d0
    upsampling from bins_head to refine)."""
    nodes = list(model.graph.node)
    in_scope = [any(n.name.startswith(f"/{s}/") for s in scopes) for n in nodes]
    if not any(in_scope):
        raise ValueError(f"no node under {scopes}: exporter naming changed?")
    producer = {o: i for i, n in enumerate(nodes) for o in n.output}
    first = [i for i, n in enumerate(nodes) if in_scope[i] and n.name.startswith(f"/{scopes[0]}/")]
    last = [i for i, n in enumerate(nodes) if in_scope[i] and n.name.startswith(f"/{scopes[-1]}/")]
    down = set(first)  # forward reach of the first scope
    for i, n in enumerate(nodes):  # nodes are topologically sorted
        if any(producer.get(x) in down for x in n.input):
            down.add(i)
    up, stack = set(last), list(last)  # backward reach of the last scope
    while stack:
        for x in nodes[stack.pop()].input:
            j = producer.get(x)
            if j is not None and j not in up:
                up.add(j)
                stack.append(j)
    keep = {i for i in range(len(nodes)) if in_scope[i]} | (down & up)
    return [nodes[i].name for i in sorted(keep)]


class FrameReader:
    """onnxruntime.quantization CalibrationDataReader over a list of frames."""

    def __init__(self, frames):
        self.frames = frames
        self._it = iter(frames)

    def get_next(self):
        f = next(self._it, None)
        return None if f is None else feeds(f)

    def rewind(self):
        self._it = iter(self.frames)


def entropy_ranges(model_path: Path, frames, exclude: list[str], cache_path: Path,
                   num_bins: int = ENTROPY_BINS, num_quantized_bins: int = 128) -> Path:
    """KL-divergence (entropy) activation ranges, written as an ORT calibration cache.

    quantize_static's own Entropy calibration uses 128 histogram bins for 128 quantised bins:
    one candidate threshold, the full range, i.e. the MinMax ranges (onnxruntime 1.32 passes no
    bin count through). So the histograms are built here with `num_bins`, one frame at a time
    (they merge; memory stays one frame's outputs), only for the tensors of nodes that get
    quantised (the threshold search is Python loops, ≈ 0.35 s per tensor at 512 bins)."""
    import contextlib
    import io

    import onnx
    from onnxruntime.quantization.calibrate import (CalibrationMethod, create_calibrator,
                                                    save_tensors_data)
    from onnxruntime.quantization.registry import QDQRegistry, QLinearOpsRegistry

    ops = sorted(set(QLinearOpsRegistry) | set(QDQRegistry))  # quantize_static's default
    model = onnx.load(str(model_path))
    consts = {i.name for i in model.graph.initializer}
    skip = set(exclude)
    wanted = {x for n in model.graph.node if n.op_type in ops and n.name not in skip
              for x in (*n.input, *n.output) if x and x not in consts}
    with tempfile.TemporaryDirectory(prefix="depthor-calib-") as tmp, \
            contextlib.redirect_stdout(io.StringIO()):  # the collector prints per call
        cal = create_calibrator(model_path, ops, augmented_model_path=str(Path(tmp) / "aug.onnx"),
                                calibrate_method=CalibrationMethod.Entropy,
                                extra_options={"num_bins": num_bins,
                                               "num_quantized_bins": num_quantized_bins})
        cal.tensors_to_calibrate = set(cal.tensors_to_calibrate) & wanted
        for f in frames:
            cal.collect_data(FrameReader([f]))
        save_tensors_data(cal.compute_data(), cache_path)
        del cal
    return cache_path


def input_ranges(net: Depthor) -> dict[str, tuple[float, float]]:
    """The input ranges the host quantizer fixes (docs/blob.md "Quantisation"): rgb is
    byte/255, sparse spans [0, max_depth_m]."""
    return {"rgb": (0.0, 1.0), "sparse": (0.0, float(net.cfg.max_depth_m))}


def quantize(f32_path: Path, int8_path: Path, frames, method: str = "minmax",
             int8_heads: bool = False,
             fixed_ranges: dict[str, tuple[float, float]] | None = None) -> dict:
    """quantize_static: QDQ, per-channel QInt8 weights, QUInt8 activations, on the model after
    ORT's pre-processing (shape inference, constant folding); `fixed_ranges` (tensor → (lo, hi))
    replace the calibrated ranges of those tensors (TensorQuantOverrides). Returns what was done
    (method, frame count, names of the nodes excluded from quantisation, seconds)."""
    import onnx
    from onnxruntime.quantization import (CalibrationMethod, QuantFormat, QuantType,
                                          quantize_static)
    from onnxruntime.quantization.shape_inference import quant_pre_process

    pre = int8_path.with_name(int8_path.stem + "_pre.onnx")
    cache = int8_path.with_name(int8_path.stem + "_entropy_ranges.json")
    t0 = time.perf_counter()
    quant_pre_process(str(f32_path), str(pre), skip_symbolic_shape=False)
    exclude = [] if int8_heads else f32_nodes(onnx.load(str(pre)))
    cache.unlink(missing_ok=True)
    if method == "entropy":
        entropy_ranges(pre, frames, exclude, cache)
    quantize_static(
        str(pre), str(int8_path), FrameReader(frames),
        quant_format=QuantFormat.QDQ, per_channel=True, reduce_range=False,
        activation_type=QuantType.QUInt8, weight_type=QuantType.QInt8,
        calibrate_method={"minmax": CalibrationMethod.MinMax,
                          "entropy": CalibrationMethod.Entropy}[method],
        calibration_cache_path=cache if method == "entropy" else None,
        nodes_to_exclude=exclude,
        extra_options={"TensorQuantOverrides": {
            name: [{"rmin": np.float32(lo), "rmax": np.float32(hi)}]
            for name, (lo, hi) in (fixed_ranges or {}).items()}},
        # Not CalibMaxIntermediateOutputs: in onnxruntime 1.32 collect_data clears the outputs
        # it has gathered when the limit is reached without merging their ranges first.
    )
    pre.unlink()
    cache.unlink(missing_ok=True)
    return {"method": method + (f" ({ENTROPY_BINS} bins)" if method == "entropy" else ""),
            "frames": len(frames), "fixed_ranges": fixed_ranges or {}, "nodes_kept_f32": exclude,
            "quantize_s": round(time.perf_counter() - t0, 1)}


# ---------------------------------------------------------------------------------------------
# Timing and accuracy
# ---------------------------------------------------------------------------------------------


def _options():
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = 1
    so.inter_op_num_threads = 1
    so.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    so.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    so.log_severity_level = 3
    return so


def session(path: Path, optimised_out: Path | None = None):
    """One-thread ORT CPU session: intra/inter op 1, sequential, all graph optimisations;
    with `optimised_out`, ORT also saves the graph it runs there."""
    import onnxruntime as ort

    so = _options()
    if optimised_out is not None:
        so.optimized_model_filepath = str(optimised_out)
    return ort.InferenceSession(str(path), so, providers=["CPUExecutionProvider"])


_INT_TYPES = (2, 3)  # onnx.TensorProto.UINT8, INT8


def _elem_types(graph) -> dict[str, int]:
    """Element type of every value of `graph` (onnx TensorProto codes), propagated by hand
    (onnx shape inference does not know ORT's contrib ops): Q → its zero point's type, DQ →
    float, QLinear* → the type of their first 8-bit input, Shape → int64, Cast → `to`, Constant →
    its value's type, anything else → the type of its first input."""
    import onnx

    t = {v.name: v.type.tensor_type.elem_type for v in graph.input}
    t.update({i.name: i.data_type for i in graph.initializer})
    for n in graph.node:
        attrs = {a.name: a for a in n.attribute}
        if n.op_type == "Constant":
            ty = attrs["value"].t.data_type if "value" in attrs else onnx.TensorProto.FLOAT
        elif n.op_type == "QuantizeLinear":
            ty = t.get(n.input[2], onnx.TensorProto.UINT8) if len(n.input) > 2 else 2
        elif n.op_type.startswith("QLinear"):  # QLinearConcat begins with the output scale
            ty = next((t[x] for x in n.input if t.get(x) in _INT_TYPES), onnx.TensorProto.UINT8)
        elif n.op_type == "DequantizeLinear":
            ty = onnx.TensorProto.FLOAT
        elif n.op_type == "Shape":
            ty = onnx.TensorProto.INT64
        elif n.op_type == "Cast":
            ty = attrs["to"].i
        else:
            ty = next((t[x] for x in n.input if x in t), onnx.TensorProto.FLOAT)
        for o in n.output:
            t[o] = ty
    return t


def op_census(optimised: Path, kept: set[str] = frozenset(), scopes=()) -> dict:
    """Op types of the graph ORT actually runs (saved after its fusions), split by the element
    type of each node's first input: "int8" (8-bit: QLinear* kernels, QuantizeLinear, data
    movement on quantised tensors) or float; float nodes split again into "float_kept" (named
    in `kept`, the nodes excluded from quantisation, or under one of `scopes`) and
    "float_other" (what ORT left in float elsewhere). Constants are not counted."""
    import onnx

    g = onnx.load(str(optimised), load_external_data=False).graph
    types = _elem_types(g)
    out = {k: collections.Counter() for k in ("int8", "float_kept", "float_other")}
    for n in g.node:
        if n.op_type == "Constant":
            continue
        quantised = n.op_type == "QuantizeLinear" or n.op_type.startswith("QLinear") or (
            n.op_type != "DequantizeLinear" and n.input and types.get(n.input[0]) in _INT_TYPES)
        if quantised:
            key = "int8"
        elif n.name in kept or any(n.name.startswith(f"/{s}/") for s in scopes):
            key = "float_kept"
        else:
            key = "float_other"
        out[key][n.op_type] += 1
    return {k: dict(sorted(v.items())) for k, v in out.items()}


def profile(path: Path, feed: dict, runs: int) -> dict:
    """Kernel milliseconds per run by top-level module scope (the first part of the TorchScript
    node name: `refine`, `bins_head`, `prior`…; "other" for top-level nodes and nodes ORT
    created) and by op type, from ORT's profiler on its own one-thread session: one untimed
    run, then `runs` profiled ones."""
    import onnxruntime as ort

    with tempfile.TemporaryDirectory(prefix="depthor-ort-prof-") as tmp:
        so = _options()
        so.enable_profiling = True
        so.profile_file_prefix = str(Path(tmp) / "prof")
        sess = ort.InferenceSession(str(path), so, providers=["CPUExecutionProvider"])
        for _ in range(1 + runs):
            sess.run(None, feed)
        events = json.loads(Path(sess.end_profiling()).read_text())
    model_runs = sorted(e["ts"] + e["dur"] for e in events if e.get("name") == "model_run")
    after_warmup = model_runs[0]
    by_op, by_scope = collections.Counter(), collections.Counter()
    for e in events:
        if e.get("cat") != "Node" or not e["name"].endswith("_kernel_time") \
                or e["ts"] < after_warmup:
            continue
        name = e["name"][: -len("_kernel_time")]
        parts = name.split("/")
        scope = parts[1].split(".")[0] if name.startswith("/") and len(parts) > 2 else "other"
        by_scope[scope] += e["dur"]
        by_op[e["args"]["op_name"]] += e["dur"]
    ms = 1e-3 / runs  # µs in total → ms per run
    return {"by_scope_ms": {k: round(v * ms, 2) for k, v in by_scope.most_common()},
            "by_op_ms": {k: round(v * ms, 2) for k, v in by_op.most_common()}}


# ---------------------------------------------------------------------------------------------
# CLI
# ---------------------------------------------------------------------------------------------


def run(a: argparse.Namespace) -> dict:
    """Export, quantise, time; returns the results (also written to <out>/bench.json)."""
    import onnxruntime as ort

    out = Path(a.out) if a.out else MODELS / ".onnx_cache" / a.variant
    out.mkdir(parents=True, exist_ok=True)
    net, weights = load_net(a.variant, a.weights)
    cfg = net.cfg
    n = a.calib_frames
    frames = bench_frames(net, a.calib, n + 1, a.calib_seed, Path(a.cli))
    calib, held_out = frames[:n], frames[n]

    with torch.no_grad():
        ref = net(*(torch.from_numpy(x) for x in held_out)).numpy()
        macs = a.macs or graph_export.count(graph_export.trace(
            net, *(torch.from_numpy(x) for x in held_out)))["macs"]
    t0 = time.perf_counter()
    f32_path = export_onnx(net, held_out, out / "depthor_f32.onnx", a.opset)
    export_s = round(time.perf_counter() - t0, 1)
    int8_path = out / "depthor_int8.onnx"
    qinfo = quantize(f32_path, int8_path, calib, a.method, a.int8_heads,
                     input_ranges(net) if a.input_ranges == "fixed" else None)

    feed = feeds(held_out)
    models = {"ORT f32": f32_path, "ORT int8": int8_path}
    opt = out / "int8_ort_optimised.onnx"
    session(int8_path, opt)  # saves the graph ORT runs after its fusions
    census = op_census(opt, set(qinfo["nodes_kept_f32"]), () if a.int8_heads else F32_SCOPES)
    sessions = {name: session(path) for name, path in models.items()}
    load = [loadavg()]
    ms = time_interleaved({name: partial(s.run, None, feed) for name, s in sessions.items()},
                          a.warmup, a.runs)
    load.append(loadavg())
    rows = []
    for name, path in models.items():
        (depth,) = sessions[name].run(None, feed)
        med = statistics.median(ms[name])
        rows.append({
            "model": name, "file": path.name, "bytes": path.stat().st_size,
            "median_ms": med, "min_ms": min(ms[name]), "runs": len(ms[name]),
            "gmac_per_s": macs / (med * 1e-3) / 1e9,
            "sqnr_db": sqnr_db(ref, depth), "sqnr_centred_db": sqnr_db(ref, depth, True),
            "max_abs_err_m": float(np.abs(depth - ref).max()),
            **({"op_census": census} if name == "ORT int8" else {}),
            **({"profile": profile(path, feed, a.runs)} if a.profile else {}),
        })
    held = (f"depthor sim frame {n} of --seed {a.calib_seed}" if a.calib == "sim"
            else f"net.random_inputs seed {a.calib_seed + n}")
    res = {
        "variant": a.variant, "height": cfg.height, "width": cfg.width, "weights": weights,
        "macs_per_frame": int(macs), "macs_source": "--macs" if a.macs else "graph_export.count",
        "calibration": {"source": a.calib, "seed": a.calib_seed, **qinfo,
                        "f32_scopes": [] if a.int8_heads else list(F32_SCOPES)},
        "sqnr_input": f"{held} (not a calibration frame)",
        "opset": a.opset, "export_s": export_s, "warmup": a.warmup,
        "onnxruntime": ort.__version__, "torch": torch.__version__,
        "cpu": cpu_name(), "cpus": os.cpu_count(), "loadavg_1min_before_after": load,
        "rows": rows,
    }
    (out / "bench.json").write_text(json.dumps(res, indent=1) + "\n")
    res["out"] = str(out)
    return res


def table(res: dict) -> str:
    """The plain-text report of `run`'s results."""
    c = res["calibration"]
    lines = [
        f"variant {res['variant']} {res['height']}x{res['width']}, weights {res['weights']}",
        f"MACs/frame {res['macs_per_frame'] / 1e9:.3f} G ({res['macs_source']}); ORT "
        f"{res['onnxruntime']}, 1 thread, {res['cpu']} ({res['cpus']} CPUs, 1-min load "
        f"{res['loadavg_1min_before_after'][0]} → {res['loadavg_1min_before_after'][1]} "
        f"while timing); warm-up {res['warmup']}",
        f"int8: QDQ, per-channel QInt8 weights, QUInt8 activations, {c['method']} ranges on "
        f"{c['frames']} {c['source']} frames; input ranges "
        + (", ".join(f"{k} [{lo:g}, {hi:g}]" for k, (lo, hi) in c["fixed_ranges"].items())
           or "calibrated") + "; kept f32: "
        + (f"{', '.join(c['f32_scopes'])} ({len(c['nodes_kept_f32'])} nodes)"
           if c["f32_scopes"] else "nothing (--int8-heads)"),
        f"SQNR vs PyTorch f32 on {res['sqnr_input']}",
        "",
        f"{'model':<9} {'runs':>4} {'median ms':>10} {'min ms':>8} {'GMAC/s':>7} "
        f"{'SQNR dB':>8} {'SQNR-mean dB':>12} {'max|err| m':>10} {'bytes':>9}",
    ]
    for r in res["rows"]:
        lines.append(
            f"{r['model']:<9} {r['runs']:>4} {r['median_ms']:>10.2f} {r['min_ms']:>8.2f} "
            f"{r['gmac_per_s']:>7.2f} {r['sqnr_db']:>8.1f} {r['sqnr_centred_db']:>12.1f} "
            f"{r['max_abs_err_m']:>10.2e} {r['bytes']:>9}")
    for r in res["rows"]:
        if "op_census" in r:
            lines.append("")
            oc = r["op_census"]
            lines.append("int8 session, nodes on 8-bit tensors: " + _fmt(oc["int8"]))
            lines.append("int8 session, float nodes kept f32:   " + _fmt(oc["float_kept"]))
            lines.append("int8 session, float nodes elsewhere:  " + _fmt(oc["float_other"]))
    for r in res["rows"]:
        if "profile" in r:
            p = r["profile"]
            lines.append("")
            lines.append(f"{r['model']} profile, kernel ms/run by scope: "
                         + _fmt(p["by_scope_ms"], 8))
            lines.append(f"{r['model']} profile, kernel ms/run by op:    " + _fmt(p["by_op_ms"], 8))
    lines.append(f"files: {res['out']}")
    return "\n".join(lines)


def _fmt(counts: dict, top: int | None = None) -> str:
    items = list(counts.items())
    text = ", ".join(f"{k} {v}" for k, v in items[:top]) or "none"
    return text + (f", … ({len(items) - top} more)" if top and len(items) > top else "")


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """Command-line arguments (see module doc)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", required=True, choices=sorted(PRESETS))
    ap.add_argument("--weights", default=None,
                    help="checkpoint/state dict, or 'random' (default: <variant>/summary.json's)")
    ap.add_argument("--runs", type=int, default=20, help="timed runs per model (default 20)")
    ap.add_argument("--warmup", type=int, default=1, help="untimed runs first (default 1)")
    ap.add_argument("--out", default=None, help="folder for the .onnx files "
                    "(default models/.onnx_cache/<variant>)")
    ap.add_argument("--calib", choices=["sim", "random"], default="sim",
                    help="calibration frames: depthor sim (default) or net.random_inputs")
    ap.add_argument("--calib-frames", type=int, default=16)
    ap.add_argument("--calib-seed", type=int, default=0)
    ap.add_argument("--cli", default=str(default_cli()), help="depthor CLI for --calib sim")
    ap.add_argument("--method", choices=["minmax", "entropy"], default="minmax",
                    help="ORT calibration method (default minmax)")
    ap.add_argument("--input-ranges", choices=["fixed", "calibrated"], default="fixed",
                    help="fixed: rgb [0, 1], sparse [0, max_depth_m] as the host quantizer "
                    "(default); calibrated: by --method like every other tensor")
    ap.add_argument("--int8-heads", action="store_true",
                    help="quantise bins_head and refine too (default: kept f32 as in the core)")
    ap.add_argument("--macs", type=int, default=None,
                    help="MACs per frame for GMAC/s (default: graph_export.count)")
    ap.add_argument("--opset", type=int, default=OPSET)
    ap.add_argument("--profile", action="store_true",
                    help="also profile --runs runs per model with ORT's profiler (ms by scope/op)")
    ap.add_argument("--smoke", action="store_true",
                    help="tiny run: 2 random calibration frames, 2 timed runs")
    a = ap.parse_args(argv)
    if a.smoke:
        a.calib, a.calib_frames, a.runs = "random", 2, 2
    if a.runs < 1 or a.calib_frames < 1 or a.warmup < 0:
        ap.error("--runs and --calib-frames must be >= 1, --warmup >= 0")
    return a


def main(argv: list[str] | None = None) -> int:
    """CLI entry point (see module doc)."""
    res = run(parse_args(argv))
    print(table(res))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
