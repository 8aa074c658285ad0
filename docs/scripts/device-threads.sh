#!/usr/bin/env bash
# The learner on more than two threads (docs/BENCHMARKS.md: "Not measured: more than two threads"): on a lent
# 16-core machine, our SMILe pair and SAC step at 1, 2, 4, 8 and 16 learner threads beside
# PyTorch doing the same work at the same thread counts, in one sitting, plus the narrow ant-goal
# pair of the long cells (docs/plans/ant-goal-mujoco-long.toml). Nothing else runs meanwhile.
#
#   SMILE=BIN [MUJOCO_LIB=DIR] docs/scripts/device-threads.sh OUT_DIR
#
# BIN: a release `smile` built with `--features mujoco` (the ant-goal pair steps MuJoCo);
# MUJOCO_LIB: the folder holding libmujoco.so.3.*; PY (default python3): one with torch. About 4 minutes on
# the device machine's 16 cores.
set -euo pipefail
: "${SMILE:?SMILE must name a release smile binary}"
PY=${PY:-python3}
source "$(dirname "$0")/bench-common.sh"
[ -n "${MUJOCO_LIB:-}" ] && export LD_LIBRARY_PATH="$MUJOCO_LIB:${LD_LIBRARY_PATH:-}"
export RAYON_NUM_THREADS=1 # candle's own matmul threads: the learner pool does the splitting
threads=(1 2 4 8 16)
{
  grep -m1 -o 'avx512[a-z]*' /proc/cpuinfo | head -1 | sed 's/^/first avx512 flag: /' || echo "no avx512"
  $py -c 'import torch; print("torch", torch.__version__)'
} | tee -a "$out/machine.txt"
sgemm_anchor
for t in "${threads[@]}"; do
  echo "== ours SMILe pair, docs/configs/authors-cv-smile.toml, learner threads $t"
  ours_pair docs/configs/authors-cv-smile.toml \
    assets/experts/cheetah-vel/demos-train-4x-sub20.safetensors "$t" 2 "$out/ours-pair-authors-t$t.json"
done
echo "== PyTorch SMILe pair doing our pair's work, threads ${threads[*]}"
$py docs/scripts/torch_smile_pair.py --threads "${threads[@]}" --iters 20 --warmup 3 | tee "$out/torch-pair.json"
for t in "${threads[@]}"; do
  echo "== ours SAC step, authors' shapes, learner threads $t"
  $smile bench --workload sac --authors --iters 30 --warmup 5 --learner-threads "$t" \
    --json "$out/ours-sac-t$t.json" | tail -1
done
echo "== PyTorch SAC step, authors' shapes, threads ${threads[*]}"
$py docs/bench/pytorch/torch_reference.py --workloads sac --hidden 256 --layers 3 --batch 1024 \
  --z-dim 64 --threads "${threads[@]}" --iters 30 --warmup 5 | tee "$out/torch-sac.json"
for t in 1 2 4 8; do
  echo "== ours SMILe pair, ant-goal MuJoCo, docs/configs/authors-ag-smile-narrow.toml, learner threads $t"
  ours_pair docs/configs/authors-ag-smile-narrow.toml \
    assets/experts/ant-goal-mujoco/demos-train-4x-sub1.safetensors "$t" 3 "$out/ours-pair-ag-t$t.json"
done
echo "done $(date -u +%T)"
