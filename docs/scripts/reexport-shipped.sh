#!/usr/bin/env bash
# Re-exports every shipped Rapier meta-policy's device blob (assets/policies/*-rapier-*/ and
# point-goal's policy.blob and its report; the MuJoCo ones need a `--features mujoco` build and
# their folders' commands in assets/policies/README.md) with the current `smile export`
# defaults: format v3, w8a8 with its first and last layers in w8a32. The weights are not touched. Run from the repository root after a release
# build; about 10 minutes on one core of a 2-vCPU Intel Xeon (the cheetah's two are most of it).
#   docs/scripts/reexport-shipped.sh [target/release/smile]
set -euo pipefail
B=${1:-target/release/smile}
P=assets/policies
export RAYON_NUM_THREADS=${RAYON_NUM_THREADS:-1}
ship() { # folder calibration-demos contexts [extra export flags]
  local d=$P/$1 demos=$2 contexts=$3; shift 3
  "$B" export --policy "$d" --quant w8a8 --demos "$demos" --contexts "$contexts" "$@" -o "$d/policy.blob"
}
E=assets/experts/cheetah-vel
for m in smile-bc meta-bc; do
  ship cheetah-vel-rapier-$m $E/demos-train-4x-sub20.safetensors $E/demos-test-4x-sub20.safetensors --horizon 1000
done
A=assets/experts/ant-goal
for m in smile-bc meta-bc meta-bc-long; do
  ship ant-goal-rapier-$m $A/demos-train-4x-sub1.safetensors $A/demos-test-4x-sub1.safetensors --rollouts 1
done
W=assets/experts/walker-dyn
for m in meta-bc smile-bc; do
  [ -d $P/walker-dyn-rapier-$m ] || continue
  ship walker-dyn-rapier-$m $W/demos-train-32x-sub20.safetensors $W/demos-test-4x-sub20.safetensors --rollouts 1
done
L=assets/experts/ant-linclass
for m in meta-bc smile-bc; do
  [ -d $P/ant-linclass-rapier-$m ] || continue
  ship ant-linclass-rapier-$m $L/demos-train-16x-sub5.safetensors $L/demos-test-16x-sub5.safetensors --rollouts 1
done
for m in smile meta-bc; do
  ship point-goal-rapier-$m $P/point-goal-demos-train.safetensors $P/point-goal-demos-test.safetensors
done
