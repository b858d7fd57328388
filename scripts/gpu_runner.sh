#!/usr/bin/env bash
# The GPU benchmark at the seeds' settings, run from a carry folder that
# `scripts/bench_gpu.sh --prepare DIR` made (this file is DIR/run.sh there).
# It needs only bash, coreutils, tar/gzip, sed, grep and awk on the machine:
# the binary, its libraries, the scenes and the meshes are in the folder.
#
#   bash DIR/run.sh [--allow-software] [--tiny] [--out OUTDIR] [--limit SECONDS] [--only CASE,...]
#
# 1. Sets up the carried libraries (DIR/env.sh), then checks for a hardware
#    GPU first: `LUCENT_GPU=hardware lucent info --gpu`, recorded verbatim.
#    Without one it refuses (exit 1, no hardware.md) unless --allow-software.
# 2. Runs the cases of DIR/cases.txt in two passes. First, per case, lucent's
#    CPU reference of the view (the truth) and a `lucent bench` of each method
#    on the GPU against it; then each method on the CPU, and the GPU-vs-CPU
#    agreement of the two images, so a slow CPU row never costs a GPU row.
#    Each call has its own time budget, and no call starts once --limit
#    seconds (default 540) have passed, so the run ends within 10 minutes.
# 3. Writes OUTDIR (default $OUT if set, else docs/gpu): hardware.md (the
#    tables), hardware_bench.csv, hardware_agreement.csv, hardware_info.txt
#    (device, driver, machine) and hardware_log.txt (every command's output).
#    hardware.md is rewritten after each case, so a run cut short still
#    leaves what it measured.
# --tiny: each case's tiny size and cheap settings, one frame, 4x the time
# budgets and --limit 1800: a smoke test of the plumbing (on llvmpipe), not a
# measurement.
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
allow_software=0
tiny=0
out=${OUT:-docs/gpu}
limit=
only=
while (($#)); do
  case $1 in
  --allow-software) allow_software=1 ;;
  --tiny) tiny=1 ;;
  --out) out=${2:?--out needs a folder}; shift ;;
  --limit) limit=${2:?--limit needs seconds}; shift ;;
  --only) only=${2:?--only needs case names}; shift ;;
  -h | --help) sed -n '2,/^set -uo/p' "${BASH_SOURCE[0]}" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
  *) echo "run.sh: unknown option '$1' (see --help)" >&2; exit 2 ;;
  esac
  shift
done
# --tiny runs on llvmpipe, where LLVM compiles each shader for tens of seconds
# on a busy machine: each budget x4 and 30 minutes in all.
scale=1
((tiny)) && scale=4
limit=${limit:-$((tiny ? 1800 : 540))}
[[ $limit =~ ^[0-9]+$ ]] || { echo "run.sh: --limit takes whole seconds, got '$limit'" >&2; exit 2; }
start=$SECONDS
mkdir -p "$out" || exit 1
log=$out/hardware_log.txt
info=$out/hardware_info.txt
: >"$log"
work=$(mktemp -d) || exit 1
trap 'rm -rf "$work"' EXIT
say() { echo "run.sh: $*" | tee -a "$log" >&2; }
loadavg() { cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo unknown; }

# shellcheck source=/dev/null
. "$here/env.sh" >>"$log" 2>&1 || { say "setting up the carried libraries failed (see $log)"; exit 1; }
L=$here/bin/lucent
export LUCENT_QUIET=1
export LUCENT_CACHE_DIR=$work/cache

{
  echo "date         $(date -u +%Y-%m-%dT%H:%MZ)"
  echo "command      bash $(basename "$here")/run.sh${*:+ $*}"
  echo "lucent       $(cat "$here/version.txt" 2>/dev/null || "$L" --version 2>&1)"
  echo "cpu          $(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo | head -1), $(nproc) cores available"
  echo "load average $(loadavg) (at start)"
  echo "libraries    $LD_LIBRARY_PATH"
  echo "EGL vendors  ${__EGL_VENDOR_LIBRARY_DIRS:-${__EGL_VENDOR_LIBRARY_FILENAMES:-glvnd defaults}}"
  if command -v nvidia-smi >/dev/null 2>&1; then
    echo "nvidia-smi   $(nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader 2>&1 | head -1)"
  fi
} >"$info"

# The hardware device first, and its answer kept whatever it is.
LUCENT_GPU=hardware "$L" info --gpu >"$work/hw.txt" 2>&1
hw_rc=$?
{
  echo
  echo "## LUCENT_GPU=hardware lucent info --gpu (exit $hw_rc)"
  cat "$work/hw.txt"
} >>"$info"
if ((hw_rc == 0)); then
  export LUCENT_GPU=hardware
  kind=hardware
  cp "$work/hw.txt" "$work/gpu.txt"
elif ((allow_software)); then
  "$L" info --gpu >"$work/gpu.txt" 2>&1 || { say "no GPU context at all: $(tail -1 "$work/gpu.txt")"; exit 1; }
  { echo; echo "## lucent info --gpu (LUCENT_GPU=${LUCENT_GPU:-auto})"; cat "$work/gpu.txt"; } >>"$info"
  kind=software
  say "no hardware GPU ($(tail -1 "$work/hw.txt")); --allow-software: running on $(sed -n 's/^renderer *//p' "$work/gpu.txt")"
