#!/usr/bin/env bash
# The CLI built without MPI (lucent_nompi, which every build with MPI makes
# too): it renders single-process to the same bytes as the CLI with MPI run
# without a launcher, and under a launcher it says that each rank works alone.
# Args: LUCENT_BINARY SOURCE_DIR; LU_LUCENT_NOMPI from CMake (absent: skipped)
set -eu
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
[ -n "${LU_LUCENT_NOMPI:-}" ] || { echo "skipped: no second CLI built without MPI (this build has no MPI)"; exit 77; }
args=("$src/scenes/demo.json" --method raymarch --size 40x24)
"$LU_LUCENT_NOMPI" render "${args[@]}" -o "$tmp/nompi.pfm" 2>"$tmp/err.txt" || { echo "FAIL: lucent_nompi render"; cat "$tmp/err.txt"; exit 1; }
"$lucent" render "${args[@]}" -o "$tmp/mpi.pfm" 2>/dev/null
cmp -s "$tmp/nompi.pfm" "$tmp/mpi.pfm" || { echo "FAIL: the CLI without MPI renders other bytes"; exit 1; }
# As a launcher's rank (its environment) it still works, alone, and says so.
OMPI_COMM_WORLD_SIZE=2 "$LU_LUCENT_NOMPI" render "${args[@]}" -o "$tmp/rank.pfm" 2>"$tmp/err.txt"
grep -q "built without MPI" "$tmp/err.txt" || { echo "FAIL: no note under a launcher"; cat "$tmp/err.txt"; exit 1; }
cmp -s "$tmp/rank.pfm" "$tmp/mpi.pfm" || { echo "FAIL: the rank alone renders other bytes"; exit 1; }
echo "ok"
