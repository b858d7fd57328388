#!/usr/bin/env bash
# bench prints its table for the reference and writes CSV and JSON.
# Args: LUCENT_BINARY SOURCE_DIR
set -eu
lucent=$1
src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$lucent" bench "$src/scenes/spot_shaft.json" --methods reference --size 24x18 \
  --csv "$tmp/b.csv" --json "$tmp/b.json" >"$tmp/table.txt" 2>/dev/null
grep -q "^reference *cpu" "$tmp/table.txt" || { echo "FAIL: no reference row"; cat "$tmp/table.txt"; exit 1; }
# The reference against itself: rel_l2 exactly 0.
awk -F, 'NR == 2 { exit !($2 == "reference" && $11 == 0) }' "$tmp/b.csv" || { echo "FAIL: csv"; cat "$tmp/b.csv"; exit 1; }
grep -q '"method": "reference"' "$tmp/b.json" || { echo "FAIL: json"; exit 1; }
echo ok
