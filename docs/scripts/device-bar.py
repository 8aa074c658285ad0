#!/usr/bin/env python3
"""The 1% bar read with its standard error, from `smile device-table`'s device-table.json.

Each column's degradation against float comes with its standard error, paired by task (the
same episodes run under float and under the blob). The deployed blob's verdict, at 95%:
  met         its upper bound, degradation + 1.96 s.e., is at most the bar;
  missed      its lower bound, degradation - 1.96 s.e., is above the bar;
  unresolved  the bar lies inside the interval: these episodes cannot tell.
A negative degradation is a better metric than float.

    python3 docs/scripts/device-bar.py runs/device-table/device-table.json [--bar 1.0]
"""
import argparse
import json
import math

Z95 = 1.96


def verdict(deg, se, bar):
    if se is None or math.isnan(se):
        return "unresolved (one task)"
    if deg + Z95 * se <= bar:
        return "met"
    if deg - Z95 * se > bar:
        return "missed"
    return "unresolved"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("table", help="device-table.json")
    ap.add_argument("--bar", type=float, default=1.0, help="the bar, percent worse than float")
    a = ap.parse_args()
    rows = json.load(open(a.table))
    print(f"| family, plant | method | deployed vs float (+- s.e.) | 95% interval | {a.bar:g}% bar | "
          "f32 blob (+- s.e.) | tasks x episodes |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        dep, f32 = r["blobs"][3], r["blobs"][0]
        deg, se = dep["degradation_pct"], dep.get("stderr_pct")
        se = float("nan") if se is None else se
        lo, hi = deg - Z95 * se, deg + Z95 * se
        method = r["method"] + (f" (int8 fine-tuned {r['qat_steps']} steps)" if r.get("qat_steps") else "")
        f32se = f32.get("stderr_pct")
        print(f"| {r['family']}, {r['physics']} | {method} | {deg:+.1f}% +- {se:.1f} | "
              f"{lo:+.1f}% to {hi:+.1f}% | {verdict(deg, se, a.bar)} | "
              f"{f32['degradation_pct']:+.1f}% +- {f32se if f32se is not None else float('nan'):.1f} | "
              f"{r['tasks']} x {r['episodes_per_task']} |")


if __name__ == "__main__":
    main()
