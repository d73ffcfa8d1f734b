#!/usr/bin/env python3
"""Instructions per frame and function from two tbprof.c outputs (3 frames, 1 frame).

    python3 profile.py <aarch64 ELF> tb3.txt tb1.txt [rows]

qemu-aarch64 loads a PIE program at 0x5500000000 (QEMU 7.2 user mode on a 64-bit host); blocks
are named by the nearest preceding symbol of `aarch64-linux-gnu-nm`. Blocks outside the program
(libc, the loader) are summed as "?other". Per frame = (3-frame count - 1-frame count) / 2."""
import bisect
import collections
import subprocess
import sys

BASE = 0x5500000000
exe, three, one = sys.argv[1:4]
rows = int(sys.argv[4]) if len(sys.argv) > 4 else 25
syms = []
nm = subprocess.run(["aarch64-linux-gnu-nm", "-C", "--defined-only", exe], capture_output=True, text=True)
for line in nm.stdout.splitlines():
    p = line.split(" ", 2)
    if len(p) == 3 and p[1] in "tTwW":
        syms.append((int(p[0], 16), p[2]))
syms.sort()
addrs = [a for a, _ in syms]


def load(path):
    agg = collections.Counter()
    for line in open(path):
        va, n = line.split()
        va = int(va, 16) - BASE
        i = bisect.bisect_right(addrs, va) - 1
        agg[syms[i][1][:110] if i >= 0 and 0 <= va < 0x10000000 else "?other"] += int(n)
    return agg


a3, a1 = load(three), load(one)
per = {k: (a3[k] - a1[k]) / 2 for k in a3}
total = sum(per.values())
print(f"per frame {total / 1e6:.2f} M")
for k, v in sorted(per.items(), key=lambda kv: -kv[1])[:rows]:
    print(f"{v / 1e6:7.2f} M {100 * v / total:5.1f} % {k}")
