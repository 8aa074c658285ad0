"""The paper's compounding-error argument in one figure: an expert and Meta-BC on cheetah-vel
under Gaussian action noise, on the old and the new plant.

    python3 docs/scripts/compounding_plot.py docs/fidelity/compounding-old-plant.json \
        docs/fidelity/compounding-new-plant.json -o docs/img/compounding.svg

Each JSON comes from `cargo run --release -p trainer --example compounding` (see its header).
Needs matplotlib (`pip install matplotlib`).
"""
import argparse
import json

import matplotlib

matplotlib.use("svg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    p = argparse.ArgumentParser()
    p.add_argument("old")
    p.add_argument("new")
    p.add_argument("-o", "--out", required=True)
    a = p.parse_args()
    fig, ax = plt.subplots(figsize=(6, 4))
    for path, label, style in [(a.old, "old plant", "--"), (a.new, "new plant (MuJoCo-held)", "-")]:
        rows = json.load(open(path))["rows"]
        sigma = [r["sigma"] for r in rows]
        ax.plot(sigma, [r["expert"] for r in rows], style, marker="o", color="tab:green",
                label=f"expert, {label}")
        ax.plot(sigma, [r["policy"] for r in rows], style, marker="s", color="tab:red",
                label=f"Meta-BC, {label}")
    ax.set_xlabel("action noise sigma (Gaussian, added before clipping)")
    ax.set_ylabel("mean |v - v*| over 1000 steps (30 test velocities)")
    ax.set_title("cheetah-vel: compounding error under action noise")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(a.out)


if __name__ == "__main__":
    main()
