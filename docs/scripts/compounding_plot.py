"""The paper's compounding-error argument in one figure: an expert and Meta-BC on cheetah-vel
under Gaussian action noise, one line style per plant; with a second panel for how far each
drifts from the expert's state distribution where the JSON has it.

    python3 docs/scripts/compounding_plot.py \
        docs/fidelity/compounding-new-plant.json:Rapier docs/fidelity/compounding-mujoco.json:MuJoCo \
        -o docs/img/compounding-plants.svg

Each JSON comes from `cargo run --release -p trainer --example compounding` (see its header);
`FILE:LABEL` names the plant in the legend. Needs matplotlib (`pip install matplotlib`).
"""
import argparse
import json

import matplotlib

matplotlib.use("svg")
import matplotlib.pyplot as plt  # noqa: E402

STYLES = ["-", "--", ":", "-."]


def main():
    p = argparse.ArgumentParser()
    p.add_argument("runs", nargs="+", help="FILE:LABEL, one per plant")
    p.add_argument("-o", "--out", required=True)
    a = p.parse_args()
    runs = []
    for spec in a.runs:
        path, _, label = spec.partition(":")
        runs.append((json.load(open(path))["rows"], label or path))
    drift = all("expert_drift" in r for rows, _ in runs for r in rows)
    fig, axes = plt.subplots(1, 2 if drift else 1, figsize=(11 if drift else 6, 4), squeeze=False)
    panels = [("", "mean |v - v*| over 1000 steps (30 test velocities)")]
    if drift:
        panels.append(("_drift", "distance to the nearest clean-expert state (standardised)"))
    for ax, (suffix, ylabel) in zip(axes[0], panels):
        for (rows, label), style in zip(runs, STYLES):
            sigma = [r["sigma"] for r in rows]
            ax.plot(sigma, [r["expert" + suffix] for r in rows], style, marker="o",
                    color="tab:green", label=f"expert, {label}")
            ax.plot(sigma, [r["policy" + suffix] for r in rows], style, marker="s",
                    color="tab:red", label=f"Meta-BC, {label}")
        ax.set_xlabel("action noise sigma (Gaussian, added before clipping)")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    if drift:
        axes[0][1].set_yscale("log")
    fig.suptitle("cheetah-vel: compounding error under action noise")
    fig.tight_layout()
    fig.savefig(a.out)


if __name__ == "__main__":
    main()
