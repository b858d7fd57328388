#!/usr/bin/env bash
# The GPU backend from the command line: `info --gpu` names a 4.5 context;
# LUCENT_GPU narrows the device kind, LUCENT_GPU_DEVICE picks a device; a forced --backend gpu without a usable
# GPU fails with one clear line (exit 1), --backend auto falls back to the CPU
# with a note and the same image; methods without a GPU path say so; auto
# means a hardware GPU, else the CPU (never llvmpipe), with one note line.
# Args: LUCENT_BINARY SOURCE_DIR
set -u
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
scene=$src/scenes/smoke_glow.json

# A build without the GPU backend cannot run this: skipped (exit 77), not passed.
if "$lucent" info --gpu 2>&1 | grep -q "built without GPU support"; then
  echo "skipped: this lucent was built without the GPU backend"; exit 77
fi
"$lucent" info --gpu >"$tmp/info.txt" 2>&1 || { cat "$tmp/info.txt"; fail "info --gpu"; }
grep -q "^version .*4\.[5-9]" "$tmp/info.txt" || { cat "$tmp/info.txt"; fail "no 4.5 version line"; }
grep -q "^renderer " "$tmp/info.txt" || fail "no renderer line"
grep -q "^max work groups" "$tmp/info.txt" || fail "no limits"
# auto is the GPU exactly when a hardware context can be made
if LUCENT_GPU=hardware "$lucent" info --gpu >/dev/null 2>&1; then
  grep -q "^backend auto  *gpu" "$tmp/info.txt" || { cat "$tmp/info.txt"; fail "info: auto should be gpu"; }
else
  grep -q "^backend auto  *cpu (no hardware GPU)" "$tmp/info.txt" || { cat "$tmp/info.txt"; fail "info: auto should be cpu"; }
fi
LUCENT_GPU=software "$lucent" info --gpu | grep -q "(software)" || fail "LUCENT_GPU=software did not give a software renderer"

# An unknown LUCENT_GPU value is an error naming the variable.
LUCENT_GPU=bogus "$lucent" render "$scene" --method raymarch --backend gpu --size 16x12 -o "$tmp/x.png" 2>"$tmp/e.txt"
[[ $? == 1 ]] || fail "LUCENT_GPU=bogus: expected exit 1"
grep -q 'LUCENT_GPU="bogus"' "$tmp/e.txt" || { cat "$tmp/e.txt"; fail "LUCENT_GPU=bogus message"; }

# LUCENT_GPU_DEVICE picks one EGL device by its index; out of range or not a
# number is an error naming the variable.
LUCENT_GPU_DEVICE=0 "$lucent" info --gpu | grep -q "^device  *EGL device 0" || fail "LUCENT_GPU_DEVICE=0"
LUCENT_GPU_DEVICE=15 "$lucent" info --gpu >/dev/null 2>"$tmp/e.txt"
[[ $? == 1 ]] || fail "LUCENT_GPU_DEVICE=15: expected exit 1"
grep -q "LUCENT_GPU_DEVICE=15 but there are" "$tmp/e.txt" || { cat "$tmp/e.txt"; fail "LUCENT_GPU_DEVICE=15 message"; }
LUCENT_GPU_DEVICE=x "$lucent" info --gpu >/dev/null 2>"$tmp/e.txt"
[[ $? == 1 ]] || fail "LUCENT_GPU_DEVICE=x: expected exit 1"
grep -q 'LUCENT_GPU_DEVICE="x"' "$tmp/e.txt" || { cat "$tmp/e.txt"; fail "LUCENT_GPU_DEVICE=x message"; }

# No EGL driver at all (glvnd finds no vendor): exit 1, one line, no crash.
__EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent.json "$lucent" render "$scene" --method raymarch --backend gpu \
  --size 16x12 -o "$tmp/x.png" 2>"$tmp/e.txt"
[[ $? == 1 ]] || fail "no EGL: expected exit 1"
grep -q "error: gpu: no EGL display" "$tmp/e.txt" || { cat "$tmp/e.txt"; fail "no EGL message"; }
[[ -e $tmp/x.png ]] && fail "a failed render left an output file"

