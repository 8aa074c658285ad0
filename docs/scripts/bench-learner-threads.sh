#!/usr/bin/env bash
# SMILe update pairs, one vs two learner threads, beside the PyTorch prototype, in one sitting
# (docs/BENCHMARKS.md "Threads"). Run on quiet cores: pause other work first (kill -STOP PID,
# then kill -CONT PID). Needs a release build and the PyTorch venv (.venv-torch).
set -euo pipefail
cd "$(dirname "$0")/../.."
for H in 128 256; do
  for lt in 1 2 1 2; do
    echo "== ours H=$H learner threads $lt"
    /usr/bin/time -f "cpu %P" target/release/smile bench --workload pair --hidden "$H" --iters 10 --learner-threads "$lt" 2>&1 | tail -2
  done
done
echo "== PyTorch H=128"
.venv-torch/bin/python docs/bench/pytorch/smile_proto.py --method smile --updates 2000 --eval_every 2000 --gp 1 --rscale 8 --sac_bs 32 | tail -1
echo "== PyTorch H=256"
.venv-torch/bin/python docs/bench/pytorch/smile_proto.py --method smile --updates 1000 --eval_every 1000 --gp 1 --rscale 8 --sac_bs 32 --h 256 --disc_h 256 | tail -1
