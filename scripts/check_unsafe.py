#!/usr/bin/env python3
"""Counts the `unsafe` uses of depthor-core (core/src) and fails when one lacks its safety
argument (issue 45). The rule, as clippy's `undocumented_unsafe_blocks` and
`missing_safety_doc` state it, applied to every target's code (also the `cfg`s a host clippy does
not compile: Arm `asm!`, AVX-512):

- an `unsafe { … }` block or an `unsafe impl` has a `// SAFETY:` comment on its line or in the
  comment lines right above its statement (attributes and blank lines may sit between);
- an `unsafe fn` or `unsafe trait` has a `# Safety` doc section or a `SAFETY:` comment there,
  or is a method of a trait or impl whose header carries one (the trait states the contract).

Usage: python3 scripts/check_unsafe.py [--list]. Prints the counts; exit 1 on a missing one.
"""
import glob
import os
import re
import sys

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))


def documented(lines, i):
    """A SAFETY comment or `# Safety` section on line i or in the comments/attributes above."""
    if "SAFETY" in lines[i]:
        return True
    j = i - 1
    while j >= 0:
        s = lines[j].strip()
        if not (s.startswith("//") or s.startswith("#[") or s == ""):
            break
        if "SAFETY" in s or "# Safety" in s:
            return True
        j -= 1
    return False


def statement_start(lines, i):
    """The first line of the statement holding line i (for `let x =\n unsafe {`)."""
    j = i
    while j > 0:
        prev = lines[j - 1].rstrip()
        if prev.endswith((";", "{", "}", ",")) or prev.strip().startswith(("//", "#[")) or prev.strip() == "":
            break
        j -= 1
    return j


def enclosing_header(lines, i):
    """Line of the `impl`/`trait` item that an indented item at line i belongs to."""
    indent = len(lines[i]) - len(lines[i].lstrip())
    for j in range(i - 1, -1, -1):
        s = lines[j]
        if s.strip() and len(s) - len(s.lstrip()) < indent:
            return j if re.match(r"\s*(pub(\([^)]*\))?\s+)?(unsafe\s+)?(impl|trait)\b", s) else None
    return None


def main():
    listing = "--list" in sys.argv
    counts = {"block": 0, "impl": 0, "fn": 0, "trait": 0}
    missing = []
    for path in sorted(glob.glob(os.path.join(ROOT, "core/src/**/*.rs"), recursive=True)):
        lines = open(path, encoding="utf-8").read().split("\n")
        for i, line in enumerate(lines):
            code = line.split("//")[0]
            for m in re.finditer(r"\bunsafe\b", code):
                rest = code[m.end():].lstrip()
                kind = next((k for k, p in (("block", "{"), ("impl", "impl"), ("fn", "fn"), ("trait", "trait"))
                             if rest.startswith(p)), None)
                if kind is None:
                    missing.append((path, i, "unrecognised `unsafe` use"))
                    continue
                counts[kind] += 1
                ok = documented(lines, i) or documented(lines, statement_start(lines, i))
                if not ok and kind == "fn":
                    h = enclosing_header(lines, i)
                    ok = h is not None and documented(lines, h)
                if listing:
                    print(f"{os.path.relpath(path, ROOT)}:{i + 1}: {kind}: {'ok' if ok else 'MISSING'}")
                if not ok:
                    missing.append((path, i, f"unsafe {kind} without a SAFETY comment / # Safety section"))
    total = sum(counts.values())
    print(f"core/src: {total} unsafe uses ({counts['block']} blocks, {counts['impl']} impls, "
          f"{counts['fn']} fns, {counts['trait']} traits), {total - len(missing)} with their safety argument")
    for path, i, what in missing:
        print(f"{os.path.relpath(path, ROOT)}:{i + 1}: {what}")
    return 1 if missing else 0


if __name__ == "__main__":
    sys.exit(main())
