#!/usr/bin/env python3
"""Where the firmware's instructions go: per-PC counts from `pcprof.c` summed per function.

    python3 symbolize.py ELF COUNTS [TOP] [RUNS]

ELF: the firmware built with debug info (firmware-sim's release profile has it); COUNTS: the
plugin's `out=` file ("0xPC count" lines); TOP: rows per table (30); RUNS: model runs the counts
cover, to print per-run figures (6 for the default image: 5 frames + the profiled frame).
Prints three tables: by outermost function, by innermost inlined function, by source line.
"""
import collections
import json
import subprocess
import sys


def main() -> None:
    elf, counts_file = sys.argv[1], sys.argv[2]
    top = int(sys.argv[3]) if len(sys.argv) > 3 else 30
    runs = float(sys.argv[4]) if len(sys.argv) > 4 else 6.0
    rows = [line.split() for line in open(counts_file)]
    pcs = [r[0] for r in rows]
    counts = [int(r[1]) for r in rows]
    out = subprocess.run(
        ["llvm-symbolizer", f"--obj={elf}", "--output-style=JSON", "-C"],
        input="\n".join(pcs) + "\n", capture_output=True, text=True, check=True,
    ).stdout
    outer, inner, line = collections.Counter(), collections.Counter(), collections.Counter()
    for c, entry in zip(counts, out.splitlines()):
        frames = json.loads(entry).get("Symbol", [])
        if not frames:
            outer["?"] += c
            continue
        outer[frames[-1]["FunctionName"][:100]] += c
        inner[frames[0]["FunctionName"][:100]] += c
        where = frames[0]["FileName"].split("/src/")[-1]
        line[f"{where}:{frames[0]['Line']}  [{frames[-1]['FunctionName'][:60]}]"] += c
    total = sum(counts)
    print(f"total {total} instructions; per run = / {runs:g}")
    for name, table in (("outermost function", outer), ("innermost function", inner),
                        ("source line", line)):
        print(f"== by {name} (M instructions per run, share)")
        for key, v in table.most_common(top):
            print(f"{v / runs / 1e6:9.2f}  {100 * v / total:5.1f} %  {key}")


if __name__ == "__main__":
    main()
