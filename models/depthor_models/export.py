"""Exports one variant: NNEF of the full network and of the prior (torch-to-nnef, offline),
graph.json + weights.bin (docs/graph.md), golden tensors, and summary.json with parameter/MAC counts.

    python -m depthor_models.export --variant mcu --out mcu [--weights runs/mcu/ckpt.pt]

torch-to-nnef's TractNNEF target always resolves a tract CLI when it is built and downloads one
unless given a path. No network is reachable here and building tract-cli takes too long, so by
default we give it a version stub (prints `tract <version>` for `--version`, refuses anything
else) and set check_io=False; with `--tract-cli PATH` (or DEPTHOR_TRACT_CLI) a real tract CLI
of that version is used and torch-to-nnef checks tract's outputs against PyTorch.
"""

from __future__ import annotations

import argparse
import json
import os
import stat
import tempfile
import time
from pathlib import Path

import torch
from torch import Tensor, nn

from . import golden, graph_export
from .net import VARIANTS, Depthor, build, parse_overrides, random_inputs

TRACT_VERSION = "0.23.9"  # the tract of requirements.txt and host/Cargo.toml, which load the export
DEFAULT_SEED = 0
GOLDEN_SEED = 1


def _version_stub(version: str, directory: Path) -> Path:
    path = directory / "tract-version-stub"
    path.write_text(
        "#!/bin/sh\n"
        f'if [ "$1" = "--version" ]; then echo "tract {version}"; exit 0; fi\n'
        'echo "depthor export: no tract CLI here (check_io is off); '
        'pass --tract-cli or set DEPTHOR_TRACT_CLI" >&2\n'
        "exit 2\n"
    )
    path.chmod(path.stat().st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)
    return path


def tract_target(tract_cli: str | Path | None = None, version: str = TRACT_VERSION,
                 stub_dir: Path | None = None):
    """A torch_to_nnef.TractNNEF target that never downloads: a real CLI (check_io on) or the
    version stub written into `stub_dir` (check_io off)."""
    from torch_to_nnef import TractNNEF

    if tract_cli:
        return TractNNEF(version, check_io=True, specific_tract_binary_path=Path(tract_cli),
                         dump_identity_properties=False)
    stub = _version_stub(version, stub_dir or Path(tempfile.mkdtemp(prefix="depthor-tract-")))
    return TractNNEF(version, check_io=False, specific_tract_binary_path=stub,
                     dump_identity_properties=False)


def export_nnef(model: nn.Module, args: tuple[Tensor, ...], path: str | Path,
                input_names: list[str], output_names: list[str],
                tract_cli: str | Path | None = None) -> Path:
    """torch_to_nnef.export_model_to_nnef into `<path>` (must end in `.nnef.tgz`); returns the
    archive path."""
    import logging

    from torch_to_nnef import export_model_to_nnef

    path = Path(path)
    if not path.name.endswith(".nnef.tgz"):
        raise ValueError("NNEF path must end in .nnef.tgz")
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="depthor-tract-") as tmp:
        target = tract_target(tract_cli, stub_dir=Path(tmp))
        with torch.no_grad():
            out = export_model_to_nnef(
                model=model.eval(),
                args=args,
                file_path_export=path.with_name(path.name[: -len(".tgz")]),
                inference_target=target,
                input_names=input_names,
                output_names=output_names,
                compression_level=6,
                log_level=logging.WARNING,
            )
    out = Path(out)
    if out != path:
        raise RuntimeError(f"torch-to-nnef wrote {out}, expected {path}")
    return out


def build_trained(variant: str, weights: str | Path, **overrides) -> Depthor:
    """The variant (with NetConfig `overrides`, as trained with `--set`) with trained weights
    from a training checkpoint (`{"model": state_dict}`, e.g. runs/mcu/ckpt.pt) or a plain
    state-dict file, in eval mode."""
    obj = torch.load(weights, map_location="cpu", weights_only=False)
    state = obj["model"] if isinstance(obj, dict) and "model" in obj else obj
    net = build(variant, calibrate_bn=False, **overrides)
    net.load_state_dict(state)
    return net.eval()


