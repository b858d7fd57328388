#!/usr/bin/env bash
# afm against OpenVDB's vdb_render (Debian libopenvdb-tools) on the same grid,
# camera, light and units, whole process each, both judged against lucent's
# reference of the same scene.
#
#   1. `lucent export-grid` writes the bundled bunny_fog density (the npm bunny
#      voxelised at 96 voxels along its longest side) as .nvdb, under its world
#      map; nanovdb_convert turns it into .vdb. Both renderers read that grid.
#   2. The matched scene: vdb_render has one directional light and no phase
#      function, so the scene is bunny_fog's grid, camera and coefficients
#      with one directional light and isotropic scattering. Units: vdb_render
#      integrates in index space, so its coefficients are per voxel (sigma x
#      voxel size), and it folds the phase 1/(4 pi) into the light colour, so
#      its colour is the scene's irradiance / (4 pi). Its -gain (extra
#      transmittance along shadow rays, not physical) is 0; its quality
#      settings (step 1 voxel, shadow step 3 voxels, cutoff 0.005) are its
#      defaults. Both write linear float EXR.
#   3. Times: wall clock of each whole process (load, build, render, write),
#      all threads each, measured one after the other in this run.
#
# Usage: scripts/vs_vdb_render.sh [BUILD_DIR] [SIZE]    (SIZE: side of the square image, default 512)
# REF=FILE reuses a reference image of the matched scene (it takes minutes on 2 cores);
# KEEP=DIR keeps the grid, the scene and the images there.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
size=${2:-512}
L=$build/lucent
[[ -x $L ]] || { echo "vs_vdb_render: $L not found (build first)" >&2; exit 1; }
[[ $size =~ ^[0-9]+$ ]] || { echo "vs_vdb_render: SIZE must be a number of pixels, got '$size'" >&2; exit 2; }
for t in vdb_render nanovdb_convert; do
  command -v "$t" >/dev/null ||
    { echo "vs_vdb_render: $t not found: install libopenvdb-tools and libnanovdb-tools (scripts/setup.sh)" >&2; exit 1; }
done
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export LUCENT_QUIET=1

# The matched view and light, written once for both renderers (bunny_fog's camera).
cam_pos=0,6,16
cam_look=0,3,0
fov=40 # vertical in lucent, horizontal in vdb_render: equal for a square image
light_dir=0.5,0.45,0.7 # towards the light, for both
light_colour=0.25      # vdb_render's colour = irradiance / (4 pi)

"$L" export-grid scenes/bunny_fog.json --medium 0 -o "$tmp/bunny.nvdb" >"$tmp/export.txt"
# "wrote F: NX x NY x NZ voxels, voxel H x H x H, values [..], sigma_s R G B, sigma_a R G B, g G"
read -r h hy hz ss sa <<<"$(sed -n 's/.*voxel \([^ ]*\) x \([^ ]*\) x \([^,]*\),.*sigma_s \([^ ]*\) .*sigma_a \([^ ]*\) .*/\1 \2 \3 \4 \5/p' "$tmp/export.txt")"
[[ -n ${sa:-} ]] || { echo "vs_vdb_render: cannot read the export line: $(cat "$tmp/export.txt")" >&2; exit 1; }
[[ $h == "$hy" && $h == "$hz" ]] ||
  { echo "vs_vdb_render: vdb_render steps in voxels, so it needs cubic voxels; the grid has $h x $hy x $hz" >&2; exit 1; }
nanovdb_convert -f "$tmp/bunny.nvdb" "$tmp/bunny.vdb" >/dev/null

