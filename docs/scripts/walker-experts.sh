#!/usr/bin/env bash
# Train walker-dyn per-task SAC experts (each fine-tuned from the base walker in OUT_DIR/base,
# trained on the unmodified dynamics), one after the other, as one "lane" of a queue that
# several lanes (one per core) share: each task is claimed with an atomic mkdir, so two lanes
# never train the same task, and a finished expert (its eval.json exists) is skipped, so the
# script can be re-run after an interruption (an unfinished run resumes from its checkpoint).
#
#   docs/scripts/walker-experts.sh BIN OUT_DIR LANE [SEEDS...]
#
# SEEDS default to the 25 meta-test then the 50 meta-train dynamics seeds; STEPS (env steps
# per expert) defaults to 50000, EVERY (env steps between evaluations and checkpoints) to
# 12500; CONFIG, if set, is an expert config file under the flags (e.g. `eval_episodes = 3`,
# so that --keep-best picks on three episodes, not one). A lane stops
# before its next task while OUT_DIR/pause-LANE exists (e.g. to free a core for a build).
# After an interruption, `rm -r OUT_DIR/claims` before starting the lanes again.
set -euo pipefail
bin=$1; out=$2; lane=$3; shift 3
seeds=("$@")
if [ ${#seeds[@]} -eq 0 ]; then
  seeds=($(seq 10000 10024) $(seq 0 49))
fi
mkdir -p "$out/claims"
for seed in "${seeds[@]}"; do
  while [ -e "$out/pause-$lane" ]; do sleep 10; done
  dir=$out/expert-$seed
  [ -e "$dir/eval.json" ] && continue
  mkdir "$out/claims/$seed" 2>/dev/null || continue
  echo "lane $lane: dynamics seed $seed ($(date +%T))"
  if [ -e "$dir/checkpoint.safetensors" ]; then
    "$bin" expert --resume "$dir" --quiet
  else
    rm -rf "$dir"
    "$bin" expert --env walker-dyn --task-value "$seed" --hidden 128,128 --batch-size 128 \
      ${CONFIG:+--config "$CONFIG"} \
      --init-from "$out/base" --total-steps "${STEPS:-50000}" --learning-starts 2000 \
      --checkpoint-every "${EVERY:-12500}" --eval-every "${EVERY:-12500}" --keep-best --quiet \
      -o "$dir"
  fi
done
echo "lane $lane: done ($(date +%T))"
