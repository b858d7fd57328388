#!/usr/bin/env bash
# Every method setting, range-checked (docs/reliability.md, "Limits"): for
# each parameter `lucent methods` lists, values outside its stated range
# (below the low end, above the high end, 1e300), NaN, infinities, a word,
# and for choices an unknown name, must each end
# `lucent render` with exit 1 or 2 and a one-line message naming the
# setting, before any work: no crash (exit >= 128), no output file. Also
# the environment variables the CLI reads. The table of what is checked is the output of `lucent methods`.
# Args: LUCENT_BINARY SOURCE_DIR
set -u
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
export LUCENT_QUIET=1
scene=$src/scenes/homogeneous_sphere.json
checked=0

refused() {  # key value: the render must refuse it cleanly
  local key=$1 val=$2 method=${1%%.*}
  rm -f "$tmp/x.png"
  "$lucent" render "$scene" --size 8x8 --method "$method" --set "$key=$val" -o "$tmp/x.png" 2>"$tmp/e.txt"
  local rc=$?
  [[ $rc == 1 || $rc == 2 ]] || { cat "$tmp/e.txt"; fail "$key=$val: exit $rc"; }
  [[ $(wc -l <"$tmp/e.txt") == 1 ]] || { cat "$tmp/e.txt"; fail "$key=$val: not one line"; }
  grep -q -- "$key" "$tmp/e.txt" || { cat "$tmp/e.txt"; fail "$key=$val: the message does not name the setting"; }
  [[ ! -e $tmp/x.png ]] || fail "$key=$val: an output file was written"
  checked=$((checked + 1))
}

"$lucent" methods >"$tmp/methods.txt" || fail "lucent methods"
params=0
while read -r key lo hi; do
  params=$((params + 1))
  refused "$key" nan
  refused "$key" inf
  refused "$key" -inf
  refused "$key" word
  if [[ $lo != choice ]]; then
    below=$(awk -v v="$lo" 'BEGIN { printf "%.17g", v - (v < 0 ? -v : v) - 1 }')
    above=$(awk -v v="$hi" 'BEGIN { printf "%.17g", v + (v < 0 ? -v : v) + 1 }')
    refused "$key" "$below"
    refused "$key" "$above"
    refused "$key" 1e300
  else
    refused "$key" no_such_choice
  fi
done < <(awk '/^    [a-z_]+\.[a-z_0-9]+ = .* in \[/ {
               key = $1; s = $0; sub(/.* in \[/, "", s); sub(/\].*/, "", s); split(s, r, ", ")
               print key, r[1], r[2] }
             /^    [a-z_]+\.[a-z_0-9]+ = [^ ]*\|/ { print $1, "choice", "choice" }' "$tmp/methods.txt")
[[ $params -ge 60 ]] || { cat "$tmp/methods.txt"; fail "only $params parameters parsed from lucent methods"; }

# The environment the CLI reads.
envbad() {  # VAR=value
  env "$1" "$lucent" render "$scene" --size 8x8 --method raymarch -o "$tmp/x.png" 2>"$tmp/e.txt"
  local rc=$?
  [[ $rc == 1 || $rc == 2 ]] || { cat "$tmp/e.txt"; fail "$1: exit $rc"; }
  grep -q -- "${1%%=*}" "$tmp/e.txt" || { cat "$tmp/e.txt"; fail "$1: the message does not name the variable"; }
  checked=$((checked + 1))
}
rm -f "$tmp/x.png"
envbad LUCENT_THREADS=0
envbad LUCENT_THREADS=100000
envbad LUCENT_THREADS=-3
envbad LUCENT_THREADS=two
envbad LUCENT_GPU=fast
envbad LUCENT_GPU_DEVICE=99
envbad LUCENT_GPU_DEVICE=-1
envbad LUCENT_GPU_DEVICE=x
echo "  $params settings and 4 environment variables: $checked bad values refused cleanly"
