#!/usr/bin/env bash
# The afm method from the CLI: its parameters are listed and take effect
# (fewer coefficients and steps change the image, more coefficients bring
# it closer to the 32-coefficient one), and bad parameter values fail with
# a message naming the setting.
# Args: LUCENT_BINARY SOURCE_DIR
set -eu
lucent=$1
src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
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
r --set afm.coefs=32 --set afm.map_res=64 --set afm.steps=20 --set afm.jitter=1 --set afm.samples=16 -o "$tmp/s20.exr"
"$lucent" compare "$tmp/s20.exr" "$tmp/c32.exr" | awk '$1 == "rel_l2" { exit !($2 > 0) }' || { echo "FAIL: steps have no effect"; exit 1; }
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
