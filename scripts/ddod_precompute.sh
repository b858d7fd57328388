#!/usr/bin/env bash
# ddod's precomputation time at the default 128^3 grid, 32 and 128 directions,
# on the two bounded scenes of the issue: wall seconds per stage (the lu_ddod_timing
# split) and processor seconds per stage (LUCENT_DDOD_DEBUG=1), fresh runs (no
# cache), the best of RUNS by processor time. load1 is the 1-minute load
# average when the run started (the machine is shared; read wall times with it).
# Usage: scripts/ddod_precompute.sh [BUILD_DIR] > docs/ddod/precompute.csv
set -eu
build=${1:-build}
RUNS=${RUNS:-3}
SCENES=${SCENES:-"homogeneous_sphere cube_torus"}
echo "scene,dirs,samples,load1,wall_s,optical_depth_s,divergence_s,sampling_s,sh_s,processor_s,cpu_voxel_grid_s,cpu_moment_s,cpu_divergence_s,cpu_sampling_s,cpu_attenuation_s,cpu_fit_s,cpu_sh_s"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for s in $SCENES; do
  for d in 32 128; do
    for i in $(seq "$RUNS"); do
      load=$(cut -d' ' -f1 /proc/loadavg)
      out=$(LUCENT_DDOD_DEBUG=1 LUCENT_QUIET=0 "$build/lucent" render "scenes/$s.json" --method ddod \
        --set ddod.dirs=$d --set ddod.cache=0 -o "$tmp/img.pfm" 2>&1)
      sum=$(echo "$out" | sed -n 's/^ddod: \([0-9]*\) samples.*precompute \([0-9.]*\) s (optical depth \([0-9.]*\), divergence \([0-9.]*\), sampling \([0-9.]*\), SH \([0-9.]*\); processor time \([0-9.]*\) s).*/\1,\2,\3,\4,\5,\6,\7/p')
      cpu=$(echo "$out" | sed -n 's/^ddod: medium 0 processor s: voxel grid \([0-9.]*\), moment sweeps \([0-9.]*\), divergence \([0-9.]*\), sampling \([0-9.]*\), sample attenuation \([0-9.]*\), fit \([0-9.]*\), SH \([0-9.]*\)$/\1,\2,\3,\4,\5,\6,\7/p')
      n=${sum%%,*}
      echo "$s,$d,$n,$load,${sum#*,},$cpu"
    done | sort -t, -k10,10g | head -1
  done
done
