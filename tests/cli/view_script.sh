#!/usr/bin/env bash
# lucent view --script orbit|light --frames N --stats FILE.csv under Xvfb:
# the CSV has the header frame,ms,scale,rel_l2,rss_kb,held_kb and a row per frame (frame 0
# the start view, 1..N scripted, then the settle); with a tiny budget the
# moving frames are rendered below full resolution, with an ample one at full
# resolution; the settle ends at scale 1 on the full image, which a fresh
# renderer reproduces exactly (rel_l2 0: the same deterministic computation),
# and the screenshot then equals `lucent render` of the scene turned by
# N x 4 degrees, the turn computed here in closed form. The default backend
# (auto) is the CPU without a hardware GPU, with one note. Bad --script,
# --frames and --budget values, and a light script without a light, exit 2.
# Args: LUCENT_BINARY SOURCE_DIR
set -u
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
export LUCENT_QUIET=1
asan_skip_tls_interceptor  # the viewer under make asan (tests/cli/lib.sh)
require_viewer "$src/scenes/smoke_glow.json"
scene=$src/scenes/smoke_glow.json
cheap=(--method raymarch --set raymarch.steps=32 --size 160x90)

usage_error() {  # expected-message args...
  local want=$1
  shift
  "$lucent" view "$scene" "$@" 2>"$tmp/e.txt"
  [[ $? == 2 ]] || fail "view $*: expected exit 2"
  grep -q -- "$want" "$tmp/e.txt" || { cat "$tmp/e.txt"; fail "view $*: message"; }
  [[ $(wc -l <"$tmp/e.txt") == 1 ]] || { cat "$tmp/e.txt"; fail "view $*: more than one line"; }
}
usage_error '--script takes orbit, light, play or soak ("spin")' --script spin
usage_error '--script play: nothing in the scene follows time' --script play
usage_error '--time takes seconds' --time inf
usage_error '--frames takes a positive integer ("0")' --script orbit --frames 0
usage_error '--frames takes a positive integer ("x")' --script orbit --frames x
usage_error '--budget takes milliseconds' --budget 0
awk '/"lights": \[/ { print "  \"lights\": [],"; skip = 1; next } skip && /^  \],/ { skip = 0; next } !skip' "$scene" >"$tmp/nolight.json"
"$lucent" view "$tmp/nolight.json" --script light 2>"$tmp/e.txt"
[[ $? == 2 ]] || { cat "$tmp/e.txt"; fail "light script without a light: expected exit 2"; }
grep -q "no light to orbit" "$tmp/e.txt" || { cat "$tmp/e.txt"; fail "no-light message"; }

command -v xvfb-run >/dev/null || fail "xvfb-run is missing (scripts/setup.sh installs xvfb and xauth)"
view() { xvfb-run -a -s "-screen 0 640x480x24" "$lucent" view "$@"; }

# The scene with the camera (orbit) or the first light (light) turned by a
# degrees about the y axis through the origin (smoke_glow's up and look-at):
# x' = x cos a + z sin a, z' = z cos a - x sin a.
turned() {  # key ("position" in camera or lights) angle-degrees out
  awk -v which="$1" -v deg="$2" '
    function turn(s,   p, n, c, si, x, z) {
      n = split(s, p, /, */); c = cos(deg * atan2(0, -1) / 180); si = sin(deg * atan2(0, -1) / 180)
      x = p[1] * c + p[3] * si; z = p[3] * c - p[1] * si
      return sprintf("%.9g, %s, %.9g", x, p[2], z)
    }
    (which == "camera" && /"camera"/) || (which == "light" && /"type": "point"/) {
      if (match($0, /"position": \[[^]]*\]/)) {
        inner = substr($0, RSTART + 13, RLENGTH - 14)
        $0 = substr($0, 1, RSTART - 1) "\"position\": [" turn(inner) "]" substr($0, RSTART + RLENGTH)
      }
    }
    { print }' "$scene" >"$3"
}

