"""The walker-dyn experts' bars from a `smile eval --base ... --expert ...` evaluation.

    python3 docs/scripts/walker-bars.py EVAL_JSON COMMAND > assets/experts/walker-dyn/eval.json

Reads the evaluation's `reference` block (the base's and each task's expert's deterministic
episodes on the 25 meta-test dynamics) and writes the shipped experts' eval.json: returns,
episode lengths and the issue's bars (expert beats base on >= 20 of 25 tasks; expert survives
>= 900 steps on >= 80% of them).
"""
import json
import statistics
import sys


def main():
    path, command = sys.argv[1], sys.argv[2]
    r = json.load(open(path))["reference"]
    er, br = r["expert_returns"], r["base_returns"]
    es, bs = r["expert_steps"], r["base_steps"]
    n = len(er)
    beats = sum(e > b for e, b in zip(er, br))
    survives = sum(s >= 900 for s in es)
    doc = {
        "what": "the shipped walker-dyn experts on the 25 meta-test dynamics: each task's own "
        "per-task expert and the base (unmodified-dynamics) policy, deterministic, 3 episodes of "
        "up to 1000 steps per task (a fall ends an episode), the episode seeds of smile eval's "
        "walker protocol",
        "command": command,
        "metric": "Return",
        "tasks": [f"dynamics_seed={int(v)}" for v in r["task_values"]],
        "expert": {
            "mean_return": round(statistics.mean(er), 1),
            "per_task_return": [round(x, 1) for x in er],
            "mean_episode_steps": round(statistics.mean(es), 1),
            "per_task_steps": [round(x, 1) for x in es],
        },
        "base": {
            "mean_return": round(statistics.mean(br), 1),
            "per_task_return": [round(x, 1) for x in br],
            "mean_episode_steps": round(statistics.mean(bs), 1),
            "per_task_steps": [round(x, 1) for x in bs],
        },
        "bars": {
            "expert_beats_base_tasks": beats,
            "expert_beats_base_bar": f">= 20 of {n}: " + ("met" if beats >= 20 else "not met"),
            "expert_survives_900_tasks": survives,
            "expert_survives_900_bar": f">= 80% of {n}: "
            + ("met" if survives >= 0.8 * n else "not met"),
        },
    }
    json.dump(doc, sys.stdout, indent=1)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
