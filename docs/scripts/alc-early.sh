#!/usr/bin/env bash
# Issue 70 item 3 (Rapier's ant-linclass): Meta-BC with the cloning weight on the first steps
# (docs/configs/alc-bc-early.toml) on demos that are not subsampled, 3 seeds, the table's
# evaluation (contexts of 1, 2, 4 and 8 test demos, 3 draws x 5 rollouts) and the diagnosis
# (`smile linclass-diagnose`: the probes of z, where the decision is made). About 3 min a seed
# on one core of the 2-vCPU Xeon (beside a long run), 20 s its evaluation, 5 min the diagnosis.
# PER_TASK train demos per hyperplane: 16 as the paper (and the shipped files), 64 or 256 for
# the larger sets whose clones reach the targets more often; STARTS `distinct` records every
# task's demos from reset seeds no other task uses (`smile demos --distinct-starts`), `shared`
# (the shipped files) the same seeds in every task (docs/RESULTS.md).
#
#   docs/scripts/alc-early.sh [RUNS_DIR] [PER_TASK] [STARTS]   # default runs/alc-early 16 shared
#
# EXPERT=<dir> records the train demos with another scripted classifier (a `smile expert --kind
# scripted-linclass` run directory; default the shipped one); the test contexts stay the shipped
# file's, so that only the train demos change. CONTEXTS=<file> evaluates on other test contexts
# (MuJoCo: assets/experts/ant-linclass-mujoco/demos-test-16x-sub5.safetensors, with a MuJoCo
# expert and SMILE_BIN a `--features mujoco` build).
#
# Each RUNS_DIR holds one kind of train demos: finished runs in it are reused, so another
# PER_TASK or STARTS needs another RUNS_DIR (refused otherwise).
set -euo pipefail
cd "$(dirname "$0")/../.."
R=${1:-runs/alc-early}
n=${2:-16}
starts=${3:-shared}
case $starts in
  shared) flag=() suffix= ;;
  distinct) flag=(--distinct-starts) suffix=-distinct ;;
  *) echo "STARTS is shared or distinct, not $starts" >&2; exit 2 ;;
esac
bin=${SMILE_BIN:-target/release/smile}
E=assets/experts/ant-linclass
expert=${EXPERT:-$E}
contexts=${CONTEXTS:-$E/demos-test-16x-sub5.safetensors}
mkdir -p "$R"
train=$R/demos-train-${n}x-sub1$suffix.safetensors
for other in "$R"/demos-train-*.safetensors; do
  if [ -e "$other" ] && [ "$other" != "$train" ]; then
    echo "$R holds runs on $other; give another RUNS_DIR for $n demos a task, $starts starts" >&2
    exit 2
  fi
done
# The scripted expert's demos, every step kept (seconds; shared starts: the shipped sub-5 files' seeds).
[ -f "$train" ] || "$bin" demos --env ant-linclass --split train --per-task "$n" --subsample 1 ${flag[@]+"${flag[@]}"} \
  --seed 0 --expert "$expert" -o "$train"
policies=()
for s in 0 1 2; do
  run=$R/meta-bc-early-s$s
  [ -f "$run/meta_policy.safetensors" ] || nice "$bin" train --algo meta-bc --env ant-linclass \
    --demos "$train" --config docs/configs/alc-bc-early.toml --seed $s -o "$run" --quiet
  [ -f "$run/eval/eval.json" ] || nice "$bin" eval --policy "$run" --env ant-linclass --split test \
    --contexts "$contexts" -o "$run/eval" --quiet
  policies+=(--policy "early-s$s=$run")
done
nice "$bin" linclass-diagnose --contexts "$contexts" --train-demos "$train" \
  --rollouts-on-train "${policies[@]}" -o "$R/diagnose"
