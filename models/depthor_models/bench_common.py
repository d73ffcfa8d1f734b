"""Timing and error helpers shared by the runtime benchmarks (`bench_onnx`, `bench_litert`).

Imports numpy and the standard library only: `bench_litert`'s worker runs it in
models/.venv-litert, which has no PyTorch."""

from __future__ import annotations

import math
import os
import platform
import time
from pathlib import Path
from typing import Callable

import numpy as np


def time_interleaved(runners: dict[str, Callable[[], object]], warmup: int,
                     runs: int) -> dict[str, list[float]]:
    """Milliseconds of `runs` timed calls of each runner (one inference of one frame), after
    `warmup` untimed calls each; the runners take turns run by run, so a change in the load of
    a shared machine hits them alike."""
    for run in runners.values():
        for _ in range(warmup):
            run()
    ms = {name: [] for name in runners}
    for _ in range(runs):
        for name, run in runners.items():
            t0 = time.perf_counter()
            run()
            ms[name].append((time.perf_counter() - t0) * 1e3)
    return ms


def sqnr_db(ref: np.ndarray, test: np.ndarray, centred: bool = False) -> float:
    """10·log10(Σ s² / Σ (s − t)²), s = ref (minus its mean when `centred`), as
    host quantize::check::sqnr_db and its "depth − mean" column."""
    r = ref.astype(np.float64).ravel()
    t = test.astype(np.float64).ravel()
    s = r - r.mean() if centred else r
    noise = float(np.sum((r - t) ** 2))
    return math.inf if noise == 0 else 10.0 * math.log10(float(np.sum(s * s)) / noise)


def loadavg() -> float | None:
    """The 1-minute load average (None where the OS has none)."""
    try:
        return round(os.getloadavg()[0], 2)
    except OSError:
        return None


def cpu_name() -> str:
    """The CPU's model name from /proc/cpuinfo (else what `platform` says)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()
