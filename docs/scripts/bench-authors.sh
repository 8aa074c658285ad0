#!/usr/bin/env bash
# The learner at the SMILe authors' shapes beside PyTorch, in one sitting (docs/BENCHMARKS.md,
# "The authors' shapes"): the single-core sgemm anchor, SAC and discriminator steps on 1 and 2
# threads each side, whole SMILe pairs of the authors' cheetah recipe on 1 and 2 learner
# threads beside PyTorch doing the same pair (docs/scripts/torch_smile_pair.py), and the
# narrow-width pair against the PyTorch prototype.
#
#   [ROUNDS=2] docs/scripts/bench-authors.sh OUT_DIR   (ROUNDS: rounds of the steps and of PyTorch's pair)
#
# Run on quiet cores (pause other work first: kill -STOP PID ... kill -CONT PID). Needs a
# release build (cargo build --release -p smile-app) and the PyTorch venv (.venv-torch, see
# docs/bench/pytorch/torch_reference.py). Takes about 17 minutes on a 2-vCPU machine.
set -euo pipefail
source "$(dirname "$0")/bench-common.sh"
sgemm_anchor
for round in $(seq 1 "${ROUNDS:-2}"); do
  for t in 1 2; do
    echo "== ours sac+disc, authors' shapes, learner threads $t (round $round)"
    $smile bench --workload sac disc --authors --iters 40 --warmup 5 --learner-threads "$t" \
      --json "$out/ours-steps-t$t-r$round.json" | grep -v '^ *hidden'
  done
  echo "== PyTorch sac, authors' shapes, threads 1 2 (round $round)"
  $py docs/bench/pytorch/torch_reference.py --workloads sac --hidden 256 --layers 3 --batch 1024 \
    --z-dim 64 --threads 1 2 --iters 40 --warmup 5 | tee "$out/torch-sac-r$round.json"
  echo "== PyTorch disc, authors' shapes, threads 1 2 (round $round)"
  $py docs/bench/pytorch/torch_reference.py --workloads disc --hidden 512 --layers 3 --enc-hidden 256 \
    --r-dim 64 --z-dim 64 --threads 1 2 --iters 40 --warmup 5 | tee "$out/torch-disc-r$round.json"
done
for t in 1 2 1 2; do
  echo "== ours SMILe pairs, docs/configs/authors-cv-smile.toml, learner threads $t"
  /usr/bin/time -f "cpu %P wall %e s" $smile bench --workload pair \
    --config docs/configs/authors-cv-smile.toml \
    --demos assets/experts/cheetah-vel/demos-train-4x-sub20.safetensors \
    --iters 3 --warmup 1 --learner-threads "$t" --json "$out/ours-pair-authors-t$t.json" 2>&1 | tail -2
done
for round in $(seq 1 "${ROUNDS:-2}"); do
  echo "== PyTorch SMILe pair doing our pair's work (docs/scripts/torch_smile_pair.py), threads 1 2 (round $round)"
  $py docs/scripts/torch_smile_pair.py --threads 1 2 --iters 40 --warmup 5 | tee "$out/torch-pair-r$round.json"
done
for t in 1 2; do
  echo "== ours SMILe pairs, prototype layout H=128, learner threads $t"
  $smile bench --workload pair --hidden 128 --iters 10 --learner-threads "$t" \
    --json "$out/ours-pair-h128-t$t.json" | tail -1
done
echo "== PyTorch prototype H=128, 1 thread"
$py docs/bench/pytorch/smile_proto.py --method smile --updates 2000 --eval_every 2000 --gp 1 \
  --rscale 8 --sac_bs 32 --out "$out/proto-h128.json" | tail -1
echo "done $(date -u +%T)"