# orbit, tiny budget: below full resolution while moving, full at the end
n=10
view "$scene" "${cheap[@]}" --no-overlay --script orbit --frames $n --budget 1 --stats "$tmp/orbit.csv" \
  --screenshot "$tmp/orbit.png" 2>"$tmp/e.txt" || { cat "$tmp/e.txt"; fail "scripted orbit"; }
grep "script orbit" "$tmp/e.txt"
# the default backend is auto: without a hardware GPU, the CPU, said in one note line
if ! LUCENT_GPU=hardware "$lucent" info --gpu >/dev/null 2>&1; then
  [[ $(grep -c "note: --backend auto: no hardware GPU" "$tmp/e.txt") == 1 ]] || { cat "$tmp/e.txt"; fail "view: auto note"; }
  grep -q "of raymarch on cpu" "$tmp/e.txt" || { cat "$tmp/e.txt"; fail "view: auto without hardware is not the CPU"; }
fi
[[ $(head -1 "$tmp/orbit.csv") == "frame,ms,scale,rel_l2,rss_kb,held_kb" ]] || { head -2 "$tmp/orbit.csv"; fail "CSV header"; }
awk -F, -v n=$n '
  NR == 1 { next }
  { rows++; if ($1 != rows - 1) { print "frame column " $1 " at row " rows; bad = 1 }
    if (!($2 > 0)) { print "ms " $2; bad = 1 }
    if (!($3 > 0 && $3 <= 1)) { print "scale " $3; bad = 1 }
    if (!($5 > 0)) { print "rss_kb " $5; bad = 1 }
    if (!($6 > 0 && $6 < $5)) { print "held_kb " $6 " (rss_kb " $5 ")"; bad = 1 }
    if ($1 >= 1 && $1 <= n && $3 < 1) low++
    if ($1 >= 1 && $1 < n && $4 != "") { print "rel_l2 on moving frame " $1; bad = 1 }
    if ($1 >= n && $4 == "") { print "no rel_l2 on frame " $1 " (final view)"; bad = 1 }
    last_scale = $3; last_err = $4 }
  END { if (rows < n + 1) { print rows " rows"; bad = 1 }
        if (low < n) { print low " of " n " moving frames below scale 1 with --budget 1"; bad = 1 }
        if (last_scale != 1) { print "last scale " last_scale; bad = 1 }
        if (last_err != 0) { print "last rel_l2 " last_err; bad = 1 }
        exit bad }' "$tmp/orbit.csv" || { cat "$tmp/orbit.csv"; fail "orbit CSV"; }
turned camera $((4 * n)) "$tmp/orbit.json"
"$lucent" render "$tmp/orbit.json" "${cheap[@]}" --backend auto -o "$tmp/orbit_render.png" 2>/dev/null || fail "render turned camera"
"$lucent" compare "$tmp/orbit.png" "$tmp/orbit_render.png" >"$tmp/c.txt" || fail "compare"
awk '$1 == "rel_l2" { exit !($2 <= 1e-3) }' "$tmp/c.txt" || { cat "$tmp/c.txt"; fail "orbit: settled screenshot != render"; }
echo "  orbit: settled screenshot vs render of the turned camera $(grep rel_l2 "$tmp/c.txt")"

# ample budget: every moving frame fits at full resolution
view "$scene" "${cheap[@]}" --no-overlay --moving-set none --script orbit --frames 3 --budget 60000 --stats "$tmp/ample.csv" 2>"$tmp/e.txt" \
  || { cat "$tmp/e.txt"; fail "scripted orbit, ample budget"; }
awk -F, 'NR > 1 && $3 != 1 { bad = 1 } END { exit bad || NR != 5 }' "$tmp/ample.csv" \
  || { cat "$tmp/ample.csv"; fail "ample budget: expected frames 0-3, all at scale 1"; }

