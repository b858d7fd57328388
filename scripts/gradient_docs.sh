#!/usr/bin/env bash
# Regenerates the measurements of docs/gradient.md under docs/gradient/:
#   bench.csv       gradient, rbf, pervoxel on every bundled volume
#                   scene, rel-L2 against the reference (BACKENDS, default cpu,gpu)
#   glow.csv        smoke_glow: gradient vs rbf (the paper's 4.3 % vs 14.7 % claim)
#   resolution.csv  frame time vs density resolution 32^3..256^3, gradient vs pervoxel
#   lights.csv      frame time vs number of point lights 1..64, gradient vs pervoxel
#   shaft.csv       spot_shaft: dynamic sampling on/off, sample counts and errors
#   scaling.png     the two timing tables as a plot (gnuplot)
# All timings are medians of `lucent bench` in one run per table, so the
# ratios are what to read. SECTIONS="bench glow ..." limits the run; SIZE
# sets the image size (default 160x120); RES_MAX the largest resolution
# (default 256; RES_LIST the resolutions, default "32 64 128 256"; KEEP=1
# appends to resolution.csv instead of rewriting it); BACKENDS the backends of the timing tables (default cpu);
# LIGHTS_RES the density resolution of the light-count table (default 64).
#
#   scripts/gradient_docs.sh [BUILD_DIR]      (default: build)
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${1:-build}
L=$BUILD/lucent
OUT=${OUT:-docs/gradient}
SIZE=${SIZE:-160x120}
RES_MAX=${RES_MAX:-256}
RES_LIST=${RES_LIST:-"32 64 128 256"}
SECTIONS=${SECTIONS:-"bench glow resolution lights shaft plot"}
BENCH_BACKENDS=${BENCH_BACKENDS:-cpu,gpu}
BACKENDS=${BACKENDS:-cpu}
LIGHTS_RES=${LIGHTS_RES:-64}
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
mkdir -p "$OUT"
export LUCENT_QUIET=1
want() { [[ " $SECTIONS " == *" $1 "* ]]; }
# bench SCENE CSV ARGS...: one bench run, CSV rows appended (header once)
bench() {
    local scene=$1 csv=$2
    shift 2
    "$L" bench "$scene" --size "$SIZE" --csv "$TMP/b.csv" "$@" >"$TMP/b.txt" 2>"$TMP/b.err" || { cat "$TMP/b.err"; exit 1; }
    [[ -s $csv ]] || head -1 "$TMP/b.csv" >"$csv"
    tail -n +2 "$TMP/b.csv" >>"$csv"
}
# A scene variant: python edits of the JSON (paths made absolute).
variant() {  # variant SRC DST PYTHON-EXPR-ON-s
    python3 - "$1" "$2" "$3" <<'PY'
import json, os, sys
src, dst, expr = sys.argv[1:4]
s = json.load(open(src))
base = os.path.dirname(os.path.abspath(src))
for m in s.get("media", []):
    d = m["density"]
    for k in ("file", "voxelize"):
        if k in d: d[k] = os.path.join(base, d[k])
exec(expr)
json.dump(s, open(dst, "w"))
PY
}

if want bench; then
    rm -f "$OUT/bench.csv"
    for s in smoke_glow spot_shaft dusty_room smoke_box demo bunny_fog cube_torus layered_cube homogeneous_sphere; do
        echo "bench $s" >&2
        bench "scenes/$s.json" "$OUT/bench.csv" --methods gradient,rbf,pervoxel --backends "$BENCH_BACKENDS" \
            --frames 3 --warmup 1
    done
fi

if want glow; then
    rm -f "$OUT/glow.csv"
    "$L" render scenes/smoke_glow.json --size "$SIZE" -o "$TMP/ref.exr" 2>/dev/null
    # label|method|settings
    while IFS='|' read -r label m sets; do
        args=()
        for kv in $sets; do args+=(--set "$kv"); done
        LUCENT_GRADIENT_STATS=1 "$L" bench scenes/smoke_glow.json --size "$SIZE" --methods "$m" --backends "$BACKENDS" \
            --reference "$TMP/ref.exr" --frames 3 --warmup 1 --csv "$TMP/g.csv" "${args[@]}" >/dev/null 2>"$TMP/g.err"
        samples=$(grep -o 'final samples [0-9]*' "$TMP/g.err" | tail -1 | grep -o '[0-9]*$' || echo 0)
        [[ -s $OUT/glow.csv ]] || echo "label,samples,$(head -1 "$TMP/g.csv")" >"$OUT/glow.csv"
        tail -n +2 "$TMP/g.csv" | sed "s/^/$label,$samples,/" >>"$OUT/glow.csv"
    done <<'EOF'
rbf (paper Fig. 3a)|rbf|
rbf; paper formulation|rbf|rbf.normalize=none
gradient; no splitting (paper Fig. 3c)|gradient|gradient.levels=0
gradient; no splitting; paper formulation|gradient|gradient.levels=0 gradient.normalize=none
gradient (defaults)|gradient|
gradient; paper formulation|gradient|gradient.normalize=none
pervoxel|pervoxel|
EOF
fi

