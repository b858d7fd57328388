#!/usr/bin/env bash
# The gradient family on the command line: the methods and their parameters
# are listed, each renders a bundled volume scene, and bad settings or a
# scene without a medium fail with one clear line and exit 1.
# Args: LUCENT_BINARY SOURCE_DIR
set -eu
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
"$lucent" methods >"$tmp/m.txt"
for m in gradient rbf pervoxel; do
  grep -q "^$m" "$tmp/m.txt" || grep -q " $m" "$tmp/m.txt" || { echo "FAIL: $m not listed"; cat "$tmp/m.txt"; exit 1; }
done
for p in epsilon levels delta1 delta2 gaussians normalize; do
  grep -q "$p" "$tmp/m.txt" || { echo "FAIL: parameter $p not listed"; exit 1; }
done
scene=$src/scenes/smoke_glow.json
for m in gradient rbf pervoxel; do
  "$lucent" render "$scene" --method $m --size 24x18 -o "$tmp/$m.exr" 2>/dev/null || { echo "FAIL: $m render"; exit 1; }
  [[ -s $tmp/$m.exr ]] || { echo "FAIL: $m wrote nothing"; exit 1; }
done
# Gradient and pervoxel agree within a few percent (both approximate the same field).
"$lucent" compare "$tmp/gradient.exr" "$tmp/pervoxel.exr" >"$tmp/c.txt"
awk '$1 == "rel_l2" { exit !($2 < 0.05) }' "$tmp/c.txt" || { echo "FAIL: gradient vs pervoxel"; cat "$tmp/c.txt"; exit 1; }
# A bounded medium (boundary maps for the shadow rays) on both backends: the GPU matches the CPU.
for m in gradient raymarch; do
  have_gpu || break
  for b in cpu gpu; do
    "$lucent" render "$src/scenes/layered_cube.json" --method $m --backend $b --size 24x24 -o "$tmp/lc_$b.exr" 2>/dev/null \
      || { echo "FAIL: $m on $b"; exit 1; }
  done
  "$lucent" compare "$tmp/lc_gpu.exr" "$tmp/lc_cpu.exr" >"$tmp/c.txt"
  awk '$1 == "rel_l2" { exit !($2 < 1e-3) }' "$tmp/c.txt" || { echo "FAIL: $m gpu vs cpu"; cat "$tmp/c.txt"; exit 1; }
done

expect_fail() {  # expect_fail PATTERN ARGS...: exit 1, one line on stderr naming PATTERN
  local pat=$1
  shift
  set +e
  "$lucent" "$@" -o "$tmp/bad.exr" 2>"$tmp/err.txt" >/dev/null
  local rc=$?
  set -e
  [[ $rc -eq 1 ]] || { echo "FAIL: exit $rc for $*"; cat "$tmp/err.txt"; exit 1; }
  grep -q "$pat" "$tmp/err.txt" || { echo "FAIL: message for $*: $(cat "$tmp/err.txt")"; exit 1; }
  [[ ! -e $tmp/bad.exr ]] || { echo "FAIL: output written for $*"; exit 1; }
}
expect_fail "outside" render "$scene" --method gradient --set gradient.levels=7
expect_fail "expected one of" render "$scene" --method gradient --set gradient.normalize=sometimes
expect_fail "no such parameter" render "$scene" --method pervoxel --set pervoxel.epsilon=0.1
expect_fail "outside" render "$scene" --method rbf --set rbf.delta2=0
cat >"$tmp/empty.json" <<'JSON'
{"camera": {"position": [0,0,4], "look_at": [0,0,0], "width": 8, "height": 8},
 "lights": [{"type": "point", "position": [0,1,0], "intensity": [1,1,1]}]}
JSON
expect_fail "no participating medium" render "$tmp/empty.json" --method gradient
echo ok
