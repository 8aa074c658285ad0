#!/usr/bin/env bash
# Device run: the walker-dyn base expert (assets/experts/walker-dyn/README.md step 1) on the
# MuJoCo plant, seeds 0-5, beside the Rapier recipe's seed 0 for a same-machine speed ratio.
# Stopped at T seconds; metrics, evals and the exported policy come back (not the checkpoints).
# Carry in $DEV (an ignored folder): smile.xz (a stripped `--features mujoco` build, xz) and
# mujoco-lib.txz (.mujoco/lib from scripts/fetch-mujoco.sh, tar cJ); the tracked tree is about
# 57 MiB, so the carry must stay under 7 MiB. Usage: DEV=runs/dev2 bash docs/scripts/device-walker-base.sh 480
set -u
D=${DEV:-runs/dev2}; mkdir -p /tmp/mj && tar xJf $D/mujoco-lib.txz -C /tmp/mj
xz -dc $D/smile.xz > /tmp/smile && chmod +x /tmp/smile
export LD_LIBRARY_PATH=/tmp/mj/lib RAYON_NUM_THREADS=1
{ nproc; lscpu | grep -E "Model name|MHz"; date -u; } > $OUT/machine.txt
T=${1:-500}
R=/tmp/wb; mkdir -p $R
run() { # name physics seed
  timeout -s INT $T /tmp/smile expert --env walker-dyn --nominal --physics $2 --seed $3 \
    --hidden 128,128 --batch-size 128 --total-steps 300000 --learning-starts 5000 \
    --checkpoint-every 25000 --eval-every 25000 --keep-best --quiet -o $R/$1 > $R/$1.log 2>&1
  echo "rc=$?" >> $R/$1.log
}
for s in 0 1 2 3 4 5; do run mujoco-s$s mujoco $s & done
run rapier-s0 rapier 0 &
wait; date -u >> $OUT/machine.txt
cd $R && find . -name checkpoint.safetensors -delete; tar czf $OUT/walker-base.tgz .
for f in *.log; do echo "== $f"; tail -3 $f; done
for d in */; do echo "== $d"; tail -2 $d/metrics.jsonl | cut -c1-300; done
