#!/usr/bin/env python3
"""Thins a training run's metrics.jsonl for the archive in docs/results (issue 47: raw run logs
stay small in the repository). Kept: every evaluation line (a key starting `eval/`), the
training line just before each (the CPU-seconds a curve is plotted against), the first and last
lines, and every k-th other line so that at most MAX training lines remain. What the tables and
docs/scripts/learning_curves.py read is unchanged; the full log stays in the run directory.

  python3 docs/scripts/thin_metrics.py SRC DEST [MAX]
"""
import json
import sys


def thin(lines, most=200):
    rows = [json.loads(line) for line in lines if line.strip()]
    is_eval = [any(k.startswith("eval/") for k in r) for r in rows]
    train = [i for i, e in enumerate(is_eval) if not e]
    every = max(1, -(-len(train) // most))
    keep = set(train[::every])
    if rows:
        keep |= {0, len(rows) - 1}
    for i, e in enumerate(is_eval):
        if e:
            keep.add(i)
            j = i - 1
            while j >= 0 and is_eval[j]:
                j -= 1
            if j >= 0:
                keep.add(j)
    return [lines[i] for i in sorted(keep)]


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    src, dest = sys.argv[1], sys.argv[2]
    most = int(sys.argv[3]) if len(sys.argv) > 3 else 200
    lines = [l if l.endswith("\n") else l + "\n" for l in open(src) if l.strip()]
    out = thin(lines, most)
    with open(dest, "w") as f:
        f.writelines(out)