irr=$(awk -v c=$light_colour 'BEGIN { printf "%.9g", c * 16 * atan2(1, 1) }')
scatter=$(awk -v s="$ss" -v h="$h" 'BEGIN { v = s * h; printf "%.9g,%.9g,%.9g", v, v, v }')
absorb=$(awk -v s="$sa" -v h="$h" 'BEGIN { v = s * h; printf "%.9g,%.9g,%.9g", v, v, v }')
cat >"$tmp/matched.json" <<EOF
{
  "name": "bunny_fog_vdb",
  "reproduces": "bunny_fog's grid, camera and coefficients with one directional light and isotropic scattering, which vdb_render can render",
  "camera": {"position": [$cam_pos], "look_at": [$cam_look], "fov_y_deg": $fov, "width": $size, "height": $size},
  "background": [0, 0, 0],
  "lights": [{"type": "directional", "direction": [$light_dir], "irradiance": [$irr, $irr, $irr]}],
  "media": [{"density": {"file": "bunny.nvdb"}, "sigma_s": [$ss, $ss, $ss], "sigma_a": [$sa, $sa, $sa], "phase_g": 0}]
}
EOF

# timed NAME CMD...: runs CMD, appends "NAME seconds" to times.txt.
timed() {
  local name=$1
  shift
  local t0 t1
  t0=$(date +%s.%N)
  "$@" >"$tmp/$name.log" 2>&1 || { cat "$tmp/$name.log" >&2; exit 1; }
  t1=$(date +%s.%N)
  awk -v a="$t0" -v b="$t1" -v n="$name" 'BEGIN { printf "%s %.3f\n", n, b - a }' >>"$tmp/times.txt"
}
vdb_args=(-res "${size}x$size" -translate "$cam_pos" -lookat "$cam_look" -up 0,1,0 -fov "$fov"
  -light "$light_dir,$light_colour,$light_colour,$light_colour" -scatter "$scatter" -absorb "$absorb")

load_before=$(uptime | sed 's/.*load average: //')
timed afm "$L" render "$tmp/matched.json" --method afm -o "$tmp/afm.exr"
timed vdb_render vdb_render "$tmp/bunny.vdb" "$tmp/vdb.exr" "${vdb_args[@]}" -gain 0
timed vdb_render_gain vdb_render "$tmp/bunny.vdb" "$tmp/vdb_gain.exr" "${vdb_args[@]}"
load_after=$(uptime | sed 's/.*load average: //')
if [[ -n ${REF:-} ]]; then
  cp "$REF" "$tmp/ref.exr"
else
  "$L" render "$tmp/matched.json" --method reference -o "$tmp/ref.exr" 2>/dev/null
fi

err() { "$L" compare "$tmp/$1.exr" "$tmp/ref.exr" | awk '$1 == "rel_l2" { print $2 }'; }
sec() { awk -v n="$1" '$1 == n { print $2 }' "$tmp/times.txt"; }
e_afm=$(err afm)
e_vdb=$(err vdb)
e_gain=$(err vdb_gain)
t_afm=$(sec afm)
t_vdb=$(sec vdb_render)
t_gain=$(sec vdb_render_gain)
ratio=$(awk -v a="$t_afm" -v b="$t_vdb" 'BEGIN { printf "%.2f", b / a }')

echo "grid: $(sed 's/^wrote [^:]*: //' "$tmp/export.txt")"
echo "image ${size}x$size, $(nproc) cores; load average before: $load_before; after: $load_after"
printf '%-40s %10s %12s\n' "renderer (whole process)" "seconds" "rel_l2"
printf '%-40s %10s %12s\n' "lucent render --method afm (defaults)" "$t_afm" "$e_afm"
printf '%-40s %10s %12s\n' "vdb_render -gain 0 (matched)" "$t_vdb" "$e_vdb"
printf '%-40s %10s %12s\n' "vdb_render, its default -gain 0.2" "$t_gain" "$e_gain"
echo "vdb_render / afm time: $ratio"
echo "vdb_render arguments: ${vdb_args[*]} -gain 0"
if [[ -n ${KEEP:-} ]]; then
  mkdir -p "$KEEP"
  cp "$tmp"/{bunny.nvdb,bunny.vdb,matched.json,afm.exr,vdb.exr,vdb_gain.exr,ref.exr} "$KEEP"/
fi
