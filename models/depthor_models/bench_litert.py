"""LiteRT (TFLite) with XNNPACK, the runtime phones use, on the same network as `bench_onnx`.

    cd models && PYTHONPATH=. .venv/bin/python -m depthor_models.bench_litert --variant phone_lite \
        [--runs 20] [--warmup 1] [--out DIR] [--calib sim|random] [--calib-frames 16] \
        [--check-frames 3] [--smoke]

Two environments: this module runs in models/.venv (PyTorch) and hands the conversion and the
timing to its worker (`--worker DIR`), run in models/.venv-litert (requirements-litert.txt:
onnx2tf, TensorFlow, ai-edge-litert; no PyTorch there, so the worker half imports only numpy,
the standard library and `bench_common`).

1. PyTorch side: the variant with the trained weights bench_onnx uses (`bench_onnx.load_net`),
   `--calib-frames` (16) calibration frames and `--check-frames` (3) held-out frames after them
   from the same source (`bench_onnx.bench_frames`: `depthor sim` frames at the model's size, or
   `random`), both exported with `bench_onnx.export_onnx` (opset 17, BN folded): the full
   network (`depth`) and its conv backbone (`net.Backbone`: rgb, sparse → F_unet, bin logits,
   the two inputs of the bins head; bins head, guidance, affinity heads and refine cut). The
   inputs are written NHWC (the layout onnx2tf gives the .tflite inputs), the PyTorch outputs
   NCHW.
2. Worker, per graph: onnx2tf converts it to a float32 .tflite and, with `-oiqt -qt
   per-channel` and the calibration frames (`-cind`, mean 0, std 1: the frames as the network
   takes them), to the full-integer `*_integer_quant.tflite`: int8 weights per channel, int8
   activations wherever the converter has an int8 kernel, float32 inputs and outputs. The TFLite
   converter takes no list of nodes to keep in float, so unlike ORT int8 (`bench_onnx`, bins
   head and refine f32) the bins head and refine are quantised too. The bins head's `CumSum`
   runs over the bin axis of a [1, N, 1, 1] tensor, which onnx2tf keeps as axis 1 after moving
   channels last (a cumulative sum over a size-1 axis: depth off by metres); a
   parameter-replacement file (`-prf`) transposes its input back to channels-first and its
   output to channels-last again (`cumsum_fix`). onnx2tf downloads a calibration sample when the
   graph has a 4-D 3-channel input; a sample made of our frames is put in its working folder
   instead (`CALIB_SAMPLE`). Conversions are reused while the ONNX file, the calibration frames
   and the onnx2tf arguments are unchanged (`<out>/<model>.key`).
3. Worker: each .tflite in LiteRT's interpreter with its default XNNPACK delegate,
   num_threads=1; counts the nodes XNNPACK took (`xnnpack_census`); checks the outputs against
   PyTorch f32 on the check frames (max |diff|, RMSE, SQNR), then times the four models taking
   turns (`bench_common.time_interleaved`): `--warmup` (1) untimed runs each, `--runs` (20)
   timed runs of the first check frame; prints the median ms/frame and GMAC/s (MACs of
   `graph_export.count`: the whole graph, and for the backbone its nodes up to the bins head).

Files go to `--out` (default models/.litert_cache/<variant>, git-ignored): the two .onnx, the
.tflite files, onnx2tf's logs, the frames and references (.npy), bench.json.
`--smoke`: random frames (2 calibration, 1 check), 2 timed runs (tests/test_bench_litert.py).
"""

from __future__ import annotations

import argparse
import collections
import hashlib
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

if __package__ in (None, ""):  # `python models/depthor_models/bench_litert.py …`
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np

from depthor_models.bench_common import cpu_name, loadavg, sqnr_db, time_interleaved

MODELS = Path(__file__).resolve().parents[1]
LITERT_VENV = MODELS / ".venv-litert"
INPUTS = ("rgb", "sparse")
# The graphs benchmarked: name → their ONNX output names (the backbone's are `net.Backbone`'s).
GRAPHS = {"full": ("depth",), "backbone": ("f_unet", "bin_logits")}
# onnx2tf looks for this file in its working folder before downloading MS-COCO samples.
CALIB_SAMPLE = "calibration_image_sample_data_20x128x128x3_float32.npy"


# ---------------------------------------------------------------------------------------------
# PyTorch side (models/.venv)
# ---------------------------------------------------------------------------------------------


