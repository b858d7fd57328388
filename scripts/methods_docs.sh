#!/usr/bin/env bash
# docs/methods.md: for each bundled volume scene, one `lucent bench` against
# the multiple-scattering truth (`--truth pathtrace`, cached) with the seeds'
# methods, froxel, the march family's multiple-scattering term (ms off and
# octaves), reference and pathtrace at a few sample counts, at half the
# scene camera's size; writes docs/methods/<scene>.csv and the error-time
# plot docs/images/methods/<scene>.png.
# Usage: scripts/methods_docs.sh BUILD_DIR [SCENE...]   (env LUCENT_CACHE_DIR: the truths' cache)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
shift || true
scenes=("$@")
((${#scenes[@]})) || scenes=(smoke_box dusty_room spot_shaft demo bunny_fog cube_torus layered_cube homogeneous_sphere
                             smoke_glow)
mkdir -p docs/methods docs/images/methods
for s in "${scenes[@]}"; do
  read -r w h < <(python3 -c "import json;c=json.load(open('scenes/$s.json'))['camera'];print(c['width']//2,c['height']//2)")
  # ddod renders media inside a closed boundary mesh only
  methods=reference,raymarch,afm,gradient,froxel,pathtrace
  python3 -c "import json,sys;sys.exit(not all('boundary' in m for m in json.load(open('scenes/$s.json'))['media']))" &&
    methods=$methods,ddod
  echo "== $s ${w}x${h}"
  "$build/lucent" bench "scenes/$s.json" --size "${w}x${h}" --truth pathtrace --frames 2 --warmup 0 \
    --methods "$methods" \
    --sweep raymarch.ms=off,octaves --sweep afm.ms=off,octaves --sweep gradient.ms=off,octaves \
    --sweep pathtrace.spp=4,16 --set pathtrace.jitter=0 \
    --csv "docs/methods/$s.csv" --plot "docs/images/methods/$s.png"
done
