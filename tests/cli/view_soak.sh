#!/usr/bin/env bash
# The short viewer soak (the long one: make soak, scripts/soak.sh): lucent
# view --script soak under Xvfb for one cycle of methods at 96x54, with the
# camera and light turning, a method switch every 20 frames (afm refuses the
# translucent scene and is skipped) and window resizes. It must end cleanly
# (exit 0; a method switch whose create failed used to crash at exit), write
# one CSV row per frame with a resident-memory figure, and have shown every
# method the scene takes.
# Args: LUCENT_BINARY SOURCE_DIR
set -u
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
export LUCENT_QUIET=1
asan_skip_tls_interceptor  # the viewer under make asan (tests/cli/lib.sh)
require_viewer "$src/scenes/demo.json"
command -v xvfb-run >/dev/null || { echo "skipped: no xvfb-run"; exit 77; }
n=$("$lucent" methods | grep -c '^[a-z]* \[')
frames=$((20 * n))
xvfb-run -a "$lucent" view "$src/scenes/bssrdf_spheres.json" --script soak --frames $frames --size 96x54 \
  --budget 200 --stats "$tmp/soak.csv" 2>"$tmp/err.txt"
rc=$?
[[ $rc == 0 ]] || { cat "$tmp/err.txt"; fail "view --script soak exited $rc"; }
# afm refuses the translucent spheres once per cycle; no other method may.
refused=$(grep -c ': afm: ' "$tmp/err.txt")
[[ $refused -ge 1 ]] || { cat "$tmp/err.txt"; fail "afm was never tried"; }
awk -F, -v n=$((frames + 1 - refused)) 'NR == 1 { if ($0 != "frame,ms,scale,rel_l2,rss_kb,held_kb") { print "header " $0; bad = 1 }; next }
  { rows++; if (!($5 > 0)) { print "rss_kb " $5 " at frame " $1; bad = 1 }
    if (!($6 > 0)) { print "held_kb " $6 " at frame " $1; bad = 1 } }
  END { if (rows < n) { print rows " rows, expected " n " (a row per frame; a refused one has none)"; bad = 1 }; exit bad }' "$tmp/soak.csv" ||
  fail "soak CSV"
if grep -v ': afm: \|note: --backend auto\|script soak' "$tmp/err.txt" | grep -q .; then
  cat "$tmp/err.txt"; fail "unexpected messages"
fi
echo "  soak: $frames frames, $(($(wc -l <"$tmp/soak.csv") - 1)) rows, afm refused $refused time(s); $(grep 'script soak' "$tmp/err.txt")"
