#!/usr/bin/env bash
# Time on the command line: a NanoVDB sequence baked from the animated plume
# (export-grid of the scene at each frame's time), `render --time` against
# the frame's file alone, `--frame-range` outputs, and the errors of bad
# ranges and missing frames. Args: LUCENT_BINARY SOURCE_DIR
set -u
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
check() { [[ $1 -eq 0 ]] || { echo "FAIL: $2"; fail=1; }; }

scene() { # scene DENSITY_JSON [EXTRA_ROOT_KEYS]
  cat <<JSON
{"camera": {"position": [0, 1.1, 4.2], "look_at": [0, 1, 0], "width": 24, "height": 20},
 "lights": [{"type": "point", "position": [1.5, 3, 1.5], "intensity": [40, 40, 40]}], ${2:-}
 "media": [{"density": $1, "sigma_s": 8, "sigma_a": 1}]}
JSON
}
plume='{"procedural": "smoke_plume", "center": [0, 1, 0], "size": [2, 2, 2], "resolution": 16, "seed": 4, "rise": 0.6}'
for f in 1 2 3; do
  scene "$plume" "\"fps\": 10, \"time\": 0.$f," >"$tmp/bake.json"
  "$lucent" export-grid "$tmp/bake.json" -o "$tmp/s_00$f.nvdb" >/dev/null 2>&1
  check $? "export-grid frame $f"
done
scene '{"file": "s_###.nvdb", "frames": [1, 3]}' '"fps": 10,' >"$tmp/seq.json"
scene '{"file": "s_002.nvdb"}' >"$tmp/one.json"

# --time 0.25 is frame 2: the image equals the frame's file alone, bit for bit
"$lucent" render "$tmp/seq.json" --method raymarch --time 0.25 -o "$tmp/t.exr" 2>/dev/null
check $? "render --time"
"$lucent" render "$tmp/one.json" --method raymarch -o "$tmp/one.exr" 2>/dev/null
"$lucent" compare "$tmp/t.exr" "$tmp/one.exr" --max-rel-l2 0 >/dev/null
check $? "--time 0.25 differs from s_002.nvdb alone"
"$lucent" render "$tmp/seq.json" --method raymarch --time 0.35 -o "$tmp/t3.exr" 2>/dev/null
"$lucent" compare "$tmp/t3.exr" "$tmp/one.exr" --max-rel-l2 0 >/dev/null 2>&1
[[ $? -ne 0 ]]; check $? "--time 0.35 (frame 3) renders like frame 2"

# --frame-range: one file per frame, frame 2 the same image again
"$lucent" render "$tmp/seq.json" --method raymarch --frame-range 1-3 -o "$tmp/out_####.exr" 2>/dev/null
check $? "render --frame-range"
for f in 1 2 3; do [[ -f $tmp/out_000$f.exr ]]; check $? "out_000$f.exr missing"; done
"$lucent" compare "$tmp/out_0002.exr" "$tmp/one.exr" --max-rel-l2 0 >/dev/null
check $? "frame 2 of --frame-range differs from s_002.nvdb alone"
"$lucent" render "$tmp/seq.json" --method raymarch --frame-range 2-2 -o "$tmp/plain.png" 2>/dev/null
[[ -f $tmp/plain_0002.png ]]; check $? "no '#' in -o: plain_0002.png expected"

usage() { # usage NEEDLE ARGS...: exit 2 and a message holding NEEDLE
  local needle=$1; shift
  "$lucent" "$@" >/dev/null 2>"$tmp/err"
  local rc=$?
  [[ $rc -eq 2 ]] && grep -qF -- "$needle" "$tmp/err"; check $? "'$*' exited $rc: $(cat "$tmp/err")"
}
usage "--frame-range takes A-B" render "$tmp/seq.json" --frame-range 3-1 -o "$tmp/x.exr"
usage "--frame-range takes A-B" render "$tmp/seq.json" --frame-range 1- -o "$tmp/x.exr"
usage "--frame-range takes A-B" render "$tmp/seq.json" --frame-range -1-2 -o "$tmp/x.exr"
usage "--time takes seconds" render "$tmp/seq.json" --time nan -o "$tmp/x.exr"
usage "not both" render "$tmp/seq.json" --time 1 --frame-range 1-2 -o "$tmp/x.exr"
usage "more than one run" render "$tmp/seq.json" --frame-range 1-2 -o "$tmp/a_#_#.exr"

# bench: the medium motion follows the sequence's time (one frame per step),
# --stability gives every timed row a flicker, update_ms the scene change
"$lucent" bench "$tmp/seq.json" --methods raymarch --motion medium --frames 3 --stability --no-yardstick \
  --csv "$tmp/b.csv" >/dev/null 2>"$tmp/err"
check $? "bench --stability: $(cat "$tmp/err")"
col() { csv_col "$tmp/b.csv" "$1"; }
awk -F, -v f="$(col flicker)" -v u="$(col update_ms)" -v l="$(col rel_l2_last_vs_first)" \
  'NR == 2 { ok = ($f > 0.5 && $f < 2 && $u > 0 && $l > 0) } END { exit !(NR == 2 && ok) }' "$tmp/b.csv"
check $? "bench CSV: $(cat "$tmp/b.csv")"
usage "--stability needs a motion" bench "$tmp/seq.json" --methods raymarch --stability
usage "--time takes seconds" bench "$tmp/seq.json" --time 1e9

# a missing frame: one line naming the file, exit 1, nothing written
rm "$tmp/s_003.nvdb"
"$lucent" render "$tmp/seq.json" --method raymarch --frame-range 1-3 -o "$tmp/miss_####.exr" >/dev/null 2>"$tmp/err"
rc=$?
[[ $rc -eq 1 ]] && grep -q "s_003.nvdb" "$tmp/err" && [[ $(wc -l <"$tmp/err") -eq 1 ]]
check $? "missing frame: exit $rc, $(cat "$tmp/err")"
[[ -z $(find "$tmp" -name 'miss_*') ]]; check $? "a missing frame left outputs"
exit $fail
