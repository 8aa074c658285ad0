#!/usr/bin/env bash
# Writes SHA256SUMS in every folder of shipped files under assets/ (issue 72, item 5): one line
# per file git tracks there, `sha256sum`'s own format, documentation (*.md) left out. Every
# load of a listed file (demos, expert and meta-policy weights, checkpoints, the shipped blob)
# checks it against the list and refuses a changed byte, naming the file; `sha256sum -c
# SHA256SUMS` in a folder checks the same with the system's tool. Run it after changing a
# shipped file on purpose, and commit the lists with the files.
#   docs/scripts/shipped-sums.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
git ls-files assets | grep -v '\.md$' | grep -v '/SHA256SUMS$' | xargs -n1 dirname | sort -u |
  while read -r dir; do
    (cd "$dir" && git ls-files . | grep -v / | grep -v '\.md$' | grep -vx SHA256SUMS |
      LC_ALL=C sort | xargs -r sha256sum > SHA256SUMS)
    echo "$dir/SHA256SUMS: $(wc -l < "$dir/SHA256SUMS") files"
  done