# moving quality: with an ample budget the moving frames are at full
# resolution (after the first, which starts small as nothing is measured at
# that quality yet) but at --moving-set's settings (8 steps), so the last
# scripted frame differs from the full image; one more frame after the input
# stops is the full image
view "$scene" "${cheap[@]}" --no-overlay --script orbit --frames 3 --budget 60000 --moving-set raymarch.steps=8 \
  --stats "$tmp/mq.csv" 2>"$tmp/e.txt" || { cat "$tmp/e.txt"; fail "scripted orbit, moving quality"; }
awk -F, 'NR > 1 { rows++; if ($1 != 1 && $3 != 1) bad = 1; err[$1] = $4 }
  END { exit bad || rows != 5 || !(err[3] > 0.001) || err[4] != 0 }' "$tmp/mq.csv" \
  || { cat "$tmp/mq.csv"; fail "moving quality: expected frames 0-4 at scale 1 (but 1, the first of its quality), frame 3 off the full image, frame 4 on it"; }
"$lucent" view "$scene" --moving-set raymarch.steps=0 2>"$tmp/e.txt"
[[ $? == 1 ]] || fail "--moving-set out of range: expected exit 1"
grep -q "moving-set.*raymarch.steps" "$tmp/e.txt" || { cat "$tmp/e.txt"; fail "--moving-set message"; }

# light: the first light turns; the settled image equals the render of the turned light
n=5
view "$scene" "${cheap[@]}" --no-overlay --script light --frames $n --budget 1 --stats "$tmp/light.csv" \
  --screenshot "$tmp/light.png" 2>"$tmp/e.txt" || { cat "$tmp/e.txt"; fail "scripted light"; }
grep "script light" "$tmp/e.txt"
awk -F, -v n=$n 'NR > 1 { rows++; last_scale = $3; last_err = $4 }
  END { exit !(rows >= n + 1 && last_scale == 1 && last_err == 0) }' "$tmp/light.csv" \
  || { cat "$tmp/light.csv"; fail "light CSV"; }
turned light $((4 * n)) "$tmp/light.json"
"$lucent" render "$tmp/light.json" "${cheap[@]}" --backend auto -o "$tmp/light_render.png" 2>/dev/null || fail "render turned light"
"$lucent" compare "$tmp/light.png" "$tmp/light_render.png" >"$tmp/c.txt" || fail "compare"
awk '$1 == "rel_l2" { exit !($2 <= 1e-3) }' "$tmp/c.txt" || { cat "$tmp/c.txt"; fail "light: settled screenshot != render"; }
echo "  light: settled screenshot vs render of the turned light $(grep rel_l2 "$tmp/c.txt")"

# play: the animated plume's time advances a frame (1/24 s) per scripted
# frame from --time 0.5; the settled image equals `render --time 0.5 + n/24`
n=3
plume=$src/scenes/smoke_plume.json
view "$plume" "${cheap[@]}" --no-overlay --time 0.5 --script play --frames $n --budget 1 \
  --screenshot "$tmp/play.png" 2>"$tmp/e.txt" || { cat "$tmp/e.txt"; fail "scripted play"; }
grep "script play" "$tmp/e.txt"
"$lucent" render "$plume" "${cheap[@]}" --backend auto --time 0.625 -o "$tmp/play_render.png" 2>/dev/null || fail "render --time"
"$lucent" compare "$tmp/play.png" "$tmp/play_render.png" >"$tmp/c.txt" || fail "compare"
awk '$1 == "rel_l2" { exit !($2 <= 1e-4) }' "$tmp/c.txt" || { cat "$tmp/c.txt"; fail "play: settled screenshot != render --time"; }
echo "  play: settled screenshot vs render --time 0.625 $(grep rel_l2 "$tmp/c.txt")"
"$lucent" render "$plume" "${cheap[@]}" --backend auto --time 0.5 -o "$tmp/play_start.png" 2>/dev/null || fail "render --time"
"$lucent" compare "$tmp/play.png" "$tmp/play_start.png" >"$tmp/c.txt"
awk '$1 == "rel_l2" { exit !($2 > 2e-3) }' "$tmp/c.txt" || { cat "$tmp/c.txt"; fail "play: the time did not move the image"; }
echo ok
