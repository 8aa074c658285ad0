#!/usr/bin/env bash
# A whole SMILe update pair at the authors' cheetah recipe, ours beside PyTorch doing the same
# work (docs/scripts/torch_smile_pair.py: the SAC batch's reward through the discriminator, the
# recipe's contexts of whole demos, per-step sampling), on 1 and 2 threads, two rounds, in one
# sitting (docs/BENCHMARKS.md, "The whole pair against PyTorch's whole pair").
#
#   docs/scripts/bench-pair.sh OUT_DIR
#
# Run on quiet cores (pause other work first: kill -STOP PID ... kill -CONT PID). Needs a
# release build (cargo build --release -p smile-app) and the PyTorch venv (.venv-torch, see
# docs/bench/pytorch/torch_reference.py). Takes about 12 minutes on a 2-vCPU machine.
set -euo pipefail
source "$(dirname "$0")/bench-common.sh"
for round in 1 2; do
  for t in 1 2; do
    echo "== ours SMILe pairs, docs/configs/authors-cv-smile.toml, learner threads $t (round $round)"
    ours_pair docs/configs/authors-cv-smile.toml \
      assets/experts/cheetah-vel/demos-train-4x-sub20.safetensors "$t" 3 "$out/ours-pair-t$t-r$round.json"
  done
  echo "== PyTorch SMILe pair, the same recipe, threads 1 2 (round $round)"
  $py docs/scripts/torch_smile_pair.py --threads 1 2 --iters 40 --warmup 5 | tee "$out/torch-pair-r$round.json"
done
echo "done $(date -u +%T)"
