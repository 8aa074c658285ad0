#!/usr/bin/env bash
# Blob fidelity on the 12 point-goal policies of docs/plans/point-goal-3seeds.toml: exports
# each run's kept policy with `smile export` and prints, per policy, the metric of the blob vs
# the float policy, z and action differences (end to end, and with the float z), and the
# blob size; then per method the mean over seeds and the worst seed. docs/RESULTS.md, "Export".
#   smile sweep docs/plans/point-goal-3seeds.toml --jobs 2     # the runs (once)
#   docs/scripts/blob-fidelity.sh w8a8 [RUNS] [OUT]
set -euo pipefail
Q=${1:-w8a8}
RUNS=${2:-runs/point-goal-3seeds}
OUT=${3:-runs/blob-fidelity-$Q}
B=${SMILE:-target/release/smile}
P=assets/experts/point-goal
mkdir -p "$OUT"
for m in smile smile-state-only meta-bc meta-dagger; do
  for s in 0 1 2; do
    "$B" export --policy "$RUNS/$m-s$s/train" --quant "$Q" \
      --demos $P/demos-train-4x-sub20.safetensors --contexts $P/demos-test-4x-sub20.safetensors \
      -o "$OUT/$m-s$s.blob" > /dev/null 2> "$OUT/$m-s$s.log" || { cat "$OUT/$m-s$s.log"; exit 1; }
  done
done
python3 - "$OUT" <<'PY'
import json, sys
out = sys.argv[1]
print("| policy | seed | bytes | metric blob vs float | z max diff | action mean diff (with float z) | action max diff |")
print("|---|---|---|---|---|---|---|")
summary = []
for m in ["smile", "smile-state-only", "meta-bc", "meta-dagger"]:
    fl, bl, rel = [], [], []
    for s in range(3):
        j = json.load(open(f"{out}/{m}-s{s}.blob.json"))
        p = j["parity"]
        fl.append(j["metric_candle"]); bl.append(j["metric_blob"]); rel.append(100 * j["metric_relative_difference"])
        print(f"| {m} | {s} | {j['bytes']} | {rel[-1]:+.2f}% | {p['z_max_abs_diff']:.4f} | "
              f"{p['action_mean_abs_diff']:.4f} ({p.get('action_mean_abs_diff_same_z', 0):.4f}) | {p['action_max_abs_diff']:.3f} |")
    summary.append((m, sum(bl) / 3, sum(fl) / 3, max(rel, key=abs)))
print()
print("| policy | mean over seeds, blob vs float | worst seed |")
print("|---|---|---|")
for m, b, f, w in summary:
    print(f"| {m} | {b:.4f} vs {f:.4f} ({100 * (b / f - 1):+.2f}%) | {w:+.2f}% |")
PY