def export_variant(variant: str, out_dir: str | Path, seed: int = DEFAULT_SEED,
                   golden_seed: int = GOLDEN_SEED, nnef: bool = True,
                   tract_cli: str | Path | None = None, net: Depthor | None = None,
                   weights: str | Path | None = None, overrides: dict | None = None) -> dict:
    """Writes every artefact of `variant` into out_dir and returns the summary dict. With
    `weights` (a training checkpoint or state dict) the trained network is exported instead of
    the seeded random one; `overrides`: NetConfig fields as trained (`--set`)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    o = overrides or {}
    if net is None:
        net = build_trained(variant, weights, **o) if weights else build(variant, seed=seed, **o)
    cfg = net.cfg
    rgb, sparse = random_inputs(cfg, torch.Generator().manual_seed(golden_seed))
    traced = graph_export.trace(net, rgb, sparse)
    counts = graph_export.count(traced)
    gpath, wpath = graph_export.write(traced, out)
    gidx = golden.write(traced, out / "golden", golden_seed)
    files = {"graph": gpath, "weights": wpath, "golden_index": gidx}
    timings = {}
    if nnef:
        t0 = time.perf_counter()
        files["nnef"] = export_nnef(net, (rgb, sparse), out / "depthor.nnef.tgz",
                                    ["rgb", "sparse"], ["depth"], tract_cli)
        timings["nnef_full_s"] = round(time.perf_counter() - t0, 2)
        t0 = time.perf_counter()
        files["prior_nnef"] = export_nnef(net.prior, (rgb,), out / "prior.nnef.tgz",
                                          ["rgb"], ["d_inv", "f_mde"], tract_cli)
        timings["nnef_prior_s"] = round(time.perf_counter() - t0, 2)
    summary = {
        "variant": variant,
        "height": cfg.height,
        "width": cfg.width,
        "seed": seed,
        "golden_seed": golden_seed,
        "weights": (_describe_weights(weights) if weights else
                    "random init (untrained), BN statistics from 3 train-mode passes"),
        "weights_path": str(weights) if weights else None,
        **counts,
        "files": {k: {"path": Path(v).name if k != "golden_index" else "golden/index.json",
                      "bytes": Path(v).stat().st_size} for k, v in files.items()},
        "export_timings": timings,
        "command": f"python -m depthor_models.export --variant {variant} --out <dir>"
                   + (f" --weights {weights}" if weights else ""),
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    return summary


def _describe_weights(weights: str | Path) -> str:
    obj = torch.load(weights, map_location="cpu", weights_only=False)
    if isinstance(obj, dict) and "step" in obj:
        return f"trained: {Path(weights).name}, step {obj['step']}"
    return f"trained: {Path(weights).name}"


def main(argv: list[str] | None = None) -> int:
    """CLI entry point (see module doc)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", required=True, choices=sorted(VARIANTS))
    ap.add_argument("--out", required=True, help="output folder, e.g. models/mcu")
    ap.add_argument("--seed", type=int, default=DEFAULT_SEED)
    ap.add_argument("--weights", default=None,
                    help="trained weights (training checkpoint or state dict; default: random)")
    ap.add_argument("--no-nnef", action="store_true", help="skip the NNEF exports")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="NetConfig override, as the weights were trained with (train --set)")
    ap.add_argument("--tract-cli", default=os.environ.get("DEPTHOR_TRACT_CLI"),
                    help="real tract CLI to check NNEF outputs with (default: none, no check)")
    a = ap.parse_args(argv)
    s = export_variant(a.variant, a.out, a.seed, nnef=not a.no_nnef, tract_cli=a.tract_cli,
                       weights=a.weights, overrides=parse_overrides(a.set))
    print(json.dumps({k: s[k] for k in ("variant", "params_deployed", "params_prior", "macs",
                                         "macs_prior", "files", "export_timings")}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
