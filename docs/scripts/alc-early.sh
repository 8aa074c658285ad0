#!/usr/bin/env bash
# Issue 70 item 3 (Rapier's ant-linclass): Meta-BC with the cloning weight on the first steps
# (docs/configs/alc-bc-early.toml) on demos that are not subsampled, 3 seeds, the table's
# evaluation (contexts of 1, 2, 4 and 8 test demos, 3 draws x 5 rollouts) and the diagnosis
# (`smile linclass-diagnose`: the probes of z, where the decision is made). About 3 min a seed
# on one core of the 2-vCPU Xeon (beside a long run), 20 s its evaluation, 5 min the diagnosis.
#
#   docs/scripts/alc-early.sh [RUNS_DIR]        # default runs/alc-early
set -euo pipefail
cd "$(dirname "$0")/../.."
R=${1:-runs/alc-early}
bin=${SMILE_BIN:-target/release/smile}
E=assets/experts/ant-linclass
mkdir -p "$R"
train=$R/demos-train-16x-sub1.safetensors
# The scripted expert's demos, every step kept (seconds; the same seeds as the shipped sub-5 files).
[ -f "$train" ] || "$bin" demos --env ant-linclass --split train --per-task 16 --subsample 1 \
  --seed 0 --expert $E -o "$train"
policies=()
for s in 0 1 2; do
  run=$R/meta-bc-early-s$s
  [ -f "$run/meta_policy.safetensors" ] || nice "$bin" train --algo meta-bc --env ant-linclass \
    --demos "$train" --config docs/configs/alc-bc-early.toml --seed $s -o "$run" --quiet
  [ -f "$run/eval/eval.json" ] || nice "$bin" eval --policy "$run" --env ant-linclass --split test \
    --contexts $E/demos-test-16x-sub5.safetensors -o "$run/eval" --quiet
  policies+=(--policy "early-s$s=$run")
done
nice "$bin" linclass-diagnose --contexts $E/demos-test-16x-sub5.safetensors --train-demos "$train" \
  --rollouts-on-train "${policies[@]}" -o "$R/diagnose"
