#!/usr/bin/env bash
# The scaling table of docs/distributed.md: each workload as one process
# with 1 and 2 threads, and under mpirun as 1 rank x 2 threads and 2 ranks x
# 1 thread, REPEATS times in turn; prints the median wall time of the whole
# command (launch, prepare on every rank, render, gather, write) and of the
# render that lucent reports (rank 0: from the first band to the whole image
# on rank 0), and each rank's global stages and bands from its report.
# Usage: scripts/mpi_scaling.sh [LUCENT] [REPEATS]   (LUCENT: build/lucent)
set -euo pipefail
cd "$(dirname "$0")/.."
lucent=${1:-build/lucent}
reps=${2:-3}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
mpi=(mpirun --oversubscribe --mca btl self,vader --mca btl_vader_single_copy_mechanism none)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

workloads=(
  "pathtrace|render scenes/layered_cube.json --method pathtrace --size 128x128 --set pathtrace.spp=32"
  "afm|render scenes/layered_cube.json --method afm --size 160x160"
  "bssrdf|render scenes/bssrdf_spheres.json --method bssrdf --size 160x160"
  "ddod|render scenes/cube_torus.json --method ddod --size 160x160"
  "bench, 2 scenes|bench scenes/demo.json scenes/layered_cube.json --methods raymarch,afm --size 96x96 --frames 3 --no-truth --no-yardstick"
)
configs=(
  "1 process, 1 thread|env LUCENT_THREADS=1"
  "1 process, 2 threads|env LUCENT_THREADS=2"
  "1 rank, 2 threads|${mpi[*]} -n 1 --bind-to none -x LUCENT_THREADS=2"
  "2 ranks, 1 thread each|${mpi[*]} -n 2 --bind-to core -x LUCENT_THREADS=1"
)
median() { sort -g | awk '{a[NR] = $1} END {print NR % 2 ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2}'; }

echo "load average at the start: $(cut -d' ' -f1-3 /proc/loadavg); $(nproc) processors; $("${mpi[0]}" --version | head -1)"
# One untimed run of each workload first: ddod's precomputation lands in
# its cache, so every timed run reads it alike.
for w in "${workloads[@]}"; do
  args=${w#*|}
  [[ $args == render* ]] && args="$args -o $tmp/warm.pfm"
  $lucent $args >/dev/null 2>&1
done
echo "| workload | configuration | wall s | render ms | per rank: global stages / bands ms |"
echo "|---|---|---|---|---|"
for w in "${workloads[@]}"; do
  name=${w%%|*} args=${w#*|}
  for c in "${configs[@]}"; do
    cname=${c%%|*} launcher=${c#*|}
    : >"$tmp/wall" && : >"$tmp/render" && : >"$tmp/ranks"
    for ((i = 0; i < reps; i++)); do
      out=$args
      [[ $args == render* ]] && out="$args -o $tmp/out.pfm"
      t0=$(date +%s.%N)
      $launcher $lucent $out >"$tmp/log" 2>&1 || { echo "failed: $launcher $lucent $out" >&2; cat "$tmp/log" >&2; exit 1; }
      t1=$(date +%s.%N)
      awk -v a="$t0" -v b="$t1" 'BEGIN { print b - a }' >>"$tmp/wall"
      sed -n 's/.*render \([0-9.]*\) ms.*/\1/p' "$tmp/log" | tail -1 >>"$tmp/render"
      sed -n 's/.*rank \([0-9]*\) of [0-9]*: .*global stages \([0-9.]*\) ms, bands \([0-9.]*\) ms.*/r\1 \2\/\3/p' "$tmp/log" |
        tr '\n' ' ' >>"$tmp/ranks"
      echo >>"$tmp/ranks"
    done
    wall=$(median <"$tmp/wall")
    render=$( [ -s "$tmp/render" ] && grep . "$tmp/render" | median || echo "-")
    ranks=$(sed -n "$(( (reps + 1) / 2 ))p" "$tmp/ranks")
    printf "| %s | %s | %.2f | %s | %s |\n" "$name" "$cname" "$wall" "${render:--}" "${ranks:--}"
  done
done
echo "load average at the end: $(cut -d' ' -f1-3 /proc/loadavg)"