else
  say "no hardware GPU: $(tail -1 "$work/hw.txt")"
  say "refusing to write hardware.md on a software device (--allow-software runs anyway); details in $info"
  exit 1
fi
gpu_line() { sed -n "s/^$1  *//p" "$work/gpu.txt" | head -1; }
renderer=$(gpu_line renderer)
say "device: $renderer ($kind)"

bench_csv=$out/hardware_bench.csv
agree_csv=$out/hardware_agreement.csv
cases_run=$work/cases_run.txt
: >"$cases_run"
echo "case,method,rel_l2_gpu_vs_cpu,max_abs_gpu_vs_cpu" >"$agree_csv"
rm -f "$bench_csv"

# budget_for S: S capped by what is left of --limit (0 when too little is left to start).
budget_for() {
  local left=$((limit - (SECONDS - start))) b=$(($1 * scale))
  ((left < b)) && b=$left
  ((b < 10)) && b=0
  echo "$b"
}
# outcome RC SECONDS: the words for a call's end.
outcome() {
  if (($1 == 124 || $1 == 137)); then echo "timed out after $2 s"
  elif (($1 != 0)); then echo "failed (exit $1 after $2 s; hardware_log.txt)"
  else echo "ok ($2 s)"; fi
}
# bench_call CASE METHOD BACKEND BUDGET: one `lucent bench` of one method on one
# backend against the case's truth; its rows go into the CSV with the case's
# columns in front. Prints the outcome.
bench_call() {
  local c=$1 m=$2 backend=$3 budget frames=$frames_gpu
  budget=$(budget_for "$4")
  ((budget)) || { echo "skipped (time limit)"; return; }
  [[ $backend == cpu ]] && frames=$frames_cpu
  local args=("$here/$scene" --methods "$m" --backends "$backend" --size "$size" --frames "$frames"
    --warmup "$warmup" --reference "$img/truth.exr" --save-images "$img" --csv "$work/b.csv" --no-yardstick
    "${set_args[@]}")
  echo "== $c: lucent bench ${args[*]} (budget $budget s)" >>"$log"
  local t0=$SECONDS rc
  rm -f "$work/b.csv"
  timeout -k 5 "$budget" "$L" bench "${args[@]}" >>"$log" 2>&1
  rc=$?
  if ((rc == 0)); then
    [[ -f $bench_csv ]] || echo "case,size,settings,$(head -1 "$work/b.csv")" >"$bench_csv"
    tail -n +2 "$work/b.csv" | sed "s|^|$c,$size,$sets_label,|" >>"$bench_csv"
  fi
  outcome $rc $((SECONDS - t0))
}

report() {
  local f=$out/hardware.md
  {
    if [[ $kind == hardware ]]; then
      echo "# lucent on a hardware GPU: $renderer"
    else
      echo "# lucent GPU benchmark on a software device: $renderer (a smoke test, not a hardware measurement)"
    fi
    echo
    echo "Made by \`bash DIR/run.sh${run_args:+ $run_args}\` in the folder DIR that \`scripts/bench_gpu.sh --prepare DIR\` makes"
    echo "(docs/gpu/README.md). Raw rows: hardware_bench.csv, hardware_agreement.csv; device and machine:"
    echo "hardware_info.txt; every command's output: hardware_log.txt."
    echo
    echo "| | |"
    echo "|---|---|"
    echo "| GPU | $renderer; $(gpu_line vendor); OpenGL $(gpu_line version) |"
    echo "| EGL | $(gpu_line device) |"
    grep '^nvidia-smi' "$info" | sed 's/^nvidia-smi *\(.*\)/| nvidia-smi | \1 |/'
    echo "| hardware check | \`LUCENT_GPU=hardware lucent info --gpu\`: $( ((hw_rc == 0)) && echo ok || echo "exit $hw_rc: $(tail -1 "$work/hw.txt")") |"
    sed -n '/^$/q; s/^cpu  *\(.*\)/| CPU | \1 |/p; s/^lucent  *\(.*\)/| lucent | \1 |/p; s/^date  *\(.*\)/| date | \1 |/p' "$info"
    echo "| load average | $(sed -n 's/^load average \(.*\) (at start)/\1/p' "$info") at start, $(loadavg) now |"
    echo
    echo "## Cases"
    echo
    echo "| case | scene | size | settings | the seed reports |"
    echo "|---|---|---|---|---|"
    awk -F'|' '{ printf "| %s | %s | %s | %s | %s |\n", $1, $2, $3, $4, $5 }' "$cases_run"
    echo
    echo "## Frame times"
    echo
    echo "Median of ${frames_gpu} GPU / ${frames_cpu} CPU frames after ${warmup} warm-up; prepare = the method's set-up before the"
    echo "first frame. rel-L2 is against lucent's CPU \`reference\` of the same view (single scattering: for"
    echo "bssrdf it measures the model gap, not the GPU; bssrdf's truth is \`pathtrace\`, docs/bssrdf.md)."
    echo "GPU vs CPU is the rel-L2 between the two backends' images of the same method."
    echo
    echo "| case | method | backend | prepare ms | frame ms | fps | rel-L2 vs reference | GPU vs CPU |"
    echo "|---|---|---|---|---|---|---|---|"
    if [[ -f $bench_csv ]]; then
      awk -F, 'NR == FNR { if (FNR > 1) agree[$1 "," $2] = $3; next }
        FNR == 1 { for (i = 1; i <= NF; i++) col[$i] = i; next }
        { ms = $col["frame_ms_median"]; fps = ms > 0 ? sprintf("%.1f", 1000 / ms) : "-"
          g = ($col["backend"] == "gpu" && ($1 "," $col["method"]) in agree) ? agree[$1 "," $col["method"]] : ""
          printf "| %s | %s | %s | %.1f | %.2f | %s | %s | %s |\n", $1, $col["method"], $col["backend"],
                 $col["prepare_ms"], ms, fps, $col["rel_l2"], g }' "$agree_csv" "$bench_csv"
    fi
    echo
    echo "## Calls"
    echo
    echo "| case | outcome of each call |"
    echo "|---|---|"
    local c
    while IFS='|' read -r c _; do echo "| $c | $(cat "$work/status_$c") |"; done <"$cases_run"
    echo
    echo "Total $((SECONDS - start)) s of the ${limit} s limit."
  } >"$f.tmp" && mv "$f.tmp" "$f"
}

