#!/usr/bin/env bash
# Convergence of the reference: for every bundled scene, the default image
# against (a) the tolerance halved and initial steps doubled, (b) a far tighter
# solution (tolerance 1e-6, 4 initial steps), and a non-adaptive fixed-step
# image against (b). Writes docs/reference_convergence.csv.
# Usage: scripts/bench_reference.sh [BUILD_DIR] [WxH]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
size=${2:-96x72}
lucent=$build/lucent
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
rel() { "$lucent" compare "$1" "$2" | awk '/^rel_l2/ {print $2}'; }
ms() { sed -n 's/.*render \([0-9.]*\) ms.*/\1/p' "$1"; }
out=docs/reference_convergence.csv
echo "scene,size,default_ms,tight_ms,rel_l2_default_vs_halved,rel_l2_default_vs_tight,rel_l2_fixed_step_vs_tight" >"$out.tmp"
for scene in scenes/*.json; do
  name=$(basename "$scene" .json)
  r() { LUCENT_QUIET=1 "$lucent" render "$scene" --size "$size" "$@" 2>"$tmp/log"; }
  r -o "$tmp/def.exr"; t_def=$(ms "$tmp/log")
  r --set reference.tolerance=5e-4 --set reference.steps=2 -o "$tmp/half.exr"
  r --set reference.tolerance=1e-6 --set reference.steps=4 -o "$tmp/tight.exr"; t_tight=$(ms "$tmp/log")
  r --set reference.max_depth=0 --set reference.steps=0.5 -o "$tmp/fixed.exr"
  echo "$name,$size,$t_def,$t_tight,$(rel "$tmp/def.exr" "$tmp/half.exr"),$(rel "$tmp/def.exr" "$tmp/tight.exr"),$(rel "$tmp/fixed.exr" "$tmp/tight.exr")" >>"$out.tmp"
done
mv "$out.tmp" "$out"
column -s, -t "$out"
