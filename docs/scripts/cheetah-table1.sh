#!/usr/bin/env bash
# cheetah-vel Table 1 at the paper's horizon (1000-step episodes), "4 demos, sub 20" setting:
# SMILe (state-action, state-only), Meta-BC (kept and stopped on held-out rollouts) and
# Meta-DAgger (relabelled by the shipped expert), from the shipped expert and demos.
#
#   docs/scripts/cheetah-table1.sh CELL...     e.g. smile-s0 bc-s0 dagger-s0 so-s0
#
# Each cell trains into runs/cv1000/<cell> (resuming from its checkpoint if one is there) and
# evaluates into runs/cv1000/eval-<cell>; a cell whose eval.json exists is skipped. Run two
# lanes at once on a 2-core machine (one cell list each). Until `smile sweep` lands this is
# the grid's runner; the numbers in docs/RESULTS.md come from it.
set -euo pipefail
cd "$(dirname "$0")/../.."
export RAYON_NUM_THREADS=1
B=${SMILE:-target/release/smile}
A=assets/experts/cheetah-vel
R=${OUT:-runs/cv1000}
TRAIN=$A/demos-train-4x-sub20.safetensors
TEST=$A/demos-test-4x-sub20.safetensors
mkdir -p "$R"
for cell in "$@"; do
  method=${cell%-s*}; seed=${cell##*-s}
  run=$R/$cell
  if [ -f "$R/eval-$cell/eval.json" ]; then echo "skip $cell (evaluated)"; continue; fi
  case $method in
    smile)  args=(--algo smile            --config docs/configs/cv1000-smile.toml) ;;
    so)     args=(--algo smile-state-only --config docs/configs/cv1000-smile.toml) ;;
    bc)     args=(--algo meta-bc          --config docs/configs/cv1000-bc-roll.toml) ;;
    dagger) args=(--algo meta-dagger      --config docs/configs/cv1000-bc-roll.toml --expert $A) ;;
    *) echo "unknown method $method" >&2; exit 2 ;;
  esac
  start=$(date +%s)
  if [ ! -f "$run/last/meta_policy.safetensors" ]; then
    if [ -f "$run/checkpoint.safetensors" ]; then
      # the run's own config, algorithm and expert (run.json) are reused
      $B train --resume --env cheetah-vel --demos $TRAIN -o "$run" --quiet
    else
      $B train "${args[@]}" --env cheetah-vel --demos $TRAIN --seed "$seed" -o "$run" --quiet
    fi
  fi
  mid=$(date +%s)
  $B eval --policy "$run" --env cheetah-vel --split test --contexts $TEST --horizon 1000 \
    -o "$R/eval-$cell" > /dev/null
  end=$(date +%s)
  echo "$cell: train $((mid - start)) s, eval $((end - mid)) s" | tee -a "$R/times.txt"
done
