#!/usr/bin/env bash
# The afm method from the CLI: its parameters are listed and take effect
# (more coefficients bring the image closer to the 32-coefficient one, and
# the view march converges as a midpoint rule in its steps), and bad parameter values fail with
# a message naming the setting.
# Args: LUCENT_BINARY SOURCE_DIR
set -eu
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
scene="$src/scenes/layered_cube.json"
"$lucent" methods >"$tmp/m.txt" 2>&1 || true
grep -q "^ *afm" "$tmp/m.txt" || { echo "FAIL: afm not listed"; cat "$tmp/m.txt"; exit 1; }
r() { "$lucent" render "$scene" --method afm --size 40x40 "$@" 2>/dev/null; }
r --set afm.coefs=32 --set afm.map_res=64 -o "$tmp/c32.exr"
r --set afm.coefs=8 --set afm.map_res=64 -o "$tmp/c8.exr"
r --set afm.coefs=2 --set afm.map_res=64 -o "$tmp/c2.exr"
"$lucent" compare "$tmp/c8.exr" "$tmp/c32.exr" | awk '$1 == "rel_l2" {print $2}' >"$tmp/e8"
"$lucent" compare "$tmp/c2.exr" "$tmp/c32.exr" | awk '$1 == "rel_l2" {print $2}' >"$tmp/e2"
e8=$(cat "$tmp/e8") e2=$(cat "$tmp/e2")
awk -v a="$e8" -v b="$e2" 'BEGIN { exit !(a < b && b > 0) }' || { echo "FAIL: coefs have no effect (N=8 $e8, N=2 $e2)"; exit 1; }
# The view march is a midpoint rule: doubling its steps must cut its error
# (against a 2000-step march, whose own error is ~(80/2000)^2 of the
# 80-step one's) at least by the factor 2 of a first-order rule.
for n in 20 40 80 2000; do r --set afm.coefs=32 --set afm.map_res=64 --set afm.steps=$n -o "$tmp/s$n.exr"; done
for n in 20 40 80; do
  "$lucent" compare "$tmp/s$n.exr" "$tmp/s2000.exr" | awk '$1 == "rel_l2" {print $2}' >"$tmp/es$n"
done
awk -v a="$(cat "$tmp/es20")" -v b="$(cat "$tmp/es40")" -v c="$(cat "$tmp/es80")" \
  'BEGIN { exit !(c > 0 && a >= 2 * b && b >= 2 * c) }' ||
  { echo "FAIL: steps 20/40/80 errors $(cat "$tmp/es20") $(cat "$tmp/es40") $(cat "$tmp/es80") do not converge"; exit 1; }
bad() {
  if "$lucent" render "$scene" --method afm --size 8x8 --set "$1" -o "$tmp/bad.exr" 2>"$tmp/err.txt"; then
    echo "FAIL: $1 accepted"; exit 1
  fi
  grep -q "$2" "$tmp/err.txt" || { echo "FAIL: $1: unexpected message"; cat "$tmp/err.txt"; exit 1; }
  [ ! -e "$tmp/bad.exr" ] || { echo "FAIL: $1 left an output"; exit 1; }
}
bad afm.coefs=0 'afm.coefs'
bad afm.coefs=65 'afm.coefs'
bad afm.coefs=2.5 'expected an integer'
bad afm.steps=1 'afm.steps'
bad afm.map_res=2 'map_res'
bad afm.samples=100000 'afm.samples'
bad afm.nosuch=1 'nosuch'
echo ok
