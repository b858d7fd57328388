#!/usr/bin/env bash
# pathtrace through the CLI: --progressive-every rewrites the output during
# the render and ends on the same image as a one-shot render; bad values are
# usage errors. Args: LUCENT_BINARY SOURCE_DIR
set -eu
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

scene="$src/scenes/spot_shaft.json"
env -u LUCENT_QUIET "$lucent" render "$scene" --size 16x12 --method pathtrace --set pathtrace.spp=5 \
    --progressive-every 2 -o "$tmp/p.exr" 2>"$tmp/log" || fail "progressive render"
grep -q "after 2 of 5 passes" "$tmp/log" || fail "no write after 2 passes: $(cat "$tmp/log")"
grep -q "after 4 of 5 passes" "$tmp/log" || fail "no write after 4 passes"
[[ -s $tmp/p.exr ]] || fail "no output"
"$lucent" render "$scene" --size 16x12 --method pathtrace --set pathtrace.spp=5 -o "$tmp/q.exr" 2>/dev/null
"$lucent" compare "$tmp/p.exr" "$tmp/q.exr" --json | grep -q '"rel_l2": 0,' || fail "progressive and one-shot differ"

set +e
"$lucent" render "$scene" --method pathtrace --progressive-every 0 -o "$tmp/x.exr" >/dev/null 2>&1
rc=$?
"$lucent" render "$scene" --method pathtrace --set pathtrace.boundary=bent -o "$tmp/x.exr" >/dev/null 2>"$tmp/err"
rc2=$?
set -e
[[ $rc -eq 2 ]] || fail "--progressive-every 0: exit $rc, expected 2"
[[ $rc2 -eq 1 ]] || fail "bad choice: exit $rc2, expected 1"
grep -q "auto|straight|refract" "$tmp/err" || fail "bad choice message: $(cat "$tmp/err")"
echo ok
