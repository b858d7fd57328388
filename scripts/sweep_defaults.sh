#!/usr/bin/env bash
# The sweep behind the error-budgeted defaults (docs/performance.md): the
# reference of every volume scene at 640x360 (kept in out/truth/ and reused),
# then each swept setting judged against it.
# Usage: scripts/sweep_defaults.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
lucent=${1:-build}/lucent
export LUCENT_QUIET=1
mkdir -p out/truth out/sweep
scenes="bunny_fog smoke_glow spot_shaft smoke_box demo dusty_room cube_torus homogeneous_sphere layered_cube"
for n in $scenes; do
  [[ -f out/truth/$n.exr ]] ||
    "$lucent" render "scenes/$n.json" --method reference --size 640x360 -o "out/truth/$n.exr"
done
for n in $scenes; do
  "$lucent" bench "scenes/$n.json" --methods afm --size 640x360 --frames 1 --warmup 0 \
    --reference "out/truth/$n.exr" --sweep afm.steps=100,150,200,300,500 --sweep afm.map_res=64,128,256 \
    --no-yardstick --csv "out/sweep/afm-$n.csv" >"out/sweep/afm-$n.txt"
  "$lucent" bench "scenes/$n.json" --methods afm,gradient,pervoxel --size 640x360 --frames 1 --warmup 0 \
    --reference "out/truth/$n.exr" --sweep afm.steps=250,300,500 --sweep gradient.steps=128,192,256 \
    --sweep pervoxel.steps=128,192,256 --csv "out/sweep/gate-$n.csv" >"out/sweep/gate-$n.txt"
done
echo "sweep_defaults: CSVs in out/sweep/"
