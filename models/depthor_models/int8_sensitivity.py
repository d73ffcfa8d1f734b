"""Which int8 value costs the most: the simulated int8 network (`qat.FakeQuant` on given ranges)
run once with every value rounded, then once per int8 value with that value alone left in
float; values ranked by how much of the RMS difference from the float depth they remove. The
candidates for 16-bit storage or a per-layer fix (issue 16, item 4).

    python -m depthor_models.int8_sensitivity --variant mcu_lite \\
        --weights mcu_lite/train/model_final.pt --ranges mcu_lite/qat_ranges.json \\
        --recording ../rec/val48_photo --recording ../rec/close_val48_photo \\
        [--kept depth_enc.stages.0.pw.act]

`--kept` leaves values in float in every run (those already stored as int16), so the ranking
names the next value given them. Use check or training recordings, never the held-out or real
sets. The rounding is PyTorch's simulation of the blob's (weights per channel, values per
tensor on the given ranges), not the engine's bits; `depthor quantize --report` gives the engine's per-op SQNR.
"""
from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path

import torch
from torch import Tensor

from . import data, qat
from .net import build, parse_overrides
from .train import load_weights


@dataclass
class Row:
    """One int8 value: the RMS int8-vs-float depth difference (m) with it left in float."""

    index: int
    name: str
    rms_m: float


def _depth(net, rgb: Tensor, sparse: Tensor, batch: int = 4) -> Tensor:
    with torch.no_grad():
        return torch.cat([net(rgb[i:i + batch], sparse[i:i + batch])
                          for i in range(0, len(rgb), batch)])


def rank(net, rgb: Tensor, sparse: Tensor, ranges: dict[str, list[float]],
         only: list[str] | None = None,
         kept: list[str] | None = None) -> tuple[float, list[Row]]:
    """(RMS difference with every value rounded, one :class:`Row` per int8 value — or per value
    named in `only` — smallest difference first). Values named in `kept` (already stored as
    int16, say) stay in float in every run, the base included, and are not ranked. Pixels where
    the float depth is not finite are left out."""
    net.eval()
    ref = _depth(net, rgb, sparse)
    fq = qat.FakeQuant(net, rgb[:1], sparse[:1]).attach()
    try:
        if fq.set_ranges(ranges) == 0:
            raise ValueError("no range names an int8 value of this network")
        ok = torch.isfinite(ref)
        kept_idx = set()
        for name in kept or []:
            if name not in fq.names or fq.kind[fq.names.index(name)] != "int8":
                raise ValueError(f"kept value {name!r} is no int8 value of this network")
            kept_idx.add(fq.names.index(name))
        fq.unrounded = set(kept_idx)

        def rms() -> float:
            return float(((_depth(net, rgb, sparse) - ref)[ok] ** 2).mean().sqrt())

        base = rms()
        rows = []
        for i, k in enumerate(fq.kind):
            if k != "int8" or not fq.seen[i] or i in kept_idx or (
                    only is not None and fq.names[i] not in only):
                continue
            fq.unrounded = kept_idx | {i}
            rows.append(Row(i, fq.names[i], rms()))
        fq.unrounded = set()
    finally:
        fq.detach()
    return base, sorted(rows, key=lambda r: r.rms_m)


def main(argv: list[str] | None = None) -> int:
    """CLI entry point (see module doc)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variant", required=True)
    ap.add_argument("--weights", required=True, help="trained checkpoint or state dict")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE")
    ap.add_argument("--ranges", required=True, help="qat_ranges.json (value name → [lo, hi])")
    ap.add_argument("--recording", action="append", required=True, help="repeatable")
    ap.add_argument("--frames", type=int, default=48, help="first frames of each recording")
    ap.add_argument("--top", type=int, default=15)
    ap.add_argument("--value", action="append", help="try only these values (repeatable)")
    ap.add_argument("--kept", action="append", default=[], metavar="VALUE",
                    help="left in float in every run, e.g. values already stored as int16 "
                         "(repeatable): ranks the next value given these")
    a = ap.parse_args(argv)
    net = build(a.variant, seed=0, calibrate_bn=False, **parse_overrides(a.set))
    net.load_state_dict(load_weights(a.weights))
    rgb, sp = data.first_frames(a.recording, a.frames, (net.cfg.height, net.cfg.width))
    ranges = json.loads(Path(a.ranges).read_text())
    base, rows = rank(net, rgb, sp, ranges, a.value, a.kept)
    kept = f" but {', '.join(a.kept)}" if a.kept else ""
    print(f"RMS int8-simulated vs float depth, every value rounded{kept}: {base:.4f} m "
          f"({len(rgb)} frames)")
    print("value left in float                   RMS (m)   share removed")
    for r in rows[: a.top]:
        print(f"{r.index:4d} {r.name:34s} {r.rms_m:.4f}   {(base - r.rms_m) / base:+.1%}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
