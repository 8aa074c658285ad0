#!/usr/bin/env bash
# Copy the walker-dyn base and per-task experts trained by walker-experts.sh into
# assets/experts/walker-dyn/ (policies, configs, evaluations; not the 50 MB checkpoints), and
# list each expert's training budget and evaluations in per-task/index.json. Shipping a subset
# (e.g. the 25 meta-test experts trained again) replaces those entries and keeps the others.
#
#   docs/scripts/walker-ship.sh RUNS_DIR [ASSETS_DIR]
set -euo pipefail
runs=$1; assets=${2:-assets/experts/walker-dyn}
mkdir -p "$assets/base" "$assets/per-task"
cp "$runs/base/"{policy.safetensors,config.toml,eval.json} "$assets/base/"
python3 - "$runs" "$assets" <<'PY'
import json, os, shutil, sys
runs, assets = sys.argv[1], sys.argv[2]
index_path = os.path.join(assets, "per-task", "index.json")
kept = json.load(open(index_path)) if os.path.exists(index_path) else []
index = []
for name in sorted(os.listdir(runs), key=lambda n: (len(n), n)):
    d = os.path.join(runs, name)
    if not name.startswith("expert-") or not os.path.exists(os.path.join(d, "eval.json")):
        continue
    seed = int(name.split("-")[1])
    shutil.copy(os.path.join(d, "policy.safetensors"),
                os.path.join(assets, "per-task", f"dynamics-{seed}.safetensors"))
    ev = json.load(open(os.path.join(d, "eval.json")))
    evals = [json.loads(l) for l in open(os.path.join(d, "metrics.jsonl")) if "eval/metric" in l]
    cfg = open(os.path.join(d, "config.toml")).read()
    steps = next(int(l.split("=")[1]) for l in cfg.splitlines() if l.startswith("total_steps"))
    index.append({
        "dynamics_seed": seed,
        "split": "test" if seed >= 10000 else "train",
        "fine_tune_env_steps": steps,
        "periodic_evals": [[e["step"], round(e["eval/metric"], 1)] for e in evals],
        "final_return_2_episodes": round(ev["report"]["mean"], 1),
    })
shipped = {e["dynamics_seed"] for e in index}
index += [e for e in kept if e["dynamics_seed"] not in shipped]
index.sort(key=lambda e: (e["split"] != "train", e["dynamics_seed"]))
with open(index_path, "w") as f:
    json.dump(index, f, indent=1)
    f.write("\n")
print(f"{len(shipped)} per-task experts shipped, {len(index)} listed -> {assets}/per-task")
PY
