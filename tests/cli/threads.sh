#!/usr/bin/env bash
# LUCENT_THREADS: a bad value is a usage error naming the variable (never a
# crash, never an output file), and images do not depend on the thread count:
# 1, 2, 3 and 256 threads give bit-identical images. Args: LUCENT_BINARY SOURCE_DIR
set -u
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
export LUCENT_QUIET=1

for bad in 1000 0 257 -4 abc 8x " 8" 1e3; do
  LUCENT_THREADS=$bad "$lucent" render "$src/scenes/smoke_glow.json" --method raymarch --size 16x9 \
    -o "$tmp/bad.exr" >"$tmp/out" 2>"$tmp/err"
  rc=$?
  if [[ $rc -ne 2 ]]; then
    echo "FAIL: LUCENT_THREADS='$bad' exited $rc, expected 2; stderr: $(cat "$tmp/err")"
    fail=1
  elif ! grep -qF "LUCENT_THREADS" "$tmp/err" || [[ $(wc -l <"$tmp/err") -ne 1 ]]; then
    echo "FAIL: LUCENT_THREADS='$bad': expected one line naming LUCENT_THREADS, got: $(cat "$tmp/err")"
    fail=1
  fi
  if ls "$tmp" | grep -q '^bad\.exr'; then
    echo "FAIL: LUCENT_THREADS='$bad' left an output file"
    fail=1
  fi
done
# Empty means unset.
LUCENT_THREADS= "$lucent" render "$src/scenes/smoke_glow.json" --method raymarch --size 16x9 -o "$tmp/empty.exr" \
  2>"$tmp/err" || { echo "FAIL: empty LUCENT_THREADS: $(cat "$tmp/err")"; fail=1; }

# render METHOD SIZE THREADS: writes $tmp/METHOD_THREADS.exr
render() {
  LUCENT_THREADS=$3 "$lucent" render "$src/scenes/smoke_glow.json" --method "$1" --size "$2" \
    -o "$tmp/$1_$3.exr" 2>"$tmp/err" || { echo "FAIL: $1 with $3 threads: $(cat "$tmp/err")"; fail=1; }
}
for method in raymarch:64x36 reference:48x27; do
  m=${method%%:*}
  size=${method#*:}
  for t in 1 2 3 256; do render "$m" "$size" "$t"; done
  # A black image would compare equal to anything.
  mean=$("$lucent" info "$tmp/${m}_1.exr" | awk '/^values/ {print $NF}')
  awk -v x="$mean" 'BEGIN { exit !(x > 0.01) }' || { echo "FAIL: $m image mean '$mean' is not positive"; fail=1; }
  for t in 2 3 256; do
    "$lucent" compare "$tmp/${m}_$t.exr" "$tmp/${m}_1.exr" --max-rel-l2 0 >"$tmp/cmp" 2>&1 ||
      { echo "FAIL: $m with $t threads differs from 1 thread: $(cat "$tmp/cmp")"; fail=1; }
  done
done

[[ $fail -eq 0 ]] && echo ok
exit $fail
