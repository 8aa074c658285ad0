#!/usr/bin/env bash
# Issue 70, item 1: MuJoCo's walker-dyn run long, seed 0, the table's recipe
# (docs/plans/walker-dyn-mujoco.toml's cells without their 1800 CPU-s budget), to 1M update
# pairs in stages (100k, 250k, 500k, 1M). At each milestone the run's weights are copied out
# (last and best-held-out) and evaluated on the 25 test dynamics under both protocols (falls end;
# the authors' 1000 steps through falls). Resumable: a killed stage resumes from its last
# checkpoint (every 20k pairs); a finished milestone is skipped.
#
#   docs/scripts/walker-long.sh smile|smile-bc|meta-bc [RUNS_DIR]   # RUNS_DIR default ~/runs
#
# meta-bc: Meta-BC without its early stop (docs/configs/wd-bc-long.toml), its milestones in
# gradient steps.
#
# Run directories live outside the work tree (the tree may be laid anew while the machine is
# kept); docs/scripts/walker-mujoco-train-demos.sh records the demos first. A --features mujoco
# build of `smile` (target/release/smile, or SMILE_BIN: a copy outside target/, so that a
# workspace build without the feature cannot replace it mid-run). One cell per core, niced.
set -euo pipefail
cd "$(dirname "$0")/../.."
cell=${1:?smile, smile-bc or meta-bc}
runs=${2:-$HOME/runs}/walker-dyn-mujoco-long
bin=${SMILE_BIN:-target/release/smile}
E=$PWD/assets/experts/walker-dyn-mujoco
demos=$E/demos-train-32x-sub20.safetensors
config=$PWD/docs/configs/authors-wd-smile-narrow.toml
algo=smile
case "$cell" in
  smile) extra=(--cpu-budget 0) ;;
  smile-bc) extra=(--cpu-budget 0 --bc-weight 100) ;;
  meta-bc) algo=meta-bc; config=$PWD/docs/configs/wd-bc-long.toml; extra=() ;;
  *) echo "walker-long.sh: unknown cell '$cell' (smile, smile-bc or meta-bc)" >&2; exit 2 ;;
esac
run=$runs/$cell-s0
mkdir -p "$runs"
for m in 100000 250000 500000 1000000; do
  stage=$runs/$cell-s0-at-$m
  if [ -f "$stage/eval-authors/eval.json" ]; then continue; fi
  if [ -f "$run/checkpoint.safetensors" ]; then
    nice "$bin" train -o "$run" --demos "$demos" --resume --updates "$m" --quiet
  else
    nice "$bin" train --algo "$algo" --config "$config" --demos "$demos" -o "$run" --seed 0 \
      --updates "$m" "${extra[@]}" --quiet
  fi
  mkdir -p "$stage"
  cp "$run"/meta_policy.safetensors "$run"/metrics.jsonl "$run"/config.toml "$run"/run.json "$stage"/
  for protocol in falls-end authors; do
    nice "$bin" eval --policy "$run" --env walker-dyn --split test \
      --contexts "$E/demos-test-4x-sub20.safetensors" --base "$E/base" --expert "$E/per-task" \
      --walker-protocol "$protocol" -o "$stage/eval-$protocol" --quiet
  done
done
