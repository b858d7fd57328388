#!/usr/bin/env bash
# Regenerates the measurements of docs/ddod.md into docs/ddod/:
#   bench_<scene>.csv   lucent bench rows (ddod, CPU and GPU) against the reference
#   psi.csv             rel-L2 of each scene with view / light attenuation traced or from the SH
#   dirs.csv + sphere_dirs<N>.png / _diff.png   the paper's Table 1 (32/128/512 directions;
#                       images and rel_l2 on the paper's SH path, rel_l2_default with the defaults)
#   precompute.csv      precomputation time per stage at 128^3, 32 and 128 directions
#                       (scripts/ddod_precompute.sh)
#   scaling.csv + scaling.png   frame time vs lights and vs samples (examples/ddod_scaling)
#   <scene>.png, <scene>_diff.png   default-settings images and difference images
# Usage: scripts/ddod_docs.sh [BUILD_DIR]   (run from the repository root)
# Overrides: OUT (docs/ddod), REF (out/ddod_ref: reference images, rendered
# when missing, minutes each), SCENES, SKIP_SCALING=1.
set -eu
build=${1:-build}
L=$build/lucent
OUT=${OUT:-docs/ddod}
REF=${REF:-out/ddod_ref}
SCENES=${SCENES:-"homogeneous_sphere cube_torus layered_cube"}
export LUCENT_CACHE_DIR=${LUCENT_CACHE_DIR:-out/cache}
export LUCENT_QUIET=${LUCENT_QUIET:-1}
mkdir -p "$OUT" "$REF"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# The precompute line is printed unless LUCENT_QUIET; keep it for parsing.
run_ddod() { LUCENT_QUIET=0 "$L" render "$@" 2>&1 | grep "^ddod:\|^lucent render" || true; }

for s in $SCENES; do
  [ -f "$REF/$s.exr" ] || "$L" render "scenes/$s.json" -o "$REF/$s.exr"
done

# 1. bench rows, default settings (precomputation from the cache after the first run)
for s in $SCENES; do
  "$L" bench "scenes/$s.json" --methods ddod --backends cpu,gpu --frames 5 --reference "$REF/$s.exr" \
    --csv "$OUT/bench_$s.csv" --save-images "$tmp/img_$s" >"$OUT/bench_$s.txt" 2>&1
  for b in cpu gpu; do
    f="$tmp/img_$s/ddod-$b.exr"
    [ -f "$f" ] || continue
    "$L" compare "$f" "$REF/$s.exr" -o "$OUT/${s}_${b}_diff.png" --json >"$OUT/${s}_${b}_compare.json"
  done
  run_ddod "scenes/$s.json" --method ddod -o "$OUT/$s.png" >/dev/null
done

# 2. traced attenuation (default) against the paper's SH, per side, default settings otherwise
echo "scene,view_psi,light_psi,rel_l2" >"$OUT/psi.csv"
for s in $SCENES; do
  for v in traced sh; do
    for l in traced sh; do
      "$L" render "scenes/$s.json" --method ddod --set ddod.view_psi=$v --set ddod.light_psi=$l -o "$tmp/psi.exr" 2>/dev/null
      e=$("$L" compare "$tmp/psi.exr" "$REF/$s.exr" | awk '$1 == "rel_l2" {print $2}')
      echo "$s,$v,$l,$e" >>"$OUT/psi.csv"
    done
  done
done

# 3. Table 1: directions on the homogeneous sphere (fresh precomputation each). The
# directions only reach the image through the SH and the sample density, so the
# table is rendered on the paper's SH path; rel_l2_default is the default (traced).
paper="--set ddod.view_psi=sh --set ddod.light_psi=sh"
echo "dirs,samples,rel_l2,precompute_s,optical_depth_s,divergence_s,sampling_s,sh_s,processor_s,rel_l2_default" >"$OUT/dirs.csv"
for d in 32 128 512; do
  line=$(run_ddod scenes/homogeneous_sphere.json --method ddod --set ddod.dirs=$d --set ddod.cache=0 $paper \
    -o "$tmp/dirs$d.exr" | grep "^ddod:")
  "$L" render scenes/homogeneous_sphere.json --method ddod --set ddod.dirs=$d $paper -o "$OUT/sphere_dirs$d.png" 2>/dev/null
  e=$("$L" compare "$tmp/dirs$d.exr" "$REF/homogeneous_sphere.exr" -o "$OUT/sphere_dirs${d}_diff.png" --scale 0.02 |
    awk '$1 == "rel_l2" {print $2}')
  "$L" render scenes/homogeneous_sphere.json --method ddod --set ddod.dirs=$d -o "$tmp/dirs${d}_default.exr" 2>/dev/null
  e2=$("$L" compare "$tmp/dirs${d}_default.exr" "$REF/homogeneous_sphere.exr" | awk '$1 == "rel_l2" {print $2}')
  n=$(echo "$line" | sed -n 's/^ddod: \([0-9]*\) samples.*/\1/p')
  t=$(echo "$line" | sed -n 's/.*precompute \([0-9.]*\) s (optical depth \([0-9.]*\), divergence \([0-9.]*\), sampling \([0-9.]*\), SH \([0-9.]*\); processor time \([0-9.]*\) s).*/\1,\2,\3,\4,\5,\6/p')
  echo "$d,$n,$e,$t,$e2" >>"$OUT/dirs.csv"
done

# 4. precomputation at 128^3 (the default res) with 32 and 128 directions, per stage
scripts/ddod_precompute.sh "$build" >"$OUT/precompute.csv"

# 5. frame time vs lights (still and moving) and samples, both backends, one run; the
# light rows again on cube_torus, whose grid makes a traced light dearer
if [ "${SKIP_SCALING:-0}" != 1 ]; then
  "$build/examples/ddod_scaling" scenes/homogeneous_sphere.json 5 >"$OUT/scaling.csv"
  "$build/examples/ddod_scaling" scenes/cube_torus.json 3 lights >"$OUT/scaling_cube_torus.csv"
  gnuplot <<GP
set terminal pngcairo size 900,380 font ",10"
set output "$OUT/scaling.png"
set datafile separator ","
set multiplot layout 1,2
set title "processor time per frame vs lights (50k samples)"
set xlabel "lights"; set ylabel "processor ms / frame"; set logscale x 2; set key top left; set yrange [0:*]
plot "< grep '^lights,.*,cpu' $OUT/scaling.csv" u 2:5 w lp t "CPU, lights still", \
     "< grep '^lights,.*,gpu' $OUT/scaling.csv" u 2:5 w lp t "GPU (llvmpipe), lights still", \
     "< grep '^lights_moving,.*,cpu' $OUT/scaling.csv" u 2:5 w lp dt 2 t "CPU, lights moving", \
     "< grep '^lights_moving,.*,gpu' $OUT/scaling.csv" u 2:5 w lp dt 2 t "GPU (llvmpipe), lights moving", \
     "< grep '^lights_sh,.*,cpu' $OUT/scaling.csv" u 2:5 w lp dt 3 t "CPU, SH path (paper)"
set title "processor time per frame vs samples (2 lights)"
set xlabel "samples"; unset logscale x
plot "< grep '^samples,.*,cpu' $OUT/scaling.csv" u 2:5 w lp t "CPU backend", \
     "< grep '^samples,.*,gpu' $OUT/scaling.csv" u 2:5 w lp t "GPU backend (llvmpipe)"
unset multiplot
GP
fi
echo "written to $OUT"
