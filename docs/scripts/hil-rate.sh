#!/usr/bin/env bash
# The highest control rate the hardware-in-the-loop link holds (issue 55): a cheetah-vel w8a8
# blob on `firmware-sim device --pty`, driven by `firmware-sim host` for one whole episode
# (1000 ticks), the plant run faster than real time (--speedup) so that the tick rate can pass
# the plant's own 20 Hz. Prints, per baud rate and tick rate: deadline misses, late starts and
# the round trip (median, p99, max). Usage:
#   docs/scripts/hil-rate.sh BLOB CONTEXTS OUT [BAUD...]
# e.g. docs/scripts/hil-rate.sh assets/policies/cheetah-vel-rapier-smile-bc/policy.blob \
#        assets/experts/cheetah-vel/demos-test-4x-sub20.safetensors runs/hil-rate 115200 0
set -euo pipefail
blob=$1 contexts=$2 out=$3
shift 3
bauds=${*:-115200 0}
fw=${FIRMWARE_SIM:-target/release/firmware-sim}
mkdir -p "$out"
printf '| baud | tick rate (Hz) | ticks | deadline misses | late starts | round trip median / p99 / max (us) |\n|---|---|---|---|---|---|\n'
for baud in $bauds; do
  if [ "$baud" = 0 ]; then speedups="25 50 100 200"; else speedups="2.5 4 4.25 4.5 5"; fi
  for x in $speedups; do
    link="$out/tty-$baud-$x"
    "$fw" device --pty "$link" --baud "$baud" > /dev/null 2> "$out/device-$baud-$x.log" &
    dev=$!
    for _ in $(seq 50); do [ -e "$link" ] && break; sleep 0.1; done
    timeout 300 "$fw" host --port "$link" --baud "$baud" --speedup "$x" --blob "$blob" \
      --env cheetah-vel --task 3 --context "$contexts" -o "$out/host-$baud-$x" > /dev/null 2>&1 || true
    kill "$dev" 2> /dev/null || true
    wait "$dev" 2> /dev/null || true
    python3 - "$out/host-$baud-$x/hil.json" "$baud" <<'PY'
import json, sys
h = json.load(open(sys.argv[1]))
r = h["round_trip_us"]
rate = h["rate_hz"] * h["speedup"]
print(f"| {sys.argv[2]} | {rate:g} | {h['ticks']} | {h['deadline_misses']} | {h['late_starts']} | "
      f"{r['median']:.0f} / {r['p99']:.0f} / {r['max']:.0f} |")
PY
  done
done