def backbone_macs(traced) -> int:
    """MACs of the nodes of a `graph_export.trace`d network that the bins head depends on (its
    ancestors: `net.Backbone`'s graph), by `graph_export.node_macs` as `graph_export.count`."""
    from depthor_models import graph_export

    g = traced.graph
    nodes = {n["name"]: n for n in g["nodes"]}
    heads = [n for n in g["nodes"] if n["op"] == "bins_head"]
    if len(heads) != 1:
        raise ValueError(f"expected one bins_head node, found {len(heads)}")
    seen, stack = set(), list(heads[0]["inputs"])
    while stack:
        name = stack.pop()
        if name in nodes and name not in seen:
            seen.add(name)
            stack.extend(nodes[name]["inputs"])
    shapes = {k: tuple(v.shape) for k, v in traced.values.items()}
    return sum(graph_export.node_macs(nodes[name], shapes, g) for name in seen)


def nhwc(x: np.ndarray) -> np.ndarray:
    """[N, C, H, W] → [N, H, W, C] float32, contiguous."""
    return np.ascontiguousarray(x.transpose(0, 2, 3, 1), dtype=np.float32)


def prepare(a: argparse.Namespace, out: Path) -> dict:
    """Exports the two graphs and writes them, the frames, the PyTorch references and the
    worker's job (job.json) to `out`; returns what only this side knows (weights, MACs, frames)."""
    import torch

    from depthor_models import bench_onnx, graph_export
    from depthor_models.net import Backbone

    net, weights = bench_onnx.load_net(a.variant, a.weights)
    n, k = a.calib_frames, a.check_frames
    frames = bench_onnx.bench_frames(net, a.calib, n + k, a.calib_seed, Path(a.cli))
    calib, check = frames[:n], frames[n:]
    graphs = {"full": net, "backbone": Backbone(net)}
    for i, name in enumerate(INPUTS):
        np.save(out / f"calib_{name}.npy", np.concatenate([nhwc(f[i]) for f in calib]))
        np.save(out / f"check_{name}.npy", np.concatenate([nhwc(f[i]) for f in check]))
    # onnx2tf's stand-in sample: 20 rgb crops of 128×128 from our frames (any float32 array of
    # this shape stops the download; it is not used when -cind gives every input's frames).
    rgb = np.concatenate([nhwc(f[0]) for f in frames])
    h0, w0 = max(0, (rgb.shape[1] - 128) // 2), max(0, (rgb.shape[2] - 128) // 2)
    crops = np.resize(rgb[:, h0:h0 + 128, w0:w0 + 128], (20, 128, 128, 3))
    np.save(out / CALIB_SAMPLE, crops.astype(np.float32))

    refs = {}
    with torch.no_grad():
        for gname, module in graphs.items():
            outs = [module(*(torch.from_numpy(x) for x in f)) for f in check]
            outs = [o if isinstance(o, tuple) else (o,) for o in outs]
            refs[gname] = {}
            for j, oname in enumerate(GRAPHS[gname]):
                path = out / f"ref_{gname}_{oname}.npy"
                np.save(path, np.concatenate([o[j].numpy() for o in outs]))
                refs[gname][oname] = path.name
            bench_onnx.export_onnx(module, check[0], out / f"{gname}.onnx",
                                   output_names=GRAPHS[gname])
        traced = graph_export.trace(net, *(torch.from_numpy(x) for x in check[0]))
    macs = {"full": int(graph_export.count(traced)["macs"]), "backbone": backbone_macs(traced)}
    held = (f"depthor sim frames {n}..{n + k - 1} of --seed {a.calib_seed}" if a.calib == "sim"
            else f"net.random_inputs seeds {a.calib_seed + n}..{a.calib_seed + n + k - 1}")
    job = {"graphs": {g: {"onnx": f"{g}.onnx", "outputs": list(GRAPHS[g]), "refs": refs[g]}
                      for g in graphs},
           "inputs": list(INPUTS), "warmup": a.warmup, "runs": a.runs}
    (out / "job.json").write_text(json.dumps(job, indent=1) + "\n")
    return {"variant": a.variant, "height": net.cfg.height, "width": net.cfg.width,
            "weights": weights, "macs_per_frame": macs,
            "calibration": {"source": a.calib, "seed": a.calib_seed, "frames": n},
            "check_input": f"{held} (not calibration frames)", "torch": torch.__version__}


def litert_python() -> Path:
    """The worker's interpreter: $DEPTHOR_LITERT_PYTHON or models/.venv-litert/bin/python."""
    return Path(os.environ.get("DEPTHOR_LITERT_PYTHON", LITERT_VENV / "bin" / "python"))


def run(a: argparse.Namespace) -> dict:
    """Prepare, run the worker in the LiteRT environment; returns the results (also written to
    <out>/bench.json)."""
    py = litert_python()
    if not py.exists():
        raise FileNotFoundError(f"{py}: no LiteRT environment (python3.11 -m venv "
                                "models/.venv-litert && models/.venv-litert/bin/pip install -r "
                                "models/requirements-litert.txt)")
    out = Path(a.out) if a.out else MODELS / ".litert_cache" / a.variant
    out.mkdir(parents=True, exist_ok=True)
    res = prepare(a, out)
    env = dict(os.environ, PYTHONPATH=str(MODELS), TF_CPP_MIN_LOG_LEVEL="2",
               PATH=f"{py.parent}{os.pathsep}{os.environ.get('PATH', '')}")  # onnx2tf → onnxsim
    with open(out / "worker.log", "w") as log:  # TensorFlow's start-up noise, onnx2tf's errors
        done = subprocess.run([str(py), "-m", "depthor_models.bench_litert", "--worker", str(out)],
                              env=env, cwd=MODELS, stdout=log, stderr=subprocess.STDOUT)
    if done.returncode:
        sys.stderr.write((out / "worker.log").read_text()[-6000:])
        raise RuntimeError(f"LiteRT worker failed ({done.returncode}): see {out / 'worker.log'}")
    res.update(json.loads((out / "litert.json").read_text()))
    for r in res["rows"]:
        r["gmac_per_s"] = res["macs_per_frame"][r["graph"]] / (r["median_ms"] * 1e-3) / 1e9
    res["cpus"] = os.cpu_count()
    (out / "bench.json").write_text(json.dumps(res, indent=1) + "\n")
    res["out"] = str(out)
    return res


# ---------------------------------------------------------------------------------------------
# Worker (models/.venv-litert): conversion, checks, timing
# ---------------------------------------------------------------------------------------------


def cumsum_fix(onnx_path: Path) -> dict | None:
    """onnx2tf parameter replacements for each `CumSum` over axis 1 of a 4-D tensor (the bins
    head's): its input transposed NHWC → NCHW before, its output NCHW → NHWC after, so the sum
    runs over the channels as in ONNX. None when the graph has no such node."""
    import onnx
    from onnx import numpy_helper

    model = onnx.load(str(onnx_path))
    model = onnx.shape_inference.infer_shapes(model)
    ranks = {v.name: len(v.type.tensor_type.shape.dim)
             for v in (*model.graph.value_info, *model.graph.input, *model.graph.output)}
    consts = {i.name: numpy_helper.to_array(i) for i in model.graph.initializer}
    for n in model.graph.node:
        if n.op_type == "Constant":
            consts[n.output[0]] = numpy_helper.to_array(n.attribute[0].t)
    ops = []
    for n in model.graph.node:
        if n.op_type != "CumSum" or ranks.get(n.input[0]) != 4:
            continue
        axis = int(consts[n.input[1]]) if n.input[1] in consts else None
        if axis not in (1, -3):
            raise ValueError(f"{n.name}: CumSum over axis {axis}: no replacement written for it")
        ops += [{"op_name": n.name, "param_target": "inputs", "param_name": n.input[0],
                 "pre_process_transpose_perm": [0, 3, 1, 2]},
                {"op_name": n.name, "param_target": "outputs", "param_name": n.output[0],
                 "post_process_transpose_perm": [0, 2, 3, 1]}]
    return {"format_version": 1, "operations": ops} if ops else None


def convert(out: Path, gname: str, spec: dict, inputs: list[str]) -> tuple[dict[str, Path], bool]:
    """onnx2tf: <out>/<gname>.onnx → ({"f32": …_float32.tflite, "int8":
    …_integer_quant.tflite} in <out>/<gname>_tf/, whether reused), with the calibration frames
    <out>/calib_<input>.npy; skipped (reused) when <out>/<gname>.key matches (same ONNX, frames
    and arguments). Log in <out>/<gname>_onnx2tf.log."""
    onnx_path = out / spec["onnx"]
    tf_dir = out / f"{gname}_tf"
    args = ["-i", onnx_path.name, "-o", tf_dir.name, "-oiqt", "-qt", "per-channel"]
    for name in inputs:
        calib = np.load(out / f"calib_{name}.npy", mmap_mode="r")
        zeros = "[[[[" + ",".join(["0.0"] * calib.shape[-1]) + "]]]]"
        ones = "[[[[" + ",".join(["1.0"] * calib.shape[-1]) + "]]]]"
        args += ["-cind", name, f"calib_{name}.npy", zeros, ones]
    prf = cumsum_fix(onnx_path)
    if prf:
        (out / f"{gname}_prf.json").write_text(json.dumps(prf, indent=1) + "\n")
        args += ["-prf", f"{gname}_prf.json"]
    files = {"f32": tf_dir / f"{onnx_path.stem}_float32.tflite",
             "int8": tf_dir / f"{onnx_path.stem}_integer_quant.tflite"}
    digest = hashlib.sha256(" ".join(args).encode())
    for f in [onnx_path.name] + [f"calib_{name}.npy" for name in inputs]:
        digest.update((out / f).read_bytes())
    key = out / f"{gname}.key"
    if key.exists() and key.read_text() == digest.hexdigest() and all(
            p.exists() for p in files.values()):
        return files, True
    key.unlink(missing_ok=True)
    onnx2tf = Path(sys.executable).parent / "onnx2tf"
    with open(out / f"{gname}_onnx2tf.log", "w") as log:
        subprocess.run([str(onnx2tf), *args], cwd=out, check=True, stdout=log,
                       stderr=subprocess.STDOUT)
    missing = [str(p) for p in files.values() if not p.exists()]
    if missing:
        raise RuntimeError(f"onnx2tf wrote no {missing} (see {gname}_onnx2tf.log)")
    key.write_text(digest.hexdigest())
    return files, False


def interpreter(path: Path):
    """LiteRT's interpreter on `path`, one thread, default delegates (XNNPACK), allocated."""
    from ai_edge_litert.interpreter import Interpreter

    it = Interpreter(model_path=str(path), num_threads=1)
    it.allocate_tensors()
    return it


def xnnpack_census(it) -> dict:
    """Nodes of the .tflite graph that the delegate took: the interpreter lists the original
    nodes and one DELEGATE node per partition; walking back from the outputs, where a DELEGATE
    node produces a tensor it stands for the nodes it replaced, so the original nodes reached
    are the ones TFLite's own kernels run. Returns {"nodes", "delegated", "partitions",
    "not_delegated": {op: count}}."""
    w = it._interpreter  # the wrapper has no public node list
    count = w.NumNodes()
    names = [w.NodeName(i) for i in range(count)]
    delegates = [i for i in range(count) if names[i] == "DELEGATE"]
    producer = {}
    for i in [i for i in range(count) if names[i] != "DELEGATE"] + delegates:
        for t in w.NodeOutputs(i):
            producer[int(t)] = i  # a delegate's outputs override the replaced nodes'
    reached, stack = set(), [producer[int(t)] for t in w.OutputIndices() if int(t) in producer]
    while stack:
        i = stack.pop()
        if i not in reached:
            reached.add(i)
            stack.extend(producer[int(t)] for t in w.NodeInputs(i) if int(t) in producer)
    own = [names[i] for i in reached if names[i] != "DELEGATE"]
    nodes = count - len(delegates)
    return {"nodes": nodes, "delegated": nodes - len(own), "partitions": len(delegates),
            "not_delegated": dict(collections.Counter(own).most_common())}


def infer(it, frame: dict[str, np.ndarray], ref_shapes: dict[str, tuple]) -> dict[str, np.ndarray]:
    """One inference of `frame` (input name → NHWC array). The outputs, 4-D ones moved back to
    channels first, are matched to the PyTorch output names by shape, which must be unambiguous."""
    for d in it.get_input_details():
        it.set_tensor(d["index"], frame[_input_name(d["name"], frame)])
    it.invoke()
    outs = [it.get_tensor(d["index"]) for d in it.get_output_details()]
    outs = [o.transpose(0, 3, 1, 2) if o.ndim == 4 else o for o in outs]
    result = {}
    for oname, shape in ref_shapes.items():
        fits = [o for o in outs if o.shape == shape]
        if len(fits) != 1:
            raise RuntimeError(f"{len(fits)} .tflite outputs have {oname}'s shape {shape}")
        result[oname] = fits[0]
    return result


def _input_name(tflite_name: str, names) -> str:
    """The one of `names` that the .tflite input's name contains (onnx2tf keeps the ONNX
    names, possibly with a prefix or suffix)."""
    found = [n for n in names if n in tflite_name]
    if len(found) != 1:
        raise KeyError(f".tflite input {tflite_name!r} matches {found} of {list(names)}")
    return found[0]


def check(it, frames: list[dict], refs: dict[str, np.ndarray]) -> dict:
    """Outputs over the check frames against PyTorch f32: per output max |diff|, RMSE, SQNR dB."""
    shapes = {o: (1, *r.shape[1:]) for o, r in refs.items()}
    got = [infer(it, f, shapes) for f in frames]
    out = {}
    for oname, ref in refs.items():
        test = np.concatenate([g[oname] for g in got])
        diff = (test.astype(np.float64) - ref)
        out[oname] = {"max_abs_diff": float(np.abs(diff).max()),
                      "rmse": float(np.sqrt(np.mean(diff ** 2))),
                      "sqnr_db": sqnr_db(ref, test)}
    return out


def worker(out: Path) -> dict:
    """Converts, checks and times what <out>/job.json asks; writes <out>/litert.json."""
    import ai_edge_litert
    import onnx2tf
    import tensorflow as tf

    job = json.loads((out / "job.json").read_text())
    inputs = job["inputs"]
    check_in = {n: np.load(out / f"check_{n}.npy") for n in inputs}
    frames = [{n: check_in[n][i:i + 1].copy() for n in inputs}
              for i in range(len(check_in[inputs[0]]))]
    rows, its, convert_s = [], {}, {}
    for gname, spec in job["graphs"].items():
        t0 = time.perf_counter()
        files, reused = convert(out, gname, spec, inputs)
        convert_s[gname] = "reused" if reused else round(time.perf_counter() - t0, 1)
        refs = {o: np.load(out / f) for o, f in spec["refs"].items()}
        for kind, path in files.items():
            name = f"LiteRT {kind}" + ("" if gname == "full" else f" {gname}")
            it = interpreter(path)
            its[name] = it
            rows.append({"model": name, "graph": gname, "kind": kind,
                         "file": str(path.relative_to(out)), "bytes": path.stat().st_size,
                         "xnnpack": xnnpack_census(it), "check": check(it, frames, refs)})
    # the timed frame: the first check frame, set once (set_tensor is not timed)
    for it in its.values():
        for d in it.get_input_details():
            it.set_tensor(d["index"], frames[0][_input_name(d["name"], inputs)])
    load = [loadavg()]
    ms = time_interleaved({name: it.invoke for name, it in its.items()},
                          job["warmup"], job["runs"])
    load.append(loadavg())
    for r in rows:
        t = ms[r["model"]]
        r.update(median_ms=statistics.median(t), min_ms=min(t), runs=len(t))
    res = {"rows": rows, "convert_s": convert_s, "warmup": job["warmup"],
           "loadavg_1min_before_after": load, "cpu": cpu_name(),
           "versions": {"ai-edge-litert": getattr(ai_edge_litert, "__version__", "?"),
                        "tensorflow": tf.__version__, "onnx2tf": onnx2tf.__version__}}
    (out / "litert.json").write_text(json.dumps(res, indent=1) + "\n")
    return res


# ---------------------------------------------------------------------------------------------
# CLI
# ---------------------------------------------------------------------------------------------


def table(res: dict) -> str:
    """The plain-text report of `run`'s results."""
    m, v, c = res["macs_per_frame"], res["versions"], res["calibration"]
    lines = [
        f"variant {res['variant']} {res['height']}x{res['width']}, weights {res['weights']}",
        f"MACs/frame full {m['full'] / 1e9:.3f} G, backbone {m['backbone'] / 1e9:.3f} G "
        f"({100 * m['backbone'] / m['full']:.1f} %; graph_export.count); LiteRT "
        f"{v['ai-edge-litert']} (XNNPACK), onnx2tf {v['onnx2tf']}, TF {v['tensorflow']}; "
        f"1 thread, {res['cpu']} ({res['cpus']} CPUs, 1-min load "
        f"{res['loadavg_1min_before_after'][0]} → {res['loadavg_1min_before_after'][1]} while "
        f"timing); warm-up {res['warmup']}",
        f"int8: onnx2tf -oiqt, per-channel int8 weights, int8 activations, calibrated on "
        f"{c['frames']} {c['source']} frames (NHWC); float32 in/out; nothing kept f32",
        f"check vs PyTorch f32 on {res['check_input']}",
        "",
        f"{'model':<21} {'runs':>4} {'median ms':>10} {'min ms':>8} {'GMAC/s':>7} "
        f"{'XNNPACK nodes':>13} {'bytes':>9}",
    ]
    for r in res["rows"]:
        x = r["xnnpack"]
        lines.append(
            f"{r['model']:<21} {r['runs']:>4} {r['median_ms']:>10.2f} {r['min_ms']:>8.2f} "
            f"{r['gmac_per_s']:>7.2f} {x['delegated']:>6}/{x['nodes']:<6} {r['bytes']:>9}")
    lines.append("")
    for r in res["rows"]:
        parts = [f"{o} max|diff| {q['max_abs_diff']:.2e} RMSE {q['rmse']:.2e} "
                 f"SQNR {q['sqnr_db']:.1f} dB" for o, q in r["check"].items()]
        lines.append(f"{r['model']:<21} " + "; ".join(parts))
    lines.append("")
    for r in res["rows"]:
        x = r["xnnpack"]
        nd = ", ".join(f"{k} {n}" for k, n in x["not_delegated"].items()) or "none"
        lines.append(f"{r['model']:<21} {x['partitions']} XNNPACK partitions; not delegated: {nd}")
    conv = ", ".join(f"{g} {t}" + ("" if t == "reused" else " s")
                     for g, t in res["convert_s"].items())
    lines.append(f"onnx2tf conversion: {conv}; files: {res['out']}")
    return "\n".join(lines)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """Command-line arguments (see module doc)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", help="mcu, mcu_lite, phone or phone_lite")
    ap.add_argument("--weights", default=None,
                    help="checkpoint/state dict, or 'random' (default: <variant>/summary.json's)")
    ap.add_argument("--runs", type=int, default=20, help="timed runs per model (default 20)")
    ap.add_argument("--warmup", type=int, default=1, help="untimed runs first (default 1)")
    ap.add_argument("--out", default=None, help="folder for the files "
                    "(default models/.litert_cache/<variant>)")
    ap.add_argument("--calib", choices=["sim", "random"], default="sim",
                    help="frames: depthor sim (default) or net.random_inputs")
    ap.add_argument("--calib-frames", type=int, default=16)
    ap.add_argument("--check-frames", type=int, default=3,
                    help="held-out frames after the calibration ones for the checks (default 3)")
    ap.add_argument("--calib-seed", type=int, default=0)
    ap.add_argument("--cli", default=None, help="depthor CLI for --calib sim "
                    "(default: $DEPTHOR_CLI or target/release/depthor)")
    ap.add_argument("--smoke", action="store_true",
                    help="tiny run: random frames (2 calibration, 1 check), 2 timed runs")
    ap.add_argument("--worker", metavar="DIR", default=None,
                    help="internal: run the LiteRT half on DIR/job.json (in .venv-litert)")
    a = ap.parse_args(argv)
    if a.worker is None and a.variant is None:
        ap.error("--variant is required")
    if a.smoke:
        a.calib, a.calib_frames, a.check_frames, a.runs = "random", 2, 1, 2
    if a.runs < 1 or a.calib_frames < 1 or a.check_frames < 1 or a.warmup < 0:
        ap.error("--runs, --calib-frames and --check-frames must be >= 1, --warmup >= 0")
    if a.worker is None:  # bench_onnx imports PyTorch: not in the worker's environment
        from depthor_models.bench_onnx import PRESETS, default_cli

        if a.variant not in PRESETS:
            ap.error(f"--variant must be one of {sorted(PRESETS)}")
        a.cli = a.cli or str(default_cli())
    return a


def main(argv: list[str] | None = None) -> int:
    """CLI entry point (see module doc)."""
    a = parse_args(argv)
    if a.worker is not None:
        worker(Path(a.worker))
        return 0
    print(table(run(a)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
