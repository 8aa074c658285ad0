# Sourced by the bench-*.sh scripts (after `set -euo pipefail`): moves to the project root,
# makes OUT_DIR (the script's first argument), names the release `smile` and the PyTorch venv's
# python, and records the machine and its load in OUT_DIR/machine.txt.
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
out=${1:?usage: $(basename "$0") OUT_DIR}
mkdir -p "$out"
py=.venv-torch/bin/python
smile=target/release/smile
echo "machine: $(nproc) vCPUs, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2), $(date -u +%FT%TZ), load $(cut -d' ' -f1-3 /proc/loadavg)" | tee "$out/machine.txt"
