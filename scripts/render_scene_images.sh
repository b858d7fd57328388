#!/usr/bin/env bash
# Renders every bundled scene with the reference at its own camera size into
# docs/images/<scene>.png (the README's gallery) and records the render times
# in docs/images/times.txt. Usage: scripts/render_scene_images.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
mkdir -p docs/images
: >docs/images/times.txt.tmp
for scene in scenes/*.json; do
  name=$(basename "$scene" .json)
  LUCENT_QUIET=1 "$build/lucent" render "$scene" --method reference -o "docs/images/$name.png" \
    2>>docs/images/times.txt.tmp
done
{
  echo "# lucent render SCENE --method reference -o docs/images/NAME.png"
  echo "# $(nproc) threads on $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $(date -u +%Y-%m-%d)"
  cat docs/images/times.txt.tmp
} >docs/images/times.txt
rm docs/images/times.txt.tmp
cat docs/images/times.txt
