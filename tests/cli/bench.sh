#!/usr/bin/env bash
# bench prints its table and writes CSV and JSON; the rel-L2 it reports is
# that of the image it saved against the truth it saved, as `lucent compare`
# computes it from the files; held_mb, what a renderer holds, is at least
# froxel's three cell grids (two lighting grids and the integral, 8 floats a
# cell) and gpu_mb is 0 on the CPU (the reference row is the truth render
# itself, not measured: 0 there, as peak_mb). Args: LUCENT_BINARY SOURCE_DIR
set -eu
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
"$lucent" bench "$src/scenes/spot_shaft.json" --methods reference,raymarch,froxel --size 24x18 --frames 2 \
  --set froxel.nx=40 --set froxel.ny=30 --set froxel.nz=32 --csv "$tmp/b.csv" --json "$tmp/b.json" --save-images "$tmp/img" >"$tmp/table.txt" 2>/dev/null
grep -q "^reference *cpu" "$tmp/table.txt" || { echo "FAIL: no reference row"; cat "$tmp/table.txt"; exit 1; }
grep -q "^raymarch *cpu" "$tmp/table.txt" || { echo "FAIL: no raymarch row"; cat "$tmp/table.txt"; exit 1; }
# The first 14 columns keep their names and order (scripts read them by position).
head -1 "$tmp/b.csv" | grep -q "^scene,method,backend,prepare_ms,frame_ms_median,frame_ms_min,frame_ms_max,frames,speedup_vs_reference,peak_mb,rel_l2,rel_l1,rmse,psnr," ||
  { echo "FAIL: csv header $(head -1 "$tmp/b.csv")"; exit 1; }
rel=$(awk -F, '$2 == "raymarch" { print $11 }' "$tmp/b.csv")
ref=$("$lucent" compare "$tmp/img/raymarch-cpu.exr" "$tmp/img/truth.exr" | awk '/^rel_l2/ {print $2}')
# The CSV prints 6 significant digits, compare 6 too.
awk -v a="$rel" -v b="$ref" 'BEGIN { d = a - b; if (d < 0) d = -d; exit !(b > 0 && d <= 1e-5 * b) }' ||
  { echo "FAIL: bench rel_l2 $rel, compare $ref"; cat "$tmp/b.csv"; exit 1; }
awk -F, -v h="$(csv_col "$tmp/b.csv" held_mb)" -v g="$(csv_col "$tmp/b.csv" gpu_mb)" \
  -v least="$(awk 'BEGIN { print 3 * 40 * 30 * 32 * 8 * 4 / 1048576 }')" '
  NR == 1 || $2 == "reference" { next }
  { if (!($h > 0) || $g != 0) { print "FAIL: " $2 " held_mb " $h ", gpu_mb " $g; bad = 1 }
    if ($2 == "froxel" && !($h >= least)) { print "FAIL: froxel holds " $h " MiB, its grids alone " least; bad = 1 } }
  END { exit bad }' "$tmp/b.csv" || { cat "$tmp/b.csv"; exit 1; }
grep -q '"held_mb": ' "$tmp/b.json" || { echo "FAIL: json has no held_mb"; exit 1; }
grep -q '"method": "reference"' "$tmp/b.json" || { echo "FAIL: json"; exit 1; }
grep -q '"motion": "still"' "$tmp/b.json" || { echo "FAIL: json has no motion"; exit 1; }
echo ok
