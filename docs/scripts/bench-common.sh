# Sourced by the bench-*.sh scripts (after `set -euo pipefail`): moves to the project root,
# makes OUT_DIR (the script's first argument), names the release `smile` (SMILE, default
# target/release/smile) and the PyTorch python (PY, default the venv's), records the machine
# and its load in OUT_DIR/machine.txt, and defines `sgemm_anchor` (PyTorch's single-core sgemm
# rate, the yardstick each sitting is read against) and `ours_pair` (our SMILe pair at a
# config's recipe).
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
out=${1:?usage: $(basename "$0") OUT_DIR}
mkdir -p "$out"
py=${PY:-.venv-torch/bin/python}
smile=${SMILE:-target/release/smile}
echo "machine: $(nproc) vCPUs, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2), $(date -u +%FT%TZ), load $(cut -d' ' -f1-3 /proc/loadavg)" | tee "$out/machine.txt"

# PyTorch's sgemm on one thread at the learner's shapes, GFLOP/s, into OUT_DIR/sgemm.txt.
sgemm_anchor() {
  echo "== sgemm anchor (torch, 1 thread)"
  $py - <<'PY' | tee "$out/sgemm.txt"
import time, torch
torch.set_num_threads(1)
for m, n, k in [(2048, 512, 512), (1024, 512, 512), (1024, 256, 256)]:
    a, b = torch.randn(m, k), torch.randn(k, n)
    for _ in range(5): a @ b
    t = time.perf_counter(); r = 50
    for _ in range(r): a @ b
    s = (time.perf_counter() - t) / r
    print(f"{m}x{n}x{k}: {2*m*n*k/s/1e9:.1f} GFLOP/s")
PY
}

# Our SMILe update pair at CONFIG's recipe with DEMOS on THREADS learner threads, ITERS timed
# after one warm-up, into JSON; prints the summary line.
#   ours_pair CONFIG DEMOS THREADS ITERS JSON
ours_pair() {
  $smile bench --workload pair --config "$1" --demos "$2" \
    --iters "$4" --warmup 1 --learner-threads "$3" --json "$5" | tail -1
}
