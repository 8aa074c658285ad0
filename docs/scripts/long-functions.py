#!/usr/bin/env python3
"""Lists the workspace's functions longer than a limit (default 100 lines), outside tests.

Issue 58's rule: no function over 100 lines without a comment saying why. A function counts
as explained when the comments above its `fn` (its doc, plain comments, attributes between)
or right below it say "long" or "over 100 lines". Test code is skipped: `tests/` and `benches/` folders, and everything after a
`#[cfg(test)]` line in a file (the house keeps its unit tests at the end of a file).

    python3 docs/scripts/long-functions.py [--limit 100] [--all]

Prints `LINES path:line name` per function over the limit, unexplained ones first (`--all`
lists the explained ones too); exits 1 when an unexplained one exists.
"""
import argparse
import pathlib
import re
import sys

FN = re.compile(r"^\s*(pub(\([^)]*\))?\s+)?(const\s+)?(async\s+)?(unsafe\s+)?fn\s+(\w+)")
WHY = ("long", "over 100 lines")
CRATES = ["sim", "trainer", "app", "infer-core", "firmware-sim", "tests"]


def code_only(line):
    """The line without string literals, char literals and a trailing // comment."""
    line = re.sub(r'"(\\.|[^"\\])*"', '""', line)
    line = re.sub(r"'(\\.|[^'\\])'", "''", line)
    return line.split("//", 1)[0]


def functions(path):
    """(name, first line, length, explained) for each function of the file's non-test part."""
    lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    end = next((i for i, l in enumerate(lines) if l.strip() == "#[cfg(test)]"), len(lines))
    i = 0
    while i < end:
        m = FN.match(lines[i])
        if not m:
            i += 1
            continue
        depth, opened, j = 0, False, i
        while j < end:
            code = code_only(lines[j])
            if not opened and ";" in code and "{" not in code:
                break  # a declaration without a body (a trait's)
            depth += code.count("{") - code.count("}")
            opened |= "{" in code
            if opened and depth <= 0:
                break
            j += 1
        length = j - i + 1
        k = i
        while k > 0 and lines[k - 1].strip().startswith(("//", "#[")):
            k -= 1
        n = i + 1
        while n < end and lines[n].strip().startswith("//"):
            n += 1
        said = " ".join(lines[k:i] + lines[i + 1:n]).lower()
        yield m.group(6), i + 1, length, any(w in said for w in WHY)
        i += 1  # nested functions are counted on their own too


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--limit", type=int, default=100)
    ap.add_argument("--all", action="store_true", help="list explained functions too")
    a = ap.parse_args()
    root = pathlib.Path(__file__).resolve().parents[2]
    rows = []
    for crate in CRATES:
        for p in sorted((root / crate).rglob("*.rs")):
            rel = p.relative_to(root)
            if {"tests", "benches", "target"} & set(rel.parts[1:-1]) or "/tests/" in f"/{rel}":
                continue
            for name, line, length, explained in functions(p):
                if length > a.limit:
                    rows.append((explained, -length, f"{rel}:{line}", name))
    rows.sort()
    unexplained = [r for r in rows if not r[0]]
    for explained, neg, where, name in rows:
        if explained and not a.all:
            continue
        print(f"{-neg:4d} {where} {name}{'  (explained)' if explained else ''}")
    print(f"{len(unexplained)} unexplained, {len(rows) - len(unexplained)} explained "
          f"functions over {a.limit} lines")
    sys.exit(1 if unexplained else 0)


if __name__ == "__main__":
    main()
