#!/usr/bin/env python3
"""ant-linclass Table 2 (right) from `smile report`'s report.json: success, no-op rate and the
accuracy among decided episodes (ours: success / (1 - no-op), per seed then mean +- std; by
context size from the means over seeds), as markdown.

    smile report runs/ant-linclass-table2 -o runs/ant-linclass-table2/report
    python3 docs/scripts/linclass-table.py runs/ant-linclass-table2/report/report.json
"""
import json
import statistics
import sys

PAPER = {"smile": "0.68 (no-op 0.02)", "smile-state-only": "0.65 (0.01)", "meta-bc": "0.50 (0.00)", "meta-dagger": "0.67 (0.14)"}


def pm(xs):
    sd = statistics.stdev(xs) if len(xs) > 1 else 0.0
    return f"{statistics.mean(xs):.3f} +- {sd:.3f}"


def main(path):
    report = json.load(open(path))
    sizes = " / ".join(str(k) for k in report["context_sizes"])
    print(f"| method | seeds | success | no-op rate | decided accuracy (ours) | success by context size ({sizes}) | decided accuracy by context size | paper success (no-op) |")
    print("|---|---|---|---|---|---|---|---|")
    for row in report["rows"]:
        no_op = row["no_op"]
        acc = [s / (1 - n) for s, n in zip(row["per_seed"], no_op["per_seed"]) if n < 1]
        acc_k = [s / (1 - n) if n < 1 else float("nan")
                 for s, n in zip(row["by_context_size"], no_op["by_context_size"])]
        print(
            f"| {row['method']} | {len(row['seeds'])} | {pm(row['per_seed'])} | {pm(no_op['per_seed'])} "
            f"| {pm(acc)} | {' / '.join(f'{x:.3f}' for x in row['by_context_size'])} "
            f"| {' / '.join(f'{x:.3f}' for x in acc_k)} | {PAPER.get(row['method'], '-')} |"
        )


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "runs/ant-linclass-table2/report/report.json")
