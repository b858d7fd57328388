#!/usr/bin/env bash
# lucent profile reports a preset's totals; the bssrdf method renders a
# procedural scene on both backends, and the two images agree.
# Args: LUCENT_BINARY SOURCE_DIR
set -eu
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
"$lucent" profile --preset marble >"$tmp/p.txt"
# Jensen et al.'s marble, red: the closed form and Simpson over [0, inf) agree to 6 digits.
grep -q "closed form *0.866526" "$tmp/p.txt" || { echo "FAIL: closed form"; cat "$tmp/p.txt"; exit 1; }
grep -q "Simpson, \[0, inf) *0.866526" "$tmp/p.txt" || { echo "FAIL: Simpson"; cat "$tmp/p.txt"; exit 1; }
"$lucent" profile --preset nosuch >/dev/null 2>&1 && { echo "FAIL: unknown preset accepted"; exit 1; }
# A marble half-space (100 x 50 x 100 mm box) under a directional light at
# normal incidence, seen from above: every 1D profile carries the same total
# A (the dipole's closed form), so the exitance is E F_t(0) A and the radiance
# F_t(0)^2 E A / (pi (1 - F_dr,ext)), 1 - F_dr,ext = 2 int F_t mu dmu (here by
# the midpoint rule). Each table holds >= 1 - eps = 0.99 of A and the splat
# grid adds < 1 %: 2 % for each profile, and for their ratio.
cat >"$tmp/slab.json" <<'EOF_SLAB'
{"camera": {"position": [0, 60, 0], "look_at": [0, 0, 0], "up": [0, 0, -1], "fov_y_deg": 8, "width": 24, "height": 24},
 "lights": [{"type": "directional", "direction": [0, 1, 0], "irradiance": [1, 1, 1]}],
 "objects": [{"mesh": {"procedural": "box", "size": [100, 50, 100]}, "transform": {"translate": [0, -25, 0]},
   "material": {"type": "translucent", "preset": "marble", "specular": 0}}]}
EOF_SLAB
want=$(awk '/closed form/ { a = ($3 + $4 + $5) / 3 }
  END { eta = 1.3; n = 4000; s = 0
        for (i = 0; i < n; i++) { mu = (i + 0.5) / n; st2 = (1 - mu * mu) / (eta * eta); ct = sqrt(1 - st2)
          rs = (mu - eta * ct) / (mu + eta * ct); rp = (eta * mu - ct) / (eta * mu + ct)
          s += 2 * (1 - 0.5 * (rs * rs + rp * rp)) * mu / n }
        f0 = ((eta - 1) / (eta + 1)) ^ 2; printf "%.6f", (1 - f0) ^ 2 * a / (3.14159265358979 * s) }' "$tmp/p.txt")
for prof in dipole burley; do
  "$lucent" render "$tmp/slab.json" --method bssrdf --set bssrdf.profile=$prof --set bssrdf.splats=20000 \
    -o "$tmp/slab_$prof.pfm" 2>/dev/null
  "$lucent" info "$tmp/slab_$prof.pfm" | awk -v w="$want" -v p=$prof '$1 == "values" {
    printf "  half-space, %s: mean radiance %s, expected %s\n", p, $NF, w; exit !($NF > 0.98 * w && $NF < 1.02 * w) }' ||
    { echo "FAIL: $prof half-space radiance"; exit 1; }
done
"$lucent" profile --preset marble --model pbd >"$tmp/q.txt"
grep -q "model pbd, 512 entries" "$tmp/q.txt" || { echo "FAIL: pbd profile"; cat "$tmp/q.txt"; exit 1; }
"$lucent" profile --preset marble --model nosuch >/dev/null 2>&1 && { echo "FAIL: unknown model accepted"; exit 1; }
backends="cpu gpu"
have_gpu || backends=cpu
for b in $backends; do
  "$lucent" render "$src/scenes/bssrdf_spheres.json" --method bssrdf --backend $b --size 48x30 \
    --set bssrdf.splats=600 --set bssrdf.profile=multipole -o "$tmp/$b.exr" 2>/dev/null
done
# Two black images would agree: the spheres must be lit (a tenth of the image
# lit at unit irradiance is a mean well above 0.01).
"$lucent" info "$tmp/cpu.exr" | awk '$1 == "values" { exit !($NF > 0.01) }' ||
  { echo "FAIL: the CPU image is black"; "$lucent" info "$tmp/cpu.exr"; exit 1; }
if [[ $backends == *gpu* ]]; then
  "$lucent" compare "$tmp/gpu.exr" "$tmp/cpu.exr" >"$tmp/c.txt"
  awk '$1 == "rel_l2" { exit !($2 < 1e-4) }' "$tmp/c.txt" || { echo "FAIL: cpu/gpu differ"; cat "$tmp/c.txt"; exit 1; }
fi
echo ok
