#!/usr/bin/env bash
# Keeps what a sweep's tables and curves are made from, without its checkpoints: the manifest
# and, per cell, its config, evaluation and training metrics thinned to the evaluations and 200
# other lines (docs/scripts/thin_metrics.py; a few KB a cell, where the run directory holds
# tens of MB). `smile report` and docs/scripts/learning_curves.py read the
# copy as they read the sweep, so a table can be made again after runs/ is gone.
#
#   docs/scripts/archive-sweep.sh runs/SWEEP [DEST]      # DEST defaults to docs/results/SWEEP
#   smile report docs/results/SWEEP -o /tmp/report
#   python3 docs/scripts/learning_curves.py docs/results/SWEEP /tmp/curves
set -euo pipefail
src=${1:?usage: archive-sweep.sh SWEEP_DIR [DEST]}
src=${src%/}
dest=${2:-docs/results/$(basename "$src")}
[ -f "$src/manifest.json" ] || { echo "$src has no manifest.json: not a sweep directory" >&2; exit 1; }
mkdir -p "$dest"
cp "$src/manifest.json" "$dest/"
# One evaluation's files (SRC a cell's eval folder, DEST its copy), those that exist.
copy_eval() {
  mkdir -p "$2"
  for f in eval.json plan.json eval.md; do
    if [ -f "$1/$f" ]; then cp "$1/$f" "$2/"; fi
  done
}
n=0
for cell in "$src"/*/; do
  cell=${cell%/}
  name=$(basename "$cell")
  [ -f "$cell/eval/eval.json" ] || continue   # only finished, evaluated cells
  # Evaluations of other weights of the cell made by hand (eval-last: its train/last/ policy),
  # copied whenever they exist, also into a cell archived before.
  for extra in "$cell"/eval-*/; do
    [ -f "$extra/eval.json" ] && copy_eval "$extra" "$dest/$name/$(basename "$extra")"
  done
  # Archived before with this evaluation: keep that copy (thinning a thinned log again would
  # drop more of it, and a sweep restored from the archive holds only the thinned logs).
  if cmp -s "$cell/eval/eval.json" "$dest/$name/eval/eval.json"; then n=$((n + 1)); continue; fi
  mkdir -p "$dest/$name/eval" "$dest/$name/train"
  for f in cell.toml cell.json; do [ -f "$cell/$f" ] && cp "$cell/$f" "$dest/$name/"; done
  copy_eval "$cell/eval" "$dest/$name/eval"
  # An extended cell's evaluations at its earlier budgets (`smile sweep`: eval.before-KEY).
  for before in "$cell"/eval.before-*/; do
    [ -f "$before/eval.json" ] && copy_eval "$before" "$dest/$name/$(basename "$before")"
  done
  for f in config.toml run.json compute.json; do
    [ -f "$cell/train/$f" ] && cp "$cell/train/$f" "$dest/$name/train/"
  done
  # The training log thinned to its evaluations and at most 200 other lines (the full log
  # stays in the run directory): what the tables and curves read, a few KB a cell.
  [ -f "$cell/train/metrics.jsonl" ] &&
    python3 "$(dirname "$0")/thin_metrics.py" "$cell/train/metrics.jsonl" "$dest/$name/train/metrics.jsonl"
  n=$((n + 1))
done
echo "archived $n evaluated cells of $src in $dest ($(du -sh "$dest" | cut -f1))"
