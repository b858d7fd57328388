#!/usr/bin/env bash
# Outputs are checked before the work starts, and an interrupted render
# leaves no partial or temporary file. Args: LUCENT_BINARY SOURCE_DIR
set -u
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
no_temp() { # no lu_atomic_file temporary left in the folder
  local left
  left=$(find "$tmp" -maxdepth 1 -name '*.tmp.*' | head -1)
  [[ -z $left ]] || { echo "FAIL: $1: temporary file left: $left"; fail=1; }
}

# A missing, a non-folder and a read-only output folder: refused before the
# scene is even read (the scene path does not exist), naming the folder.
check_refused() {
  local needle=$1; shift
  "$lucent" "$@" 2>"$tmp/err" >/dev/null
  local rc=$?
  if [[ $rc -ne 1 ]] || ! grep -qF -- "$needle" "$tmp/err" || grep -q "nosuch.json" "$tmp/err"; then
    echo "FAIL: '$*' exited $rc: $(cat "$tmp/err")"
    fail=1
  fi
}
touch "$tmp/file"
mkdir "$tmp/ro" && chmod 555 "$tmp/ro"
check_refused "/nonexistent/dir" render "$tmp/nosuch.json" -o /nonexistent/dir/x.png
check_refused "is not a folder" render "$tmp/nosuch.json" -o "$tmp/file/x.png"
mkdir "$tmp/dir.png"
check_refused "the output is a folder" render "$tmp/nosuch.json" -o "$tmp/dir.png"
if [[ $(id -u) -ne 0 ]]; then  # root writes anywhere
  check_refused "not writable" render "$tmp/nosuch.json" -o "$tmp/ro/x.png"
fi
check_refused "/nonexistent/dir" bench "$src/scenes/demo.json" --csv /nonexistent/dir/b.csv
check_refused "/nonexistent/dir" export-grid "$tmp/nosuch.json" -o /nonexistent/dir/g.nvdb

# SIGINT in the middle of a one-shot render: exit 130, no output, no temporary.
"$lucent" render "$src/scenes/smoke_glow.json" --method pathtrace --size 96x96 --set pathtrace.spp=100000 \
  -o "$tmp/one.exr" 2>/dev/null &
pid=$!
sleep 1
kill -INT $pid
wait $pid
rc=$?
[[ $rc -eq 130 ]] || { echo "FAIL: interrupted render exited $rc, expected 130"; fail=1; }
[[ ! -e $tmp/one.exr ]] || { echo "FAIL: interrupted render left an output"; fail=1; }
no_temp "one-shot"

# SIGINT while progressive images are being rewritten: exit 130, and the last
# complete progressive image is still a valid image.
"$lucent" render "$src/scenes/smoke_glow.json" --method pathtrace --size 96x96 --set pathtrace.spp=100000 \
  --progressive-every 1 -o "$tmp/prog.exr" 2>/dev/null &
pid=$!
for _ in $(seq 1 600); do [[ -e $tmp/prog.exr ]] && break; sleep 0.1; done
sleep 0.3
kill -INT $pid
wait $pid
rc=$?
[[ $rc -eq 130 ]] || { echo "FAIL: interrupted progressive render exited $rc, expected 130"; fail=1; }
"$lucent" info "$tmp/prog.exr" >"$tmp/info" 2>&1 && grep -q "96 x 96" "$tmp/info" ||
  { echo "FAIL: the last progressive image is not valid: $(cat "$tmp/info")"; fail=1; }
no_temp "progressive"

[[ $fail -eq 0 ]] && echo ok
exit $fail
