# shellcheck shell=bash disable=SC2034  # lucent, src, tmp, fail: the sourcing script reads them
# What the CLI tests share; each tests/cli/*.sh sources it right after its
# `set` line:
#   source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
# It is not a test itself (CMakeLists.txt leaves it out of the cli_ tests).
# Sourcing it gives the script:
#   lucent, src  its arguments (LUCENT_BINARY SOURCE_DIR, as CMake passes them)
#   tmp          a fresh folder, removed when the script exits
#   fail         0: scripts that report every failed check before they end
#                set it to 1 on a failure and end with `exit $fail`
# and the helpers below. It sets no shell options: each script keeps its own
# `set -u` or `set -eu`.

lucent=$1
src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0

# fail MESSAGE: a fatal check; print it and end the script with exit 1. (The
# variable of the same name is the other style, which goes on.)
fail() { echo "FAIL: $*"; exit 1; }

# The two expect helpers run a command with stdout in $tmp/out and stderr in
# $tmp/err, check its exit status and that NEEDLE ("" for any) is on stderr,
# and on a miss print one FAIL line and set fail=1 (they go on, so they are
# for scripts without set -e). They differ in how many lines a failing
# command may print:
#
# expect CODE NEEDLE -- command...: a failure (CODE != 0) in exactly one line.
expect() { expect_lines_rule every_failure "$@"; }
# expect_usage_lenient CODE NEEDLE -- command...: only exit 1 is held to one
# line at most; a usage error (exit 2) may print the usage after its message.
expect_usage_lenient() { expect_lines_rule exit1_only "$@"; }
expect_lines_rule() {  # RULE CODE NEEDLE -- command...
  local rule=$1 code=$2 needle=$3
  shift 4
  "$@" >"$tmp/out" 2>"$tmp/err"
  local rc=$?
  if [[ $rc -ne $code ]]; then
    echo "FAIL: '$*' exited $rc, expected $code; stderr: $(cat "$tmp/err")"
    fail=1
  elif [[ -n $needle ]] && ! grep -qF -- "$needle" "$tmp/err"; then
    echo "FAIL: '$*' stderr lacks '$needle': $(cat "$tmp/err")"
    fail=1
  elif [[ $rule == every_failure && $code -ne 0 && $(wc -l <"$tmp/err") -ne 1 ]]; then
    echo "FAIL: '$*' printed $(wc -l <"$tmp/err") error lines: $(cat "$tmp/err")"
    fail=1
  elif [[ $rule == exit1_only && $code -eq 1 && $(wc -l <"$tmp/err") -gt 1 ]]; then
    echo "FAIL: '$*' printed more than one error line: $(cat "$tmp/err")"
    fail=1
  fi
}

# csv_col FILE NAME: the 1-based position of column NAME in FILE's header
# (empty when there is none), so checks do not depend on the column order.
csv_col() { head -1 "$1" | tr ',' '\n' | grep -nx "$2" | cut -d: -f1; }

# require_viewer SCENE: a build without the viewer cannot run the test, so it
# is skipped (exit 77), not passed.
require_viewer() {
  if "$lucent" view "$1" 2>&1 | grep -q "built without the viewer"; then
    echo "skipped: this lucent was built without the viewer"; exit 77
  fi
}

# asan_skip_tls_interceptor: for the tests that run the viewer. Under `make
# asan`: LeakSanitizer's __tls_get_addr interceptor (GCC 12's libsanitizer,
# LLVM < 17) takes a dynamic TLS block whose address is 16 mod 4096 for one
# from glibc 2.19-2.24 and reads the 16 bytes before it as that version's
# {size, start} header. glibc >= 2.25 mallocs the blocks, so those bytes are
# ASan's own chunk header and the leak check scans a bogus range (seen: "DTLS
# 11 at 0x1010-0x1800002112", module 11 = libLLVM-15, whose TLS the main
# thread first touches when llvmpipe compiles a shader) and dies with "Tracer
# caught signal 11" at exit. Whether the block lands there depends on the
# heap's history, not on a bug in lucent (docs/gpu.md, "LeakSanitizer tracer
# crash"). On this glibc the interceptor records no usable range for any other
# block either (size 0: "Can't guess glibc version"), so switching it off
# loses no leak coverage. A binary built without ASan ignores ASAN_OPTIONS.
asan_skip_tls_interceptor() {
  export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}intercept_tls_get_addr=0"
}

# have_gpu: whether this lucent was built with the GPU backend. A script's
# GPU comparison is skipped (with a line saying so) in a build without it,
# not counted as passed.
have_gpu() {
  if "$lucent" info --gpu 2>&1 | grep -q "built without GPU support"; then
    echo "  GPU part skipped: this lucent was built without GPU support"
    return 1
  fi
}
