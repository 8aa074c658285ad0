#!/usr/bin/env bash
# The two plants side by side (docs/BENCHMARKS.md, "Rapier and MuJoCo side by side"): control
# steps per second per robot on each backend (criterion, sim/benches/env_steps.rs), and the
# share of a SMILe iteration spent in rollouts on each (smile bench --workload pair at the
# Table 1 recipe, docs/configs/authors-cv-smile-narrow.toml, on each plant's shipped cheetah
# demos).
#
#   scripts/fetch-mujoco.sh && docs/scripts/bench-physics.sh OUT_DIR
#
# Needs a `--features mujoco` build of smile (cargo build --release --features mujoco). Run on
# quiet cores where possible; the output names the load. About 6 minutes.
set -euo pipefail
source "$(dirname "$0")/bench-common.sh"
taskset -c 0 cargo bench -q -p sim --features mujoco --bench env_steps -- \
  --warm-up-time 1 --measurement-time 4 2>&1 | grep -E "^env_step|time:|thrpt:" | tee "$out/env_steps.txt"
for plant in cheetah-vel cheetah-vel-mujoco; do
  echo "== SMILe iterations on $plant's demos (5 rollouts + 100 pairs), one learner thread"
  taskset -c 0 $smile bench --workload pair --config docs/configs/authors-cv-smile-narrow.toml \
    --demos "assets/experts/$plant/demos-train-4x-sub20.safetensors" \
    --iters 6 --warmup 2 --json "$out/pair-$plant.json" | tail -2
done
echo "load at the end $(cut -d' ' -f1-3 /proc/loadavg), $(date -u +%T)"
