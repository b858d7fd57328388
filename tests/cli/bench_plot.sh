#!/usr/bin/env bash
# bench --plot: a PNG from gnuplot, renamed into place whole; without gnuplot
# on PATH, or with a bad name or folder, an error before anything renders.
# Args: LUCENT_BINARY SOURCE_DIR
set -eu
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
unset LUCENT_QUIET
b=(bench "$src/scenes/spot_shaft.json" --size 24x18 --frames 1 --no-yardstick --sweep raymarch.steps=8,64
   --methods reference,raymarch)

# Without gnuplot on PATH: an error before anything renders (also where gnuplot is installed).
set +e
PATH=/nonexistent "$lucent" "${b[@]}" --plot "$tmp/q.png" >/dev/null 2>"$tmp/e1"; rc1=$?
set -e
[[ $rc1 == 1 ]] || fail "without gnuplot: exit $rc1"
grep -q "needs gnuplot, which is not on PATH" "$tmp/e1" || fail "without gnuplot: $(cat "$tmp/e1")"
grep -q "rendering\|on cpu" "$tmp/e1" && fail "without gnuplot it rendered first"
command -v gnuplot >/dev/null || { echo "gnuplot is not installed (scripts/setup.sh): the rest skipped"; exit 77; }
"$lucent" "${b[@]}" --plot "$tmp/p.png" >"$tmp/out.txt" 2>"$tmp/log" || fail "plot run: $(cat "$tmp/log")"
[[ -s $tmp/p.png ]] || fail "no PNG"
[[ $(head -c 8 "$tmp/p.png" | od -An -tx1 | tr -d ' \n') == 89504e470d0a1a0a ]] || fail "not a PNG signature"
grep -q "plot written to $tmp/p.png" "$tmp/log" || fail "no message: $(cat "$tmp/log")"
ls "$tmp" | grep -q "p.png.tmp" && fail "temporary file left behind"

# Refused before any work: a name without .png, a missing folder, no truth.
set +e
"$lucent" "${b[@]}" --plot "$tmp/q.jpg" >/dev/null 2>"$tmp/e2"; rc2=$?
"$lucent" "${b[@]}" --plot "$tmp/nodir/q.png" >/dev/null 2>"$tmp/e3"; rc3=$?
"$lucent" "${b[@]}" --no-truth --plot "$tmp/q.png" >/dev/null 2>&1; rc4=$?
set -e
[[ $rc2 == 2 ]] || fail ".jpg: exit $rc2"
[[ $rc3 == 1 ]] || fail "missing folder: exit $rc3"
grep -q "rendering\|on cpu" "$tmp/e3" && fail "missing folder: it rendered first"
[[ $rc4 == 2 ]] || fail "--plot with --no-truth: exit $rc4"
[[ -e $tmp/q.png ]] && fail "a refused run wrote a plot"
echo ok
