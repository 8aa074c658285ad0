"""Mean +- std over seeds of `smile eval` results.

usage: python3 docs/scripts/aggregate_evals.py EVAL_DIR_OR_JSON...

Each argument is an `eval.json` (or the directory holding one). Methods are grouped by their
algorithm (the part of the method name before " (run dir)"); one line per algorithm with the
per-file means, their mean and sample std, and the mean per context size.
"""
import json
import os
import statistics as st
import sys


def main(paths):
    by = {}
    for p in paths:
        if os.path.isdir(p):
            p = os.path.join(p, "eval.json")
        with open(p) as f:
            report = json.load(f)
        for m in report["methods"]:
            algo = m["name"].split(" (")[0]
            by.setdefault(algo, []).append(m)
    print("| method | runs | test metric per run | mean +- std over runs | per context size |")
    print("|---|---|---|---|---|")
    for algo, ms in by.items():
        v = [m["mean"] for m in ms]
        sd = st.stdev(v) if len(v) > 1 else 0.0
        sizes = len(ms[0]["by_context_size"])
        per_k = [st.mean(m["by_context_size"][k] for m in ms) for k in range(sizes)]
        print(
            f"| {algo} | {len(v)} | {', '.join(f'{x:.3f}' for x in v)} | "
            f"**{st.mean(v):.3f} +- {sd:.3f}** | {' / '.join(f'{x:.3f}' for x in per_k)} |"
        )


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
