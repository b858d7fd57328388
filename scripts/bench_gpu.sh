#!/usr/bin/env bash
# CPU vs GPU for the raymarch method (one kernel source, two backends) on every
# bundled volume scene, measured in one `lucent bench` run per scene so the
# ratio is fair on a shared machine; plus GPU-vs-CPU image agreement and the
# error against the reference. Writes docs/gpu/bench.csv (bench rows),
# docs/gpu/agreement.csv and docs/gpu/machine.txt.
# Usage: scripts/bench_gpu.sh [BUILD_DIR] [WxH] [FRAMES]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
size=${2:-160x120}
frames=${3:-3}
lucent=$build/lucent
out=docs/gpu
mkdir -p "$out"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export LUCENT_QUIET=1
{
  echo "date        $(date -u +%Y-%m-%dT%H:%MZ)"
  echo "command     scripts/bench_gpu.sh $build $size $frames"
  echo "cpu         $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) cores available"
  "$lucent" info --gpu | grep -E "^(renderer|version|device) "
} >"$out/machine.txt"
scenes=$(for f in scenes/*.json; do grep -q '"media"' "$f" && basename "$f" .json; done)
first=1
echo "scene,size,steps,rel_l2_gpu_vs_cpu,max_abs_gpu_vs_cpu" >"$tmp/agree.csv"
for name in $scenes; do
  "$lucent" bench "scenes/$name.json" --methods raymarch --backends cpu,gpu --size "$size" \
    --frames "$frames" --warmup 1 --save-images "$tmp/img" --csv "$tmp/b.csv" >"$tmp/log" 2>&1 ||
    { cat "$tmp/log"; exit 1; }
  if ((first)); then head -1 "$tmp/b.csv" >"$out/bench.csv"; first=0; fi
  tail -n +2 "$tmp/b.csv" >>"$out/bench.csv"
  "$lucent" compare "$tmp/img/raymarch-gpu.exr" "$tmp/img/raymarch-cpu.exr" >"$tmp/c.txt"
  echo "$name,$size,256,$(awk '$1=="rel_l2"{print $2}' "$tmp/c.txt"),$(awk '$1=="max_abs"{print $2}' "$tmp/c.txt")" >>"$tmp/agree.csv"
  echo "bench_gpu: $name done" >&2
done
mv "$tmp/agree.csv" "$out/agreement.csv"
cat "$out/machine.txt"
column -s, -t "$out/bench.csv"
column -s, -t "$out/agreement.csv"
