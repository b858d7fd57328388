#!/usr/bin/env bash
# Distributed rendering (docs/distributed.md) under the Open MPI that
# scripts/setup.sh installs, on loopback only (shared memory between the
# ranks of this machine), every launch bounded by `timeout`:
# - pathtrace with 2 and 3 ranks writes the very bytes one process writes;
# - one-shot methods by bands from the work queue (bssrdf: a light pass and
#   16-pixel tiles; raymarch: maps and a view march) the same;
# - a sequence's frames, taken by the ranks in turn, the same;
# - bench over two scenes merges both ranks' rows on rank 0, in scene order;
# - a rank that fails (its scene is missing) and a rank that dies (SIGSEGV)
#   each end the whole job: a non-zero exit, a message, no output, no hang.
# Args: LUCENT_BINARY SOURCE_DIR; LU_MPIEXEC from CMake (absent: skipped)
set -u
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
[ -n "${LU_MPIEXEC:-}" ] || { echo "skipped: built without MPI"; exit 77; }
# The launch options below are Open MPI's (the MPI scripts/setup.sh installs).
"$LU_MPIEXEC" --version 2>/dev/null | grep -qiE "open ?mpi|open-mpi|OpenRTE" ||
  { echo "skipped: $LU_MPIEXEC is not Open MPI's launcher"; exit 77; }
# CI runs as root, which mpirun refuses without these.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
# Open MPI's own libraries leave memory at MPI_Finalize; leak checks (the
# ASan build) judge lucent's code in every other test.
export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0"
# self + vader: ranks on this machine only, over shared memory (no single-
# copy mechanism: containers often forbid the ptrace it needs).
mpi() {
  timeout -k 5 ${MPI_TIMEOUT:-120} "$LU_MPIEXEC" --oversubscribe --bind-to none --mca btl self,vader \
    --mca btl_vader_single_copy_mechanism none "$@"
}
scene=$src/scenes/layered_cube.json

