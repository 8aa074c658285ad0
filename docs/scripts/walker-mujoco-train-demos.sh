#!/usr/bin/env bash
# Records walker-dyn's MuJoCo meta-train demos (9.8 MB, over the repository's 8 MB limit for a
# tracked file) from the shipped per-task experts, and checks they are the bytes every result
# was made from: the recording is deterministic (seed 0), and the SHA-256 below is the one each
# run's run.json records (a resume refuses other demos).
#
#   docs/scripts/walker-mujoco-train-demos.sh [SMILE_BIN]     # a --features mujoco build; 2.4 min
set -euo pipefail
bin=${1:-target/release/smile}
E=assets/experts/walker-dyn-mujoco
out=$E/demos-train-32x-sub20.safetensors
want=2d517c63f7069310963059f777be9142431e91752a68bd12c5d0177cb4ca4de0
if [ ! -f "$out" ]; then
  "$bin" demos --env walker-dyn --physics mujoco --split train --per-task 32 --subsample 20 --seed 0 \
    --expert $E/per-task -o "$out"
fi
got=$(sha256sum "$out" | cut -d' ' -f1)
if [ "$got" != "$want" ]; then
  echo "$out: SHA-256 $got, expected $want (the experts or the recorder changed)" >&2
  exit 1
fi
echo "$out: SHA-256 $got, as recorded"
