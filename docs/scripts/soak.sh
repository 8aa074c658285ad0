#!/usr/bin/env bash
# Soak test of issue 27's cases: repeats kill -9 at random moments, two writers on one
# directory, and a full disk, and checks that no run looks finished when it is not.
#
#   cargo build --release && bash docs/scripts/soak.sh [ROUNDS]     # default 10 rounds
#
# The full-disk case mounts a 2 MiB tmpfs and needs root (skipped, saying so, otherwise).
# Exit status 0 only when every round held; each failure prints what it found.
set -uo pipefail
cd "$(dirname "$0")/../.."
S=${SMILE:-target/release/smile}
ROUNDS=${1:-10}
W=$(mktemp -d /tmp/smile-soak.XXXX)
trap 'umount "$W/full" 2>/dev/null; rm -rf "$W"' EXIT
export RAYON_NUM_THREADS=1
fail=0
bad() { echo "FAIL: $*"; fail=1; }

"$S" expert --env point-goal --kind scripted-pd -o "$W/pd" >/dev/null 2>&1 || { echo "no smile at $S"; exit 2; }
"$S" demos --env point-goal --split train --per-task 2 --subsample 5 --expert "$W/pd" -o "$W/train.safetensors" >/dev/null
"$S" demos --env point-goal --split test --per-task 1 --subsample 5 --seed 100 --expert "$W/pd" -o "$W/test.safetensors" >/dev/null
printf 'patience = 0\n' > "$W/bc.toml"

for r in $(seq 1 "$ROUNDS"); do
  run="$W/run-$r"
  algo=$([ $((r % 2)) -eq 0 ] && echo smile || echo meta-bc)
  extra=$([ "$algo" = meta-bc ] && echo "--config $W/bc.toml" || echo "")
  # shellcheck disable=SC2086
  "$S" train --algo "$algo" $extra --demos "$W/train.safetensors" -o "$run" --updates 3000 \
    --eval-every 100 --hidden 16,16 --quiet >/dev/null 2>&1 &
  pid=$!
  sleep "0.$((RANDOM % 9 + 1))"
  # A second writer while the first runs: refused, or (the first already gone) a resume.
  if kill -0 "$pid" 2>/dev/null && [ -f "$run/checkpoint.safetensors" ]; then
    out=$("$S" train --resume --demos "$W/train.safetensors" -o "$run" --quiet 2>&1)
    if kill -0 "$pid" 2>/dev/null && ! grep -q "in use by another process" <<<"$out"; then
      bad "round $r: a second writer on a running $run was not refused: $out"
    fi
  fi
  kill -9 "$pid" 2>/dev/null
  wait "$pid" 2>/dev/null
  [ -f "$run/meta_policy.safetensors" ] || continue
  out=$("$S" eval --policy "$run" --contexts "$W/test.safetensors" -o "$W/eval-$r" --rollouts 1 --quiet 2>&1)
  finished=$([ -f "$run/last/meta_policy.safetensors" ] && echo yes || echo no)
  if [ "$finished" = no ] && ! grep -q "unfinished run" <<<"$out"; then
    bad "round $r: eval accepted the policy of a killed $algo run: $out"
  fi
  ls -a "$run" | grep -q '\.tmp$' && bad "round $r: temporary files left in $run: $(ls -a "$run")"
done

# Full disk: a demo file rewritten onto a full file system keeps its old contents.
if [ "$(id -u)" = 0 ] && mkdir -p "$W/full" && mount -t tmpfs -o size=2m tmpfs "$W/full" 2>/dev/null; then
  "$S" demos --env point-goal --split train --per-task 1 --subsample 20 --expert "$W/pd" -o "$W/full/d.safetensors" >/dev/null
  before=$(sha256sum "$W/full/d.safetensors" | cut -d' ' -f1)
  if "$S" demos --env point-goal --split train --per-task 64 --expert "$W/pd" -o "$W/full/d.safetensors" >/dev/null 2>&1; then
    bad "full disk: a 64-demo file fitted into 2 MiB?"
  fi
  after=$(sha256sum "$W/full/d.safetensors" | cut -d' ' -f1)
  [ "$before" = "$after" ] || bad "full disk: the old demo file changed"
  ls -a "$W/full" | grep -q 'tmp' && bad "full disk: a temporary file was left: $(ls -a "$W/full")"
else
  echo "full-disk case skipped (needs root to mount a tmpfs)"
fi

[ "$fail" = 0 ] && echo "soak: $ROUNDS rounds held" || echo "soak: failures above"
exit "$fail"
