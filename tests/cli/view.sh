#!/usr/bin/env bash
# lucent view: a clear error without a display; under Xvfb, the window's
# screenshot of a method equals `lucent render` of the same scene and method
# (same backend, same tone curve, so the 8-bit images agree exactly: the
# bound allows 1e-3 for driver differences in the blit); the overlay draws
# into the image; the live error equals `lucent compare`; progressive
# passes converge.
# Args: LUCENT_BINARY SOURCE_DIR
set -u
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
export LUCENT_QUIET=1
asan_skip_tls_interceptor  # the viewer under make asan (tests/cli/lib.sh)
require_viewer "$src/scenes/smoke_glow.json"
"$lucent" view --help | grep -q "screenshot" || fail "view --help"
"$lucent" view "$src/scenes/smoke_glow.json" --method nosuch 2>/dev/null
[[ $? == 2 ]] || fail "unknown method: expected exit 2"
"$lucent" view "$src/scenes/smoke_glow.json" --screenshot "$tmp/x.exr" 2>/dev/null
[[ $? == 2 ]] || fail "non-PNG screenshot: expected exit 2"

# No display: exit 1 with one line that says so.
env -u DISPLAY -u WAYLAND_DISPLAY "$lucent" view "$src/scenes/smoke_glow.json" --screenshot "$tmp/x.png" 2>"$tmp/e.txt"
[[ $? == 1 ]] || fail "no display: expected exit 1"
grep -q "error: no display" "$tmp/e.txt" || { cat "$tmp/e.txt"; fail "no display message"; }
[[ $(wc -l <"$tmp/e.txt") == 1 ]] || { cat "$tmp/e.txt"; fail "no display: more than one line"; }

command -v xvfb-run >/dev/null || fail "xvfb-run is missing (scripts/setup.sh installs xvfb and xauth)"
view() { xvfb-run -a -s "-screen 0 640x480x24" "$lucent" view "$@"; }

check_same() {  # scene method backend size [settings...]
  local scene=$1 method=$2 backend=$3 size=$4
  shift 4
  view "$src/scenes/$scene.json" --method "$method" --backend "$backend" --size "$size" "$@" --no-overlay \
    --screenshot "$tmp/shot.png" --frames 2 2>"$tmp/e.txt" || { cat "$tmp/e.txt"; fail "view $scene $method"; }
  "$lucent" render "$src/scenes/$scene.json" --method "$method" --backend "$backend" --size "$size" "$@" \
    -o "$tmp/render.png" 2>/dev/null || fail "render $scene $method"
  "$lucent" compare "$tmp/shot.png" "$tmp/render.png" >"$tmp/c.txt" || fail "compare"
  awk '$1 == "rel_l2" { exit !($2 <= 1e-3) }' "$tmp/c.txt" || { cat "$tmp/c.txt"; fail "$scene $method: screenshot != render"; }
  echo "  $scene $method $backend: screenshot vs render $(grep rel_l2 "$tmp/c.txt")"
}
check_same smoke_glow raymarch gpu 64x48
check_same bssrdf_spheres bssrdf gpu 64x40 --set bssrdf.splats=600
check_same cube_torus raymarch cpu 48x48

# Live error: --compare renders the reference; the rel-L2 the viewer reports
# for its frame equals `lucent compare` of the same two renders.
view "$src/scenes/smoke_glow.json" --size 48x36 --compare --no-overlay --screenshot "$tmp/cmp.png" 2>"$tmp/e.txt" \
  || { cat "$tmp/e.txt"; fail "view --compare"; }
live=$(sed -n 's/.*rel-L2 vs reference \([0-9.e+-]*\).*/\1/p' "$tmp/e.txt")
[[ -n $live ]] || { cat "$tmp/e.txt"; fail "no live rel-L2 reported"; }
"$lucent" render "$src/scenes/smoke_glow.json" --method raymarch --backend auto --size 48x36 -o "$tmp/rm.pfm" 2>/dev/null
"$lucent" render "$src/scenes/smoke_glow.json" --method reference --size 48x36 -o "$tmp/ref.pfm" 2>/dev/null
want=$("$lucent" compare "$tmp/rm.pfm" "$tmp/ref.pfm" | awk '$1 == "rel_l2" { print $2 }')
echo "  live rel-L2 $live, lucent compare $want"
awk -v a="$live" -v b="$want" 'BEGIN { d = a - b; if (d < 0) d = -d; exit !(b > 0 && d <= 1e-4 * b) }' \
  || fail "live rel-L2 $live != $want"

# The overlay is drawn into the window (top-left), so it changes the screenshot.
view "$src/scenes/smoke_glow.json" --size 160x120 --screenshot "$tmp/overlay.png" 2>/dev/null || fail "overlay shot"
view "$src/scenes/smoke_glow.json" --size 160x120 --no-overlay --screenshot "$tmp/plain.png" 2>/dev/null || fail "plain shot"
"$lucent" compare "$tmp/overlay.png" "$tmp/plain.png" | awk '$1 == "max_abs" { exit !($2 > 0.1) }' \
  || fail "overlay not drawn"

# Progressive: 16 accumulated pathtrace passes are closer to an independent
# 128-pass render than 1 pass (noise falls as 1/sqrt(passes): 0.25x expected;
# the bound 0.6x leaves room for the heavy tail of single passes).
for n in 1 16; do
  view "$src/scenes/smoke_glow.json" --method pathtrace --size 32x24 --no-overlay --screenshot "$tmp/pt$n.png" \
    --frames $n 2>/dev/null || fail "pathtrace $n frames"
done
"$lucent" render "$src/scenes/smoke_glow.json" --method pathtrace --set pathtrace.spp=128 --set pathtrace.seed=99 \
  --size 32x24 -o "$tmp/pt128.png" 2>/dev/null || fail "pathtrace render"
e1=$("$lucent" compare "$tmp/pt1.png" "$tmp/pt128.png" | awk '$1 == "rel_l2" { print $2 }')
e16=$("$lucent" compare "$tmp/pt16.png" "$tmp/pt128.png" | awk '$1 == "rel_l2" { print $2 }')
echo "  pathtrace progressive: 1 pass $e1, 16 passes $e16 (vs 128 spp)"
awk -v a="$e1" -v b="$e16" 'BEGIN { exit !(b < 0.6 * a) }' || fail "progressive passes did not converge"
echo ok