same() { # NAME ARGS... : one process, then 2 and 3 ranks, and 2 ranks by
          # bands of 5 rows (bssrdf: tiles cut by bands), byte for byte
  local name=$1; shift
  "$lucent" render "$@" -o "$tmp/$name-1.pfm" 2>"$tmp/err.txt" || { echo "FAIL: $name single"; cat "$tmp/err.txt"; fail=1; return; }
  for job in 2 3 "2 --band-rows 5"; do
    local n=${job%% *} extra=()
    [ "$job" = "$n" ] || extra=(${job#* })
    if ! mpi -n $n "$lucent" render "$@" "${extra[@]}" -o "$tmp/$name-$n.pfm" >"$tmp/out.txt" 2>&1; then
      echo "FAIL: $name with $job ranks failed"; cat "$tmp/out.txt"; fail=1; continue
    fi
    cmp -s "$tmp/$name-1.pfm" "$tmp/$name-$n.pfm" || { echo "FAIL: $name: $job ranks wrote other bytes than one process"; fail=1; }
    grep -q "rank $((n - 1)) of $n: " "$tmp/out.txt" || { echo "FAIL: $name: no report of rank $((n - 1))"; cat "$tmp/out.txt"; fail=1; }
    ls "$tmp"/*.tmp.* >/dev/null 2>&1 && { echo "FAIL: $name: a temporary file stayed"; fail=1; }
  done
}
same pathtrace "$scene" --method pathtrace --size 64x64 --set pathtrace.spp=4
same bssrdf "$src/scenes/bssrdf_spheres.json" --method bssrdf --size 64x64 --set bssrdf.splats=256 \
  --set bssrdf.map_res=48 --set bssrdf.table_size=64 --set bssrdf.prefilter=2
same raymarch "$src/scenes/demo.json" --method raymarch --size 64x40

# A sequence: the ranks take the frames in turn and rank 0 writes them all,
# each the bytes of one process's frame (a renderer that skips frames
# renders each as a fresh one would).
seq=("$src/scenes/smoke_plume.json" --method raymarch --size 32x32 --frame-range 0-4)
"$lucent" render "${seq[@]}" -o "$tmp/seq1_##.pfm" 2>/dev/null || { echo "FAIL: sequence single"; fail=1; }
for n in 2 3; do
  if mpi -n $n "$lucent" render "${seq[@]}" -o "$tmp/seq${n}_##.pfm" >"$tmp/out.txt" 2>&1; then
    for f in 00 01 02 03 04; do
      cmp -s "$tmp/seq1_$f.pfm" "$tmp/seq${n}_$f.pfm" || { echo "FAIL: sequence: frame $f with $n ranks differs"; fail=1; }
    done
    grep -q "frame 4, .*(rank $((4 % n)))" "$tmp/out.txt" || { echo "FAIL: sequence: frame 4 not from rank $((4 % n))"; cat "$tmp/out.txt"; fail=1; }
  else
    echo "FAIL: sequence with $n ranks"; cat "$tmp/out.txt"; fail=1
  fi
done

# bench: two scenes, one per rank; the merged table lists the rows of one
# process, scene by scene.
b=(bench "$src/scenes/demo.json" "$scene" --methods raymarch,afm --size 32x32 --frames 1 --warmup 0 --no-truth --no-yardstick)
"$lucent" "${b[@]}" --csv "$tmp/b1.csv" >/dev/null 2>&1 || { echo "FAIL: bench single"; fail=1; }
if mpi -n 2 "$lucent" "${b[@]}" --csv "$tmp/b2.csv" >"$tmp/out.txt" 2>&1; then
  for r in 0 1; do grep -q "rank $r of 2: " "$tmp/out.txt" || { echo "FAIL: bench: rank $r took no scene"; cat "$tmp/out.txt"; fail=1; }; done
  cut -d, -f1-3,15,16 "$tmp/b1.csv" >"$tmp/k1"
  cut -d, -f1-3,15,16 "$tmp/b2.csv" >"$tmp/k2"
  cmp -s "$tmp/k1" "$tmp/k2" || { echo "FAIL: bench: merged rows differ from one process's"; diff "$tmp/k1" "$tmp/k2"; fail=1; }
else
  echo "FAIL: bench with 2 ranks"; cat "$tmp/out.txt"; fail=1
fi

# A command that divides nothing says so rather than running twice.
if mpi -n 2 "$lucent" compare "$tmp/raymarch-1.pfm" "$tmp/raymarch-1.pfm" >"$tmp/out.txt" 2>&1; then
  echo "FAIL: compare ran in a job of 2"; fail=1
fi
grep -q "divides no work" "$tmp/out.txt" || { echo "FAIL: compare in a job: no message"; cat "$tmp/out.txt"; fail=1; }

# Failure: rank 1's scene is missing (MPMD launch: one binary, two
# command lines). The job must end, not wait for rank 1's bands.
args=(render "$scene" --method pathtrace --size 64x64 --set pathtrace.spp=64)
t0=$(date +%s)
mpi -n 1 "$lucent" "${args[@]}" -o "$tmp/f.pfm" : -n 1 "$lucent" render "$tmp/missing.json" -o "$tmp/f.pfm" \
  >"$tmp/out.txt" 2>&1
rc=$?
[ $rc -ne 0 ] && [ $rc -ne 124 ] && [ $rc -ne 137 ] || { echo "FAIL: a failing rank: exit $rc (0: no failure; 124/137: hung)"; fail=1; }
grep -q "error (rank 1 of 2): .*missing.json" "$tmp/out.txt" || { echo "FAIL: a failing rank: no message naming it"; cat "$tmp/out.txt"; fail=1; }
grep -q "ending the whole job" "$tmp/out.txt" || { echo "FAIL: a failing rank: the job's end is not said"; cat "$tmp/out.txt"; fail=1; }
ls "$tmp"/f.pfm* >/dev/null 2>&1 && { echo "FAIL: a failing rank left an output"; ls "$tmp"; fail=1; }

# Death: rank 1 is killed by SIGSEGV while it renders (exec keeps the pid
# mpirun started, so the rank itself dies, not a shell around it). The
# render is far longer than the second before the kill (minutes of passes),
# so the rank is always still rendering when it dies.
rm -f "$tmp/pid"
long=(render "$scene" --method pathtrace --size 64x64 --set pathtrace.spp=100000)
mpi -n 1 "$lucent" "${long[@]}" -o "$tmp/d.pfm" : \
  -n 1 bash -c 'echo $$ >"$0/pid.tmp" && mv "$0/pid.tmp" "$0/pid" && exec "$@"' "$tmp" "$lucent" "${long[@]}" -o "$tmp/d.pfm" \
  >"$tmp/out.txt" 2>&1 &
job=$!
for _ in $(seq 100); do [ -f "$tmp/pid" ] && break; sleep 0.1; done
sleep 1
[ -f "$tmp/pid" ] && kill -SEGV "$(cat "$tmp/pid")"
wait $job
rc=$?
[ $rc -ne 0 ] && [ $rc -ne 124 ] && [ $rc -ne 137 ] || { echo "FAIL: a dying rank: exit $rc (0: it did not die; 124/137: hung)"; fail=1; }
# mpirun names the signal; under ASan, its handler reports the SEGV first
# and exits non-zero, which ends the job the same way.
grep -qi "signal 11\|segmentation\|AddressSanitizer: SEGV" "$tmp/out.txt" || { echo "FAIL: a dying rank: no message"; cat "$tmp/out.txt"; fail=1; }
ls "$tmp"/d.pfm* >/dev/null 2>&1 && { echo "FAIL: a dying rank left an output"; ls "$tmp"; fail=1; }
echo "failure cases took $(( $(date +%s) - t0 )) s"
[ $fail -eq 0 ] && echo "ok"
exit $fail
