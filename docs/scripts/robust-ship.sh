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
# SMILE_BIN: the `smile` to use (a --features mujoco build for MuJoCo rows).
set -euo pipefail
cd "$(dirname "$0")/../.."
run=${1:?RUN_DIR}; from=assets/policies/${2:?FROM}; suffix=${3:+-$3}
dst=assets/policies/$2-robust$suffix
bin=${SMILE_BIN:-target/release/smile}
[ -f "$run/meta_policy.safetensors" ] || { echo "robust-ship.sh: no finished run in $run" >&2; exit 2; }
[ -f "$from/deploy.toml" ] || { echo "robust-ship.sh: $from has no deploy.toml" >&2; exit 2; }
key() { sed -n "s/^$1 = \"\{0,1\}\([^\"]*\)\"\{0,1\}$/\1/p" "$from/deploy.toml"; }
demos=$from/$(key demos); contexts=$from/$(key contexts); qat=$(key qat_steps)
env=$(sed -n 's/^env = "\(.*\)"$/\1/p' "$run/config.toml")
sensing=$(python3 -c "import tomllib,sys; s=tomllib.load(open(sys.argv[1],'rb'))['sensing']; \
print(f\"noise {s.get('noise_std',0)} + {s.get('adc_bits','ideal')}-bit ADC, {s.get('fraction',1.0):g} of the batch rows\")" "$run/config.toml")
mkdir -p "$dst"
cp "$run"/{meta_policy.safetensors,config.toml,run.json} "$dst"/
"$bin" eval --policy "$dst" --env "$env" --split test --contexts "$contexts" -o "$dst/eval" --quiet
mv "$dst/eval/eval.json" "$dst/eval.json"; rm -rf "$dst/eval"
"$bin" export --policy "$dst" --demos "$demos" --contexts "$contexts" -o "$dst/policy.blob" \
  ${qat:+--qat-steps "$qat"}
method=$(key method)
{
  echo "# What \`smile device-table\` reads (docs/DEVICE.md): $2 retrained through the sensors"
  echo "# (docs/scripts/robust-ship.sh; its config.toml's [sensing])."
  echo "method = \"$method, trained through the sensors ($sensing)\""
  echo "demos = \"$(key demos)\""
  echo "contexts = \"$(key contexts)\""
  echo "horizon = $(key horizon)"
  [ -z "$qat" ] || echo "qat_steps = $qat"
} > "$dst/deploy.toml"
git add "$dst"
docs/scripts/shipped-sums.sh
git add "$dst/SHA256SUMS"
echo "shipped $dst"
