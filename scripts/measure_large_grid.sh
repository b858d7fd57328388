#!/usr/bin/env bash
# Resident memory and time of each volume method on the large grid of
# scripts/make_large_grid.sh, against a baseline of the same method on the
# small sparse scene (the process's own footprint: Embree, the GL driver,
# images), on the CPU:
#   scripts/measure_large_grid.sh LUCENT [DIR=build/large] [SIZE=160x90] [METHODS...]
# Prints one line per method: peak RSS of the large and the baseline run
# (/usr/bin/time -v), their difference, the render's prepare and frame ms
# as lucent render reports them, or the method's error.
set -uo pipefail
lucent=${1:?usage: measure_large_grid.sh LUCENT [DIR] [SIZE] [METHODS...]}
dir=${2:-build/large}
size=${3:-160x90}
shift $(( $# < 3 ? $# : 3 ))
methods=${*:-reference pathtrace raymarch afm gradient rbf pervoxel ddod}
here=$(cd "$(dirname "$0")/.." && pwd)
scene="$dir/dragon_fog.json"
small="$here/scenes/sparse_cloud.json"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# pathtrace and ddod at cheap settings: 1 spp, few precomputation directions
declare -A extra=([pathtrace]="--set pathtrace.spp=1" [ddod]="--set ddod.cache=0")
rss() { awk '/Maximum resident/ {print $6}' "$1"; }
printf "%-10s %12s %12s %12s  %s\n" method "rss_kB" "base_kB" "delta_MB" "lucent render"
for m in $methods; do
    /usr/bin/time -v "$lucent" render "$small" --method "$m" --size "$size" ${extra[$m]:-} -o "$tmp/b.pfm" \
        >"$tmp/b.out" 2>"$tmp/b.time"
    /usr/bin/time -v "$lucent" render "$scene" --method "$m" --size "$size" ${extra[$m]:-} -o "$tmp/$m.pfm" \
        >"$tmp/l.out" 2>"$tmp/l.time"
    rc=$?
    a=$(rss "$tmp/l.time"); b=$(rss "$tmp/b.time")
    msg=$(grep -h "^lucent render" "$tmp/l.time" "$tmp/l.out" | tail -1)
    printf "%-10s %12s %12s %12.1f  rc=%d %s\n" "$m" "$a" "$b" "$(echo "($a - $b) / 1024" | bc -l)" "$rc" "$msg"
done
