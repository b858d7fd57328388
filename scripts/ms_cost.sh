#!/usr/bin/env bash
# Cost of the multiple-scattering octaves (docs/multiple-scattering.md): CPU
# (user) seconds of one single-threaded `lucent render` per method and scene,
# ms=off and ms=octaves alternating, 3 runs each; one line "scene method ms seconds".
#   scripts/ms_cost.sh [BUILD_DIR]      (default: build)
set -euo pipefail
cd "$(dirname "$0")/.."
L=${1:-build}/lucent
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
for s in demo bunny_fog cube_torus layered_cube homogeneous_sphere; do
  sz=$(python3 -c "import json;c=json.load(open('scenes/$s.json'))['camera'];print('%dx%d'%(c['width']//2,c['height']//2))")
  for m in raymarch afm; do
    for k in 1 2 3; do for ms in off octaves; do
      t=$(LUCENT_THREADS=1 LUCENT_QUIET=1 /usr/bin/time -f "%U" "$L" render scenes/$s.json --method $m --size $sz --set $m.ms=$ms -o "$OUT/c.exr" 2>&1 | tail -1)
      echo "$s $m $ms $t"
    done; done
  done
done
