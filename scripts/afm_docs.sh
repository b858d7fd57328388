#!/usr/bin/env bash
# Regenerates the measurements of docs/afm.md under docs/afm/:
#   1. bench_<SIZE>.csv: `lucent bench` of reference and afm (CPU) on every
#      bundled volume scene, one run per scene (so the speed ratio is measured
#      under the same load); the truth images are kept for stages 2-3;
#   2. bench_gpu_<SIZE>.csv: afm on the GPU backend against the same truths;
#   3. sweep_<SIZE>.csv + sweep_<SIZE>.png: error vs frame time over
#      coefficients (4, 8, 16, 32) and view-march steps (50, 100, 250, 500)
#      on the SWEEP scenes.
# STAGES="1 2 3" picks stages; SCENES / SWEEP limit the scenes; SIZE sets the
# image size (default 256x256). docs/afm.md used SIZE=512x512 STAGES=1 on four
# scenes and the defaults for the rest; the reference dominates the time
# (bunny_fog: 11 minutes at 512x512 on the shared 2-core machine).
#
#   scripts/afm_docs.sh [BUILD_DIR]      (default: build)
#
# Needs: the built `lucent`, gnuplot (scripts/setup.sh installs gnuplot-nox),
# and data/ (scripts/setup.sh) for bunny_fog.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${1:-build}
L=$BUILD/lucent
OUT=${OUT:-docs/afm}
SIZE=${SIZE:-256x256}
STAGES=${STAGES:-"1 2 3"}
SCENES=${SCENES:-"bunny_fog cube_torus demo dusty_room homogeneous_sphere layered_cube smoke_box smoke_glow spot_shaft"}
SWEEP=${SWEEP:-"cube_torus spot_shaft"}
TRUTH=${TRUTH:-$BUILD/afm_truth_$SIZE}
mkdir -p "$OUT" "$TRUTH"
export LUCENT_QUIET=1
has() { case " $STAGES " in *" $1 "*) return 0 ;; esac; return 1; }
header="scene,method,backend,prepare_ms,frame_ms_median,frame_ms_min,frame_ms_max,frames,speedup_vs_reference,peak_mb,rel_l2,rel_l1,rmse,psnr"

if has 1; then
    echo "$header" >"$OUT/bench_$SIZE.csv.tmp"
    [ -f "$OUT/bench_$SIZE.csv" ] && [ -n "${APPEND:-}" ] && tail -n +2 "$OUT/bench_$SIZE.csv" >>"$OUT/bench_$SIZE.csv.tmp"
    for s in $SCENES; do
        echo "== bench $s" >&2
        rm -rf "$TRUTH/$s"
        "$L" bench "scenes/$s.json" --methods reference,afm --backends cpu --size "$SIZE" --frames 3 --warmup 1 \
            --save-images "$TRUTH/$s" --csv "$TRUTH/$s.csv"
        tail -n +2 "$TRUTH/$s.csv" >>"$OUT/bench_$SIZE.csv.tmp"
    done
    mv "$OUT/bench_$SIZE.csv.tmp" "$OUT/bench_$SIZE.csv"
fi

if has 2; then
    echo "$header" >"$OUT/bench_gpu_$SIZE.csv.tmp"
    for s in $SCENES; do
        echo "== gpu $s" >&2
        "$L" bench "scenes/$s.json" --methods afm --backends gpu --size "$SIZE" --frames 1 --warmup 0 \
            --reference "$TRUTH/$s/truth.exr" --save-images "$TRUTH/$s/gpu" --csv "$TRUTH/$s.gpu.csv"
        tail -n +2 "$TRUTH/$s.gpu.csv" >>"$OUT/bench_gpu_$SIZE.csv.tmp"
        "$L" compare "$TRUTH/$s/gpu/afm-gpu.exr" "$TRUTH/$s/afm-cpu.exr" | awk -v s="$s" '$1 == "rel_l2" { print "  gpu vs cpu " s ": " $2 }' >&2
    done
    mv "$OUT/bench_gpu_$SIZE.csv.tmp" "$OUT/bench_gpu_$SIZE.csv"
fi

if has 3; then
    echo "scene,coefs,steps,frame_ms,rel_l2,reference_ms" >"$OUT/sweep_$SIZE.csv.tmp"
    for s in $SWEEP; do
        ref_ms=$(awk -F, '$2 == "reference" { print $5 }' "$TRUTH/$s.csv")
        for c in 4 8 16 32; do
            for n in 50 100 250 500; do
                echo "== sweep $s coefs=$c steps=$n" >&2
                "$L" bench "scenes/$s.json" --methods afm --backends cpu --size "$SIZE" --frames 1 --warmup 0 \
                    --set afm.coefs=$c --set afm.steps=$n --reference "$TRUTH/$s/truth.exr" --csv "$TRUTH/sweep.csv" >/dev/null
                awk -F, -v s="$s" -v c=$c -v n=$n -v r="$ref_ms" 'NR == 2 { print s "," c "," n "," $5 "," $11 "," r }' \
                    "$TRUTH/sweep.csv" >>"$OUT/sweep_$SIZE.csv.tmp"
            done
        done
    done
    mv "$OUT/sweep_$SIZE.csv.tmp" "$OUT/sweep_$SIZE.csv"
    gnuplot -e "csv='$OUT/sweep_$SIZE.csv'; out='$OUT/sweep_$SIZE.png'; scenes='$SWEEP'" scripts/afm_plot.gp
fi
