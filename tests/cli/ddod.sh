#!/usr/bin/env bash
# The ddod method from the CLI: a render computes and caches the
# precomputation, a second run loads it (same image, bit for bit), bad
# parameters and a corrupt cache file fail with one clear line.
# Args: LUCENT_BINARY SOURCE_DIR
set -eu
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
export LUCENT_CACHE_DIR="$tmp/cache"
opts=(--size 32x32 --set ddod.res=32 --set ddod.dirs=32 --set ddod.samples=2000 --set ddod.bands=4)
"$lucent" render "$src/scenes/homogeneous_sphere.json" --method ddod "${opts[@]}" -o "$tmp/a.pfm" 2>"$tmp/a.log"
grep -q "precompute [0-9]" "$tmp/a.log" || { echo "FAIL: no precompute line"; cat "$tmp/a.log"; exit 1; }
ls "$tmp/cache"/ddod-*.bin >/dev/null || { echo "FAIL: no cache file"; exit 1; }
"$lucent" render "$src/scenes/homogeneous_sphere.json" --method ddod "${opts[@]}" -o "$tmp/b.pfm" 2>"$tmp/b.log"
grep -q "precompute loaded" "$tmp/b.log" || { echo "FAIL: cache not used"; cat "$tmp/b.log"; exit 1; }
cmp -s "$tmp/a.pfm" "$tmp/b.pfm" || { echo "FAIL: cached render differs"; exit 1; }
# out-of-range parameter
if "$lucent" render "$src/scenes/homogeneous_sphere.json" --method ddod --set ddod.bands=9 -o "$tmp/c.pfm" 2>"$tmp/c.log"; then
  echo "FAIL: bands=9 accepted"; exit 1
fi
grep -q "ddod.bands" "$tmp/c.log" || { echo "FAIL: message"; cat "$tmp/c.log"; exit 1; }
# corrupt cache file: one line naming it
for f in "$tmp/cache"/ddod-*.bin; do head -c 100 "$f" >"$f.x" && mv "$f.x" "$f"; done
if "$lucent" render "$src/scenes/homogeneous_sphere.json" --method ddod "${opts[@]}" -o "$tmp/d.pfm" 2>"$tmp/d.log"; then
  echo "FAIL: corrupt cache accepted"; exit 1
fi
grep -q "ddod-.*\.bin: truncated" "$tmp/d.log" || { echo "FAIL: corrupt-cache message"; cat "$tmp/d.log"; exit 1; }
# a medium without boundary mesh
if "$lucent" render "$src/scenes/smoke_box.json" --method ddod "${opts[@]}" -o "$tmp/e.pfm" 2>"$tmp/e.log"; then
  echo "FAIL: unbounded medium accepted"; exit 1
fi
grep -q "no boundary mesh" "$tmp/e.log" || { echo "FAIL: unbounded message"; cat "$tmp/e.log"; exit 1; }
echo ok