# Forced hardware on a machine without one: exit 1 naming why; auto falls back.
if grep -q "(software)" "$tmp/info.txt"; then
  LUCENT_GPU=hardware "$lucent" render "$scene" --method raymarch --backend gpu --size 16x12 -o "$tmp/x.png" 2>"$tmp/e.txt"
  [[ $? == 1 ]] || fail "LUCENT_GPU=hardware without hardware: expected exit 1"
  grep -q "hardware requested" "$tmp/e.txt" || { cat "$tmp/e.txt"; fail "hardware message"; }
  LUCENT_QUIET=1 LUCENT_GPU=hardware "$lucent" render "$scene" --method raymarch --backend auto --size 16x12 \
    -o "$tmp/auto.pfm" 2>"$tmp/e.txt" || { cat "$tmp/e.txt"; fail "--backend auto did not fall back"; }
  grep -q "note: --backend auto: no hardware GPU" "$tmp/e.txt" || { cat "$tmp/e.txt"; fail "no fallback note"; }
  grep -q "on cpu" "$tmp/e.txt" || fail "fallback did not say cpu"
  LUCENT_QUIET=1 "$lucent" render "$scene" --method raymarch --size 16x12 -o "$tmp/cpu.pfm" 2>/dev/null || fail "cpu render"
  cmp -s "$tmp/auto.pfm" "$tmp/cpu.pfm" || fail "fallback image differs from the CPU image"
fi

# A method without a GPU path.
"$lucent" render "$scene" --method reference --backend gpu --size 16x12 -o "$tmp/x.png" 2>"$tmp/e.txt"
[[ $? == 1 ]] || fail "reference on gpu: expected exit 1"
grep -q "does not run on the gpu backend" "$tmp/e.txt" || { cat "$tmp/e.txt"; fail "reference gpu message"; }
"$lucent" render "$scene" --method raymarch --backend tpu -o "$tmp/x.png" 2>/dev/null
[[ $? == 2 ]] || fail "--backend tpu: expected usage exit 2"

# --backend auto: with only a software rasteriser (this machine, CI) it is the
# CPU, said in exactly one note line, and the image is the CPU's bit for bit;
# on a hardware GPU it runs there and equals the CPU image within the
# cross-backend tolerance. --backend gpu still takes llvmpipe.
LUCENT_QUIET=1 "$lucent" render "$scene" --method raymarch --backend auto --size 24x16 -o "$tmp/a.pfm" 2>"$tmp/e.txt" || fail "auto render"
LUCENT_QUIET=1 "$lucent" render "$scene" --method raymarch --size 24x16 -o "$tmp/c.pfm" 2>/dev/null || fail "cpu render"
if grep -q "(software)" "$tmp/info.txt"; then
  [[ $(grep -c "note: --backend auto: no hardware GPU" "$tmp/e.txt") == 1 ]] || { cat "$tmp/e.txt"; fail "auto: one note line"; }
  [[ $(grep -c "note" "$tmp/e.txt") == 1 ]] || { cat "$tmp/e.txt"; fail "auto: more than one note"; }
  grep -q "with raymarch on cpu" "$tmp/e.txt" || { cat "$tmp/e.txt"; fail "auto without hardware did not run on cpu"; }
  cmp -s "$tmp/a.pfm" "$tmp/c.pfm" || fail "auto image differs from the CPU image"
  LUCENT_QUIET=1 "$lucent" render "$scene" --method raymarch --backend gpu --size 24x16 -o "$tmp/g.pfm" 2>"$tmp/e.txt" \
    || { cat "$tmp/e.txt"; fail "--backend gpu on the software rasteriser"; }
  grep -q "with raymarch on gpu" "$tmp/e.txt" || { cat "$tmp/e.txt"; fail "--backend gpu did not run on gpu"; }
else
  grep -q "with raymarch on gpu" "$tmp/e.txt" || { cat "$tmp/e.txt"; fail "auto with a hardware GPU did not run on gpu"; }
  "$lucent" compare "$tmp/a.pfm" "$tmp/c.pfm" | awk '$1 == "rel_l2" { exit !($2 <= 1e-3) }' || fail "auto vs cpu"
fi
# A method without a GPU path: auto is the CPU, with no note about GPUs.
LUCENT_QUIET=1 "$lucent" render "$scene" --method reference --backend auto --size 8x6 \
  -o "$tmp/r.pfm" 2>"$tmp/e.txt" || { cat "$tmp/e.txt"; fail "auto reference"; }
grep -q "note" "$tmp/e.txt" && { cat "$tmp/e.txt"; fail "auto reference: a note for a CPU-only method"; }
grep -q "with reference on cpu" "$tmp/e.txt" || fail "auto reference not on cpu"
echo ok
