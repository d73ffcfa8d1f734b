"""Peak memory of a command and all its descendants (Linux /proc), e.g. training with DataLoader
workers:

    python models/peak_mem.py -- python -m depthor_models.train --data stream ...

Samples every `--every` seconds the process tree's summed PSS (proportional set size: pages
shared between the training process and its forked workers counted once in total) and summed
RSS (shared pages counted in every process: an upper bound), and prints the peaks and the
largest single-process RSS on stderr when the command ends; exits with the command's status.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path


def _children() -> dict[int, list[int]]:
    kids: dict[int, list[int]] = {}
    for p in Path("/proc").iterdir():
        if not p.name.isdigit():
            continue
        try:
            ppid = int((p / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        kids.setdefault(ppid, []).append(int(p.name))
    return kids


def _tree(root: int) -> list[int]:
    kids, out, todo = _children(), [], [root]
    while todo:
        pid = todo.pop()
        out.append(pid)
        todo.extend(kids.get(pid, []))
    return out


def _kib(path: Path, field: str) -> int:
    try:
        for line in path.read_text().splitlines():
            if line.startswith(field + ":"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


def main() -> int:
    """CLI (see module doc)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--every", type=float, default=0.5, help="sampling period, seconds")
    ap.add_argument("cmd", nargs=argparse.REMAINDER, help="the command, after --")
    a = ap.parse_args()
    cmd = a.cmd[1:] if a.cmd[:1] == ["--"] else a.cmd
    if not cmd:
        ap.error("no command given")
    proc = subprocess.Popen(cmd)
    peak_pss = peak_rss = peak_one = procs = 0
    while proc.poll() is None:
        pids = _tree(proc.pid)
        pss = sum(_kib(Path(f"/proc/{p}/smaps_rollup"), "Pss") for p in pids)
        rss = [_kib(Path(f"/proc/{p}/status"), "VmRSS") for p in pids]
        peak_pss, peak_rss = max(peak_pss, pss), max(peak_rss, sum(rss))
        peak_one, procs = max(peak_one, max(rss, default=0)), max(procs, len(pids))
        time.sleep(a.every)
    mib = 1024.0
    print(f"peak_mem: tree PSS {peak_pss / mib:.0f} MiB, tree RSS {peak_rss / mib:.0f} MiB, "
          f"largest process RSS {peak_one / mib:.0f} MiB, up to {procs} processes "
          f"(sampled every {a.every} s)", file=sys.stderr)
    return proc.returncode


if __name__ == "__main__":
    raise SystemExit(main())