if want resolution; then
    [[ -n ${KEEP:-} ]] || rm -f "$OUT/resolution.csv"
    for r in $RES_LIST; do
        [[ $r -le $RES_MAX ]] || continue
        echo "resolution $r" >&2
        variant scenes/smoke_glow.json "$TMP/glow_$r.json" "s['media'][0]['density']['resolution'] = $r"
        # 256^3 per-voxel tracing takes minutes per frame on 2 cores: one frame, no warm-up there.
        fw=(--frames 3 --warmup 1)
        [[ $r -lt 256 ]] || fw=(--frames 1 --warmup 0)
        bench "$TMP/glow_$r.json" "$TMP/res_$r.csv" --methods gradient,pervoxel --backends "$BACKENDS" "${fw[@]}"
        bench "$TMP/glow_$r.json" "$TMP/res_paper_$r.csv" --methods gradient --backends "$BACKENDS" "${fw[@]}" \
            --set gradient.levels=0
        [[ -s $OUT/resolution.csv ]] || echo "resolution,variant,$(head -1 "$TMP/res_$r.csv")" >"$OUT/resolution.csv"
        tail -n +2 "$TMP/res_$r.csv" | sed "s/^/$r,default,/" >>"$OUT/resolution.csv"
        tail -n +2 "$TMP/res_paper_$r.csv" | sed "s/^/$r,no splitting,/" >>"$OUT/resolution.csv"
    done
fi

if want lights; then
    rm -f "$OUT/lights.csv"
    for n in 1 4 16 64; do
        echo "lights $n" >&2
        # n point lights on a sphere of radius 1.5 around the cloud's centre, total intensity kept.
        variant scenes/smoke_glow.json "$TMP/lights_$n.json" "
import math
l0 = s['lights'][0]; n = $n
I = [v / n for v in l0['intensity']]
s['lights'] = []
for i in range(n):
    z = 1 - (2 * i + 1) / n; r = math.sqrt(max(0, 1 - z * z)); ph = i * 2.39996323
    p = [l0['position'][0] + 1.5 * r * math.cos(ph) * (n > 1), l0['position'][1] + 1.5 * z * (n > 1), l0['position'][2] + 1.5 * r * math.sin(ph) * (n > 1)]
    s['lights'].append({'type': 'point', 'position': p, 'intensity': I})
s['media'][0]['density']['resolution'] = $LIGHTS_RES"
        bench "$TMP/lights_$n.json" "$TMP/l_$n.csv" --methods gradient,pervoxel --backends "$BACKENDS" --frames 1 --warmup 1 \
            --set gradient.levels=0
        [[ -s $OUT/lights.csv ]] || echo "lights,$(head -1 "$TMP/l_$n.csv")" >"$OUT/lights.csv"
        tail -n +2 "$TMP/l_$n.csv" | sed "s/^/$n,/" >>"$OUT/lights.csv"
    done
fi

if want shaft; then
    rm -f "$OUT/shaft.csv"
    "$L" render scenes/spot_shaft.json --size "$SIZE" -o "$TMP/ref.exr" 2>/dev/null
    for nz in none falloff emission; do
        for lv in 0 3; do
            LUCENT_GRADIENT_STATS=1 "$L" bench scenes/spot_shaft.json --size "$SIZE" --methods gradient --backends "$BACKENDS" \
                --reference "$TMP/ref.exr" --frames 3 --warmup 1 --csv "$TMP/s.csv" --set gradient.normalize=$nz \
                --set gradient.levels=$lv >/dev/null 2>"$TMP/s.err"
            st=$(grep '^gradient:' "$TMP/s.err" | tail -1)
            roots=$(echo "$st" | grep -o 'roots [0-9]*' | grep -o '[0-9]*$')
            final=$(echo "$st" | grep -o 'final samples [0-9]*' | grep -o '[0-9]*$')
            levels=$(echo "$st" | grep -o 'levels [0-9/]*' | cut -d' ' -f2)
            [[ -s $OUT/shaft.csv ]] || echo "normalize,levels,roots,final_samples,per_level,$(head -1 "$TMP/s.csv")" >"$OUT/shaft.csv"
            tail -n +2 "$TMP/s.csv" | sed "s|^|$nz,$lv,$roots,$final,$levels,|" >>"$OUT/shaft.csv"
        done
    done
fi

if want plot && [[ -s $OUT/resolution.csv && -s $OUT/lights.csv ]]; then
    # columns: resolution.csv: 1 res, 2 variant, 4 method, 5 backend, 7 frame_ms; lights.csv: 1 n, 3 method, 4 backend, 6 frame_ms
    awk -F, 'NR > 1 && $2 == "default" && $4 == "gradient" {print $1, $7}' "$OUT/resolution.csv" >"$TMP/rg.dat"
    awk -F, 'NR > 1 && $2 == "no splitting" && $4 == "gradient" {print $1, $7}' "$OUT/resolution.csv" >"$TMP/rn.dat"
    awk -F, 'NR > 1 && $2 == "default" && $4 == "pervoxel" {print $1, $7}' "$OUT/resolution.csv" >"$TMP/rp.dat"
    awk -F, 'NR > 1 && $3 == "gradient" {print $1, $6}' "$OUT/lights.csv" >"$TMP/lg.dat"
    awk -F, 'NR > 1 && $3 == "pervoxel" {print $1, $6}' "$OUT/lights.csv" >"$TMP/lp.dat"
    gnuplot <<EOF
set terminal pngcairo size 1000,420 font ",10" noenhanced
set output "$OUT/scaling.png"
set multiplot layout 1,2
set logscale xy 2
set grid
set key top left
set xlabel "density grid resolution (n^3), smoke_glow, 1 point light"
set ylabel "frame time (ms), $BACKENDS, $SIZE"
plot "$TMP/rp.dat" w lp lw 2 t "pervoxel", "$TMP/rg.dat" w lp lw 2 t "gradient (defaults)", \
     "$TMP/rn.dat" w lp lw 2 t "gradient, no splitting"
set xlabel "point lights ($LIGHTS_RES^3 smoke_glow)"
plot "$TMP/lp.dat" w lp lw 2 t "pervoxel", "$TMP/lg.dat" w lp lw 2 t "gradient, no splitting"
unset multiplot
EOF
fi
echo "wrote $OUT" >&2