cases=$here/cases.txt
run_args="$*"
warmup=1
frames_gpu=5
frames_cpu=3
((tiny)) && { warmup=0; frames_gpu=1; frames_cpu=1; }
# cases.txt, one case a line: name|scene|size|GPU methods|CPU methods|settings|
# reference budget s|budget s per GPU method|budget s per CPU method|the seed's report|tiny size|tiny settings
lines=()
while IFS= read -r line; do
  [[ -z $line || $line == \#* ]] && continue
  [[ -n $only && ",$only," != *",${line%%|*},"* ]] && continue
  lines+=("$line")
done <"$cases"
((${#lines[@]})) || { say "no case in $cases matches '${only}'"; exit 2; }
# use_case LINE: the case's fields as globals (bench_call reads them).
use_case() {
  IFS='|' read -r name scene size gpu_m cpu_m sets ref_budget gpu_budget cpu_budget seed tiny_size tiny_sets <<<"$1"
  if ((tiny)); then size=$tiny_size; sets=$tiny_sets; fi
  sets_label=${sets:-defaults}
  set_args=()
  for kv in $sets; do set_args+=(--set "$kv"); done
  img=$work/img_$name
}
note() { echo -n "$2" >>"$work/status_$1"; }

# Pass 1, the GPU: per case the truth (lucent's CPU reference of the view, which
# every method and backend is judged against), then each method on the GPU.
for line in "${lines[@]}"; do
  use_case "$line"
  echo "$name|$scene|$size|$sets_label|$seed" >>"$cases_run"
  : >"$work/status_$name"
  mkdir -p "$img"
  say "$name: $scene at $size ($sets_label), $((SECONDS - start)) s elapsed"
  budget=$(budget_for "$ref_budget")
  if ((budget)); then
    t0=$SECONDS
    echo "== $name: lucent render $here/$scene --method reference --size $size (budget $budget s)" >>"$log"
    timeout -k 5 "$budget" "$L" render "$here/$scene" --method reference --size "$size" -o "$img/truth.exr" >>"$log" 2>&1
    note "$name" "reference: $(outcome $? $((SECONDS - t0)))"
  else
    note "$name" "reference: skipped (time limit)"
  fi
  if [[ -f $img/truth.exr ]]; then
    for m in ${gpu_m//,/ }; do note "$name" "; $m gpu: $(bench_call "$name" "$m" gpu "$gpu_budget")"; done
  fi
  say "$name: $(cat "$work/status_$name")"
  report
done
# Pass 2, the CPU: the same methods where the GPU made an image, and the
# agreement of the two images. After every GPU row, so a slow CPU costs only itself.
for line in "${lines[@]}"; do
  use_case "$line"
  for m in ${cpu_m//,/ }; do
    [[ -f $img/$m-gpu.exr ]] || continue
    note "$name" "; $m cpu: $(bench_call "$name" "$m" cpu "$cpu_budget")"
    [[ -f $img/$m-cpu.exr ]] || continue
    "$L" compare "$img/$m-gpu.exr" "$img/$m-cpu.exr" >"$work/cmp.txt" 2>>"$log" &&
      awk -v c="$name" -v m="$m" '$1 == "rel_l2" { r = $2 } $1 == "max_abs" { a = $2 }
        END { print c "," m "," r "," a }' "$work/cmp.txt" >>"$agree_csv"
  done
  say "$name: $(cat "$work/status_$name")"
  report
done
say "wrote $out/hardware.md in $((SECONDS - start)) s"
