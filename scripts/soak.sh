#!/usr/bin/env bash
# make soak (docs/reliability.md, "Soak" and "Faults"): the long runs kept
# out of the default suite, in one script, at most about 30 minutes on a
# 2-core machine:
#   1. test_alloc_fail --full: every allocation of one frame of each CPU
#      method failed in turn, then --gpu --full: the same over the GPU
#      methods' host side (skipped without a GPU context);
#   2. test_soak --frames 1000 --size 160x90: the library loop, its CSV in
#      out/soak/library.csv;
#   3. lucent view --script soak --frames 2000 at 160x90 under Xvfb (orbit,
#      light, a method switch every 20 frames, a resize every 60), its CSV in
#      out/soak/viewer.csv; the resident memory's peak over the last cycle of
#      methods may exceed the first cycle's by at most 5 %;
#   4. out/soak/soak.png: resident memory against frame, both loops (gnuplot).
# Usage: scripts/soak.sh BUILD_DIR   (env SOAK_FRAMES, SOAK_VIEW_FRAMES)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
frames=${SOAK_FRAMES:-1000}
vframes=${SOAK_VIEW_FRAMES:-2000}
out=out/soak
mkdir -p "$out"
export LUCENT_QUIET=1
echo "soak: 1/3 allocation failure, every allocation of one frame per method"
"$build/test_alloc_fail" --full
set +e
"$build/test_alloc_fail" --gpu --full
rc=$?
set -e
[[ $rc -eq 0 || $rc -eq 77 ]] || exit $rc
echo "soak: 2/3 library loop, $frames frames per method at 160x90"
"$build/test_soak" --frames "$frames" --size 160x90 --csv "$out/library.csv"
echo "soak: 3/3 viewer, $vframes scripted frames at 160x90 under Xvfb"
xvfb-run -a "$build/lucent" view scenes/bssrdf_spheres.json --script soak --frames "$vframes" --size 160x90 \
  --stats "$out/viewer.csv"
# Windows of 20 frames (lucent view's LU_VIEW_SOAK_METHOD_EVERY) times the
# method table's size: each holds at least one whole cycle of the methods
# the scene takes (a method it refuses is skipped and takes no frames).
n=$("$build/lucent" methods | grep -c '^[a-z]* \[')
awk -F, -v cycle=$((20 * n)) 'NR > 1 && $1 > 0 {
    c = int(($1 - 1) / cycle); if ($5 > peak[c]) peak[c] = $5; last = c }
  END { if (last < 1) { print "soak: fewer than two cycles of methods"; exit 1 }
        g = 100 * (peak[last] - peak[0]) / peak[0]
        printf "soak: viewer resident peak, first cycle %d kB, last (%d) %d kB: %+.2f %%\n", peak[0], last + 1, peak[last], g
        exit !(g <= 5) }' "$out/viewer.csv"
gnuplot <<GP
set terminal pngcairo size 900,420 font ",10"
set output "$out/soak.png"
set datafile separator ","
set multiplot layout 1,2
set title "library loop: resident memory (160x90, $frames frames per method)"
set xlabel "frame (all methods in turn)"; set ylabel "MiB"; set key off
plot "$out/library.csv" every ::1 using 0:(\$4/1024) with lines lw 1.5
set title "viewer soak: resident memory ($vframes frames)"
set xlabel "frame"
plot "$out/viewer.csv" every ::1 using 1:(\$5/1024) with lines lw 1.5
unset multiplot
GP
echo "soak: wrote $out/library.csv, $out/viewer.csv, $out/soak.png"
