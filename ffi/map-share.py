#!/usr/bin/env python3
"""Bytes a GNU ld map file places in FLASH/RAM from each archive: `map-share.py MAP [ARCHIVE…]`.

Sums the input sections kept in the link (.text*, .rodata*, .data*, .bss*, .ARM.ex*) per
archive basename (objects outside archives count as "objects"); prints one line per archive:
`name text+rodata=… data=… bss=…`.
"""
import re
import sys
from collections import defaultdict

line_re = re.compile(r"^\s*(\.\S+)?\s+0x([0-9a-f]+)\s+0x([0-9a-f]+)\s+(\S+)$")
kinds = {".text": "code", ".rodata": "code", ".ARM": "code", ".data": "data", ".bss": "bss", "COMMON": "bss"}


def main() -> None:
    path = sys.argv[1]
    totals = defaultdict(lambda: defaultdict(int))
    pending = None
    in_memory_map = False
    for raw in open(path, encoding="utf-8", errors="replace"):
        if raw.startswith("Linker script and memory map"):
            in_memory_map = True
            continue
        if not in_memory_map:
            continue
        s = raw.rstrip("\n")
        m = line_re.match(s)
        if m and (m.group(1) or pending):
            section = m.group(1) or pending
            pending = None
            size = int(m.group(3), 16)
            origin = m.group(4)
            kind = next((v for k, v in kinds.items() if section.startswith(k)), None)
            if kind is None or size == 0 or origin.startswith("0x"):
                continue
            archive = origin.split("(")[0].rsplit("/", 1)[-1] if "(" in origin else "objects"
            totals[archive][kind] += size
            continue
        t = s.strip()
        pending = t if (t.startswith(".") or t.startswith("COMMON")) and " " not in t else None
    want = sys.argv[2:] or sorted(totals)
    for a in want:
        t = totals.get(a, {})
        print(f"{a} text+rodata={t.get('code', 0)} data={t.get('data', 0)} bss={t.get('bss', 0)}")


main()
