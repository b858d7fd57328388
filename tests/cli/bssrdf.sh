#!/usr/bin/env bash
# lucent profile reports a preset's totals; the bssrdf method renders a
# procedural scene on both backends, and the two images agree.
# Args: LUCENT_BINARY SOURCE_DIR
set -eu
lucent=$1
src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$lucent" profile --preset marble >"$tmp/p.txt"
# Jensen et al.'s marble, red: the closed form and Simpson over [0, inf) agree to 6 digits.
grep -q "closed form *0.866526" "$tmp/p.txt" || { echo "FAIL: closed form"; cat "$tmp/p.txt"; exit 1; }
grep -q "Simpson, \[0, inf) *0.866526" "$tmp/p.txt" || { echo "FAIL: Simpson"; cat "$tmp/p.txt"; exit 1; }
"$lucent" profile --preset nosuch >/dev/null 2>&1 && { echo "FAIL: unknown preset accepted"; exit 1; }
for b in cpu gpu; do
  "$lucent" render "$src/scenes/bssrdf_spheres.json" --method bssrdf --backend $b --size 48x30 \
    --set bssrdf.splats=600 --set bssrdf.profile=multipole -o "$tmp/$b.exr" 2>/dev/null
done
# Two black images would agree: the spheres must be lit (a tenth of the image
# lit at unit irradiance is a mean well above 0.01).
"$lucent" info "$tmp/cpu.exr" | awk '$1 == "values" { exit !($NF > 0.01) }' ||
  { echo "FAIL: the CPU image is black"; "$lucent" info "$tmp/cpu.exr"; exit 1; }
"$lucent" compare "$tmp/gpu.exr" "$tmp/cpu.exr" >"$tmp/c.txt"
awk '$1 == "rel_l2" { exit !($2 < 1e-4) }' "$tmp/c.txt" || { echo "FAIL: cpu/gpu differ"; cat "$tmp/c.txt"; exit 1; }
echo ok
