#!/usr/bin/env bash
# Runs every libFuzzer target for FUZZ_SECONDS (default 60) seconds, or until
# FUZZ_RUNS executions if that is set and comes first, under ASan+UBSan,
# starting from the committed corpus (fuzz/corpus/<target>/);
# what a run adds to the corpus goes to out/fuzz/<target>/ (merge the small,
# new files into fuzz/corpus by hand with -merge=1). Prints, per target, the
# executions, the edge coverage and whether it crashed. clang and its fuzzer
# runtime are installed here (as root), not by `make test`.
# Usage: scripts/fuzz.sh [TARGET...]   (env FUZZ_SECONDS, FUZZ_RUNS, JOBS)
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${FUZZ_SECONDS:-60}
[[ $seconds =~ ^[0-9]+$ && $seconds -ge 1 ]] || { echo "fuzz: FUZZ_SECONDS must be a positive integer" >&2; exit 2; }
runs=${FUZZ_RUNS:--1}
[[ $runs == -1 || ( $runs =~ ^[0-9]+$ && $runs -ge 1 ) ]] || { echo "fuzz: FUZZ_RUNS must be a positive integer" >&2; exit 2; }
need=()
command -v clang >/dev/null || need+=(clang)
dpkg-query -W -f='${Status}' libclang-rt-14-dev 2>/dev/null | grep -q "install ok installed" || need+=(libclang-rt-14-dev)
if ((${#need[@]})); then
  if [[ $(id -u) -eq 0 ]]; then
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${need[@]}" >/dev/null
  else
    echo "fuzz: missing Debian packages. Run: sudo apt-get install -y ${need[*]}" >&2
    exit 1
  fi
fi
build=${BUILD_FUZZ:-build-fuzz}
cmake -S . -B "$build" -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ -DLUCENT_FUZZ=ON \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
targets=("$@")
((${#targets[@]})) || targets=($(ls fuzz/fuzz_*.c | xargs -n1 basename | sed 's/\.c$//'))
cmake --build "$build" -j "${JOBS:-$(nproc)}" --target "${targets[@]}" -- --no-print-directory >/dev/null
status=0
printf '%-12s %12s %8s %8s %8s  %s\n' target executions exec/s edges seconds result
for t in "${targets[@]}"; do
  mkdir -p "out/fuzz/$t"
  log="out/fuzz/$t.log"
  start=$SECONDS
  set +e
  (cd "out/fuzz" && ASAN_OPTIONS=detect_leaks=1 "../../$build/$t" -max_total_time="$seconds" -runs="$runs" -rss_limit_mb=4096 \
     -timeout=20 -print_final_stats=1 "$t" "../../fuzz/corpus/$t") >"$log" 2>&1
  rc=$?
  set -e
  execs=$(awk '/stat::number_of_executed_units/ {print $2}' "$log" | tail -1)
  speed=$(awk '/stat::average_exec_per_sec/ {print $2}' "$log" | tail -1)
  edges=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | awk '{print $2}')
  result=ok
  [[ $rc -eq 0 ]] || { result="CRASH (see $log)"; status=1; }
  printf '%-12s %12s %8s %8s %8s  %s\n' "$t" "${execs:-?}" "${speed:-?}" "${edges:-?}" "$((SECONDS - start))" "$result"
done
exit $status
