#!/usr/bin/env python3
"""Learning curves of a sweep's cells: the held-out train-task metric (`eval/val_metric` in each
cell's train/metrics.jsonl) against update pairs (SMILe) or gradient steps (Meta-BC) and
against wall-clock seconds (and against CPU-seconds, `charts/cpu_s`, where the runs log it),
one line per cell, coloured by method; with each cell's final
meta-test metric (eval/eval.json) and its training's last step and wall-clock, so a table can
state each method's updates and time.

    python3 docs/scripts/learning_curves.py SWEEP_DIR OUT_PREFIX [TITLE] [--also [METHOD=]DIR]...
        [--keep EARLIER.json]

`--also` adds cells from elsewhere to the same table and plot: DIR is another sweep directory
or one cell's directory (`runs/cv-width/narrow-s0`); `METHOD=` names their method (else the
cell name without its `-sN`), e.g. `--also smile=runs/cv-width/narrow-s0`. `--keep` carries the
cells of an earlier OUT_PREFIX.json whose run directories are gone (a later session adding a
seed): each is kept unless a cell of the same name is found again.

writes OUT_PREFIX.json (the curves and the per-cell summary) and OUT_PREFIX.svg (needs
matplotlib), and prints a markdown table: method, seeds, test metric mean +- std over seeds,
steps and wall-clock per cell.
"""
import json
import os
import statistics
import sys


def cells(sweep, method=None):
    """(cell name, method, directory) of every trained cell in a sweep, or of one cell."""
    if os.path.exists(os.path.join(sweep, "train", "metrics.jsonl")):
        name = os.path.basename(sweep.rstrip("/"))
        yield name, method or method_of(name), sweep
        return
    for name in sorted(os.listdir(sweep)):
        train = os.path.join(sweep, name, "train", "metrics.jsonl")
        if os.path.exists(train):
            yield name, method or method_of(name), os.path.join(sweep, name)


def method_of(name):
    return name.rsplit("-s", 1)[0]


def main():
    args, also, keep = [], [], None
    it = iter(sys.argv[1:])
    for a in it:
        if a == "--keep":
            keep = next(it, None)
            if keep is None:
                sys.exit("--keep needs an earlier OUT_PREFIX.json")
        elif a == "--also":
            spec = next(it, None)
            if spec is None:
                sys.exit("--also needs [METHOD=]DIR")
            method, _, d = spec.rpartition("=")
            also.append((d, method or None))
        else:
            args.append(a)
    if len(args) < 2:
        sys.exit(__doc__)
    sweep, out = args[0], args[1]
    title = args[2] if len(args) > 2 else os.path.basename(sweep.rstrip("/"))
    data = []
    found = [c for src in [(sweep, None)] + also for c in cells(*src)]
    for name, method, d in found:
        steps, walls, cpus, vals, last_step, last_wall = [], [], [], [], 0, 0.0
        cpu = 0.0
        for line in open(os.path.join(d, "train", "metrics.jsonl")):
            r = json.loads(line)
            last_step, last_wall = max(last_step, r["step"]), max(last_wall, r.get("wall_s", 0.0))
            cpu = r.get("charts/cpu_s", cpu)
            if "eval/val_metric" in r:
                steps.append(r["step"])
                walls.append(round(r["wall_s"], 1))
                cpus.append(round(cpu, 1))
                vals.append(r["eval/val_metric"])
        test = None
        ev = os.path.join(d, "eval", "eval.json")
        if os.path.exists(ev):
            test = json.load(open(ev))["methods"][0]["mean"]
        data.append({"cell": name, "method": method, "steps": steps, "wall_s": walls,
                     "cpu_s": cpus, "val_metric": vals, "last_step": last_step,
                     "last_wall_s": round(last_wall), "last_cpu_s": round(cpu),
                     "test_metric": test})
    kept = []
    if keep:
        earlier = json.load(open(keep))
        names = {c["cell"] for c in data}
        kept = [c for c in earlier["cells"] if c["cell"] not in names]
        data = kept + data
    with open(out + ".json", "w") as f:
        doc = {"sweep": sweep, "also": [d for d, _ in also], "cells": data}
        if kept:
            doc["kept_from"] = {"file": keep, "cells": [c["cell"] for c in kept]}
        json.dump(doc, f, indent=1)
        f.write("\n")
    methods = sorted({c["method"] for c in data})
    print("| method | seeds | meta-test metric (mean +- std over seeds) | steps per cell | wall-clock per cell (s) | CPU per cell (s) |")
    print("|---|---|---|---|---|---|")
    for m in methods:
        cs = [c for c in data if c["method"] == m and c["test_metric"] is not None]
        if not cs:
            continue
        t = [c["test_metric"] for c in cs]
        sd = statistics.stdev(t) if len(t) > 1 else 0.0
        print(f"| {m} | {len(cs)} | {statistics.mean(t):.3f} +- {sd:.3f} ({', '.join(f'{x:.3f}' for x in t)}) "
              f"| {', '.join(str(c['last_step']) for c in cs)} | {', '.join(str(c['last_wall_s']) for c in cs)} "
              f"| {', '.join(str(c['last_cpu_s']) if c['last_cpu_s'] else '-' for c in cs)} |")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib missing: no plot (pip install matplotlib)", file=sys.stderr)
        return
    with_cpu = any(c["last_cpu_s"] for c in data)
    fig, axes = plt.subplots(1, 3 if with_cpu else 2, figsize=(16 if with_cpu else 11, 4))
    colours = {m: f"C{i}" for i, m in enumerate(methods)}
    labelled = set()
    for c in data:
        label = None if c["method"] in labelled else c["method"]
        labelled.add(c["method"])
        axes[0].plot(c["steps"], c["val_metric"], color=colours[c["method"]], label=label, lw=1)
        axes[1].plot(c["wall_s"], c["val_metric"], color=colours[c["method"]], lw=1)
        if with_cpu and c["last_cpu_s"]:  # runs from before charts/cpu_s have no CPU axis
            axes[2].plot(c["cpu_s"], c["val_metric"], color=colours[c["method"]], lw=1)
    axes[0].set_xlabel("update pairs (SMILe) / gradient steps (Meta-BC)")
    axes[1].set_xlabel("wall-clock (s)")
    if with_cpu:
        axes[2].set_xlabel("CPU-seconds of the training process (charts/cpu_s)")
    for a in axes:
        a.set_ylabel("held-out train-task metric")
        a.grid(alpha=0.3)
    axes[0].legend()
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out + ".svg")


if __name__ == "__main__":
    main()
