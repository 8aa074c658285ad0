#!/usr/bin/env bash
# The recorded "same seed, same results" check of a restructuring (issue 47, deliverable 7):
# trains every learner briefly with a fixed seed and prints the SHA-256 of what it wrote (the
# kept and last policies, the checkpoint) and its held-out validation curve. Run it with the
# binary before and after a change; the two outputs must be identical.
#   docs/scripts/same-results.sh target/release/smile /tmp/same-before > before.txt
# Takes about 2 minutes on two cores. Everything runs candle single-threaded (`--threads 1`);
# the last two runs use two learner threads.
set -euo pipefail
bin=${1:?usage: same-results.sh SMILE_BINARY OUT_DIR}
out=${2:?usage: same-results.sh SMILE_BINARY OUT_DIR}
rm -rf "$out" && mkdir -p "$out"
cv=assets/experts/cheetah-vel
demos=$cv/demos-train-4x-sub20.safetensors
q=(--quiet --threads 1)

digest() { # run dir -> one line per file, then the validation curve
  local d=$1 name=${1#"$out"/}
  for f in meta_policy.safetensors last/meta_policy.safetensors checkpoint.safetensors policy.safetensors; do
    [[ -f $d/$f ]] && echo "$name $f $(sha256sum < "$d/$f" | cut -c1-16)"
  done
  # the held-out curve: every eval/ field of metrics.jsonl (timings left out)
  echo "$name eval $(grep -o '"eval/[a-z_]*":[^,}]*' "$d/metrics.jsonl" | sha256sum | cut -c1-16)"
}

# SAC (the experts' learner) on point-goal.
"$bin" expert --env point-goal --total-steps 1500 --learning-starts 500 --eval-every 750 \
  --eval-episodes 2 --seed 3 -o "$out/expert" "${q[@]}" > /dev/null
digest "$out/expert"

# The meta-learners on the shipped Rapier cheetah-vel demos.
smile_args=(--config docs/configs/authors-cv-smile-narrow.toml --updates 300 --eval-every 150 --seed 5)
"$bin" train --algo smile --demos $demos -o "$out/smile" "${smile_args[@]}" "${q[@]}" > /dev/null
digest "$out/smile"
"$bin" train --algo smile-state-only --demos $demos -o "$out/smile-state-only" "${smile_args[@]}" "${q[@]}" > /dev/null
digest "$out/smile-state-only"
"$bin" train --algo smile --bc-weight 100 --demos $demos -o "$out/smile-bc" "${smile_args[@]}" "${q[@]}" > /dev/null
digest "$out/smile-bc"
bc_args=(--config docs/configs/cv1000-bc.toml --updates 400 --eval-every 100 --seed 5)
"$bin" train --algo meta-bc --demos $demos -o "$out/meta-bc" "${bc_args[@]}" "${q[@]}" > /dev/null
digest "$out/meta-bc"
"$bin" train --algo meta-dagger --expert $cv --demos $demos -o "$out/meta-dagger" "${bc_args[@]}" "${q[@]}" > /dev/null
digest "$out/meta-dagger"

# The sweep's cell runner (train, then evaluate) on a two-cell plan, and the blob export.
cat > "$out/plan.toml" <<PLAN
env = "cheetah-vel"
out = "$out/sweep"
demos = ["$PWD/$demos"]
seeds = [0]
[algo.meta-bc]
config = "$PWD/docs/configs/cv1000-bc.toml"
set = { total_steps = 200, eval_every = 100 }
[algo.smile]
config = "$PWD/docs/configs/authors-cv-smile-narrow.toml"
set = { total_updates = 200, eval_every = 100 }
[eval]
contexts = "$PWD/$cv/demos-test-4x-sub20.safetensors"
horizon = 100
context_sizes = [1]
rollouts = 1
PLAN
"$bin" sweep "$out/plan.toml" --jobs 1 --quiet > /dev/null
for c in meta-bc-s0 smile-s0; do
  digest "$out/sweep/$c/train"
  echo "$c eval.json $(grep -o '"metric": [-0-9.e]*' "$out/sweep/$c/eval/eval.json" | sha256sum | cut -c1-16)"
done
"$bin" export --policy "$out/meta-bc" --quant w8a8 --demos $demos --contexts $cv/demos-test-4x-sub20.safetensors \
  --rollouts 1 --horizon 100 -o "$out/meta-bc.blob" > /dev/null
echo "export meta-bc.blob $(sha256sum < "$out/meta-bc.blob" | cut -c1-16)"

# SMILe and SMILe + BC on two learner threads: the overlapped pair and the rollouts beside it
# (added 2026-12-05 with SMILe in one file; the lines above are those of the older records).
for bc in 0 100; do
  "$bin" train --algo smile --bc-weight $bc --learner-threads 2 --demos $demos -o "$out/smile-lt2-bc$bc" \
    --config docs/configs/authors-cv-smile-narrow.toml --updates 200 --eval-every 100 --seed 5 "${q[@]}" > /dev/null
  digest "$out/smile-lt2-bc$bc"
done
