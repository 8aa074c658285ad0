#!/usr/bin/env bash
# Issue 32, deliverable 4: the authors' cheetah recipe at their widths against the same recipe
# at narrow widths, at equal compute: every cell trains for BUDGET CPU-seconds (`--cpu-budget`,
# one learner thread), then is evaluated on the 30 meta-test velocities (contexts of 1-4 demos,
# 3 draws x 5 deterministic 1000-step rollouts). Two queues, one per core, niced; the CPU budget
# keeps the comparison fair beside other work on the machine.
#   docs/scripts/cv-width.sh [OUT=runs/cv-width] [BUDGET=1800] [SEEDS="0 1"]
set -euo pipefail
OUT=${1:-runs/cv-width}
BUDGET=${2:-1800}
SEEDS=${3:-"0 1"}
SMILE=${SMILE:-target/release/smile}
E=assets/experts/cheetah-vel
cell() { # name config seed
  local d=$OUT/$1-s$3
  if [ ! -f "$d/train/meta_policy.safetensors" ] || [ ! -f "$d/train/last/meta_policy.safetensors" ]; then
    nice -n 10 "$SMILE" train --config "$2" --demos $E/demos-train-4x-sub20.safetensors \
      --seed "$3" --cpu-budget "$BUDGET" -o "$d/train" --quiet 2> "$d.train.log"
  fi
  nice -n 10 "$SMILE" eval --policy "$d/train" --env cheetah-vel --split test \
    --contexts $E/demos-test-4x-sub20.safetensors --horizon 1000 -o "$d/eval" 2> "$d.eval.log"
}
mkdir -p "$OUT"
for s in $SEEDS; do cell wide docs/configs/authors-cv-smile.toml "$s"; done &
for s in $SEEDS; do cell narrow docs/configs/authors-cv-smile-narrow.toml "$s"; done &
wait
python3 docs/scripts/learning_curves.py "$OUT" docs/img/cheetah-vel-width-curves \
  "cheetah-vel, authors' recipe: 3 x 512 / 3 x 256 against 2 x 128, ${BUDGET} CPU-s per cell"
