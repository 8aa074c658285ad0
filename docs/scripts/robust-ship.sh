#!/usr/bin/env bash
# Issue 73: ship a policy trained through the device's senses beside the row it was retrained
# from, as assets/policies/<FROM>-robust[-SUFFIX]/: its weights, config and run record, its
# evaluation on the test tasks (the row's protocol: `smile eval`'s family defaults), its w8a8 blob
# exported as the row's (the same calibration demos and contexts, the same `qat_steps`), a
# deploy.toml naming the method and the sensing it trained through, and SHA256SUMS. Then
# `smile device-table` measures both folders side by side.
#
#   docs/scripts/robust-ship.sh RUN_DIR FROM [SUFFIX]
#   e.g. docs/scripts/robust-ship.sh ~/runs/robust/cheetah-vel-rapier-smile-bc-robust cheetah-vel-rapier-smile-bc
#
# DEST=<folder name> ships under that name instead, and a run without [sensing] is labelled
# with NOTE (e.g. the ants' narrow actors: DEST=ant-goal-rapier-smile-bc-actor128 NOTE="actor 2 x 128").
#
# SMILE_BIN: the `smile` to use (a --features mujoco build for MuJoCo rows).
set -euo pipefail
cd "$(dirname "$0")/../.."
run=${1:?RUN_DIR}; from=assets/policies/${2:?FROM}; suffix=${3:+-$3}
dst=assets/policies/${DEST:-$2-robust$suffix}
bin=${SMILE_BIN:-target/release/smile}
[ -f "$run/meta_policy.safetensors" ] || { echo "robust-ship.sh: no finished run in $run" >&2; exit 2; }
[ -f "$from/deploy.toml" ] || { echo "robust-ship.sh: $from has no deploy.toml" >&2; exit 2; }
key() { sed -n "s/^$1 = \"\{0,1\}\([^\"]*\)\"\{0,1\}$/\1/p" "$from/deploy.toml"; }
demos=$from/$(key demos); contexts=$from/$(key contexts); qat=$(key qat_steps); adc=$(key adc_range)
env=$(sed -n 's/^env = "\(.*\)"$/\1/p' "$run/config.toml")
sensing=$(python3 - "$run/config.toml" <<'PY'
import sys, tomllib
s = tomllib.load(open(sys.argv[1], "rb")).get("sensing")
if not s:
    print("")
else:
    adc = f" + {s['adc_bits']}-bit ADC" if s.get("adc_bits") else ""
    noise = f"noise {s.get('noise_std', 0)}{adc}"
    share = f"{s.get('fraction', 1.0):g} of the batch rows"
    if s.get("positions"):
        print(f"trained through position-only sensing and the estimator ({noise}, {share})")
    else:
        print(f"trained through the sensors ({noise}, {share})")
PY
)
label=${sensing:-${NOTE:?a run without [sensing] needs NOTE, its label}}
mkdir -p "$dst"
cp "$run"/{meta_policy.safetensors,config.toml,run.json} "$dst"/
"$bin" eval --policy "$dst" --env "$env" --split test --contexts "$contexts" -o "$dst/eval" --quiet
mv "$dst/eval/eval.json" "$dst/eval.json"; rm -rf "$dst/eval"
"$bin" export --policy "$dst" --demos "$demos" --contexts "$contexts" -o "$dst/policy.blob" \
  ${qat:+--qat-steps "$qat"}
method=$(key method)
{
  echo "# What \`smile device-table\` reads (docs/DEVICE.md): $2 retrained (docs/scripts/robust-ship.sh)."
  echo "method = \"$method, $label\""
  echo "demos = \"$(key demos)\""
  echo "contexts = \"$(key contexts)\""
  [ -z "$(key horizon)" ] || echo "horizon = $(key horizon)"
  [ -z "$qat" ] || echo "qat_steps = $qat"
  [ -z "$adc" ] || echo "adc_range = $adc"
} > "$dst/deploy.toml"
git add "$dst"
docs/scripts/shipped-sums.sh
git add "$dst/SHA256SUMS"
echo "shipped $dst"
