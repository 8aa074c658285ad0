#!/usr/bin/env python3
"""Table 2 (left) from a walker-dyn sweep: per method, mean +- std over seeds of the mean return,
of the paper's normalised score (mean over tasks of (R - R_base) / (R_expert - R_base), tasks
with R_expert > R_base), of a ratio-of-means variant ((mean R - mean R_base) / (mean R_expert -
mean R_base) over the same tasks: not the paper's, but not dominated by the tasks where expert
and base are close), and of the mean episode length (survival; a fall ends an episode).

    python3 docs/scripts/walker-table.py runs/walker-dyn-table2
"""
import json, os, statistics as st, sys

root = sys.argv[1]
rows = {}
ref = None
for cell in sorted(os.listdir(root)):
    path = os.path.join(root, cell, "eval", "eval.json")
    if not os.path.exists(path):
        continue
    ev = json.load(open(path))
    ref = ev["reference"]
    m = ev["methods"][0]
    method = cell.rsplit("-s", 1)[0]
    base, expert = ref["base_returns"], ref["expert_returns"]
    used = [i for i in range(len(base)) if expert[i] > base[i]]
    r = [t["metric"] for t in m["tasks"]]
    mean = lambda xs: sum(xs) / len(xs)
    ratio = (mean([r[i] for i in used]) - mean([base[i] for i in used])) / (
        mean([expert[i] for i in used]) - mean([base[i] for i in used]))
    rows.setdefault(method, []).append((m["mean"], m["normalised"]["score"], ratio))

def ms(xs):
    return f"{st.mean(xs):.3f} +- {st.stdev(xs) if len(xs) > 1 else 0:.3f}"

print("| method | seeds | return | normalised (paper) | normalised, ratio of means |")
print("|---|---|---|---|---|")
for method, v in rows.items():
    ret = [x[0] for x in v]
    print(f"| {method} | {len(v)} | {st.mean(ret):.0f} +- {st.stdev(ret) if len(v) > 1 else 0:.0f} "
          f"| {ms([x[1] for x in v])} | {ms([x[2] for x in v])} |")
if ref:
    b, e = ref["base_returns"], ref["expert_returns"]
    bs, es = ref.get("base_steps", []), ref.get("expert_steps", [])
    print(f"\nbase: return {st.mean(b):.0f}, survives >= 900 steps on {sum(s >= 900 for s in bs)}/{len(b)}, "
          f"mean length {st.mean(bs):.0f}")
    print(f"experts: return {st.mean(e):.0f}, survive >= 900 steps on {sum(s >= 900 for s in es)}/{len(e)}, "
          f"mean length {st.mean(es):.0f}; R_expert > R_base on {sum(x > y for x, y in zip(e, b))}/{len(e)}")
