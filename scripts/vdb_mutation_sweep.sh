#!/usr/bin/env bash
# Mutation sweep of the OpenVDB converter (docs/volumes.md, "OpenVDB (.vdb) input"): N mutated
# copies (default 400) of the fuzz seeds tiny_*.vdb (bit flips, bytes set to 0/0xff/0x7f/0x80,
# 4-byte fields set to extreme values; Python random.seed(7)) go through lucent-vdb-convert one
# at a time, each under a 60 s timeout. Prints how many loaded, were refused (by exit status:
# 3 FORMAT, 7 NOMEM), crashed (a signal) or timed out, and the slowest file.
# Usage: scripts/vdb_mutation_sweep.sh [BUILD_DIR] [N]   (default build, 400)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
count=${2:-400}
conv=$build/lucent-vdb-convert
[[ -x $conv ]] || { echo "vdb_mutation_sweep: $conv not built (needs libopenvdb-dev)" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
python3 - "$tmp" "$count" fuzz/corpus/fuzz_vdb/tiny_*.vdb <<'PY'
import random, sys
out, count, paths = sys.argv[1], int(sys.argv[2]), sorted(sys.argv[3:])
random.seed(7)
seeds = [open(p, 'rb').read() for p in paths]
for t in range(count):
    d = bytearray(random.choice(seeds))
    for _ in range(random.choice([1, 1, 2, 4, 8])):
        p = random.randrange(len(d))
        mode = random.random()
        if mode < 0.5:
            d[p] ^= 1 << random.randrange(8)
        elif mode < 0.8:
            d[p] = random.choice([0, 0xff, 0x7f, 0x80])
        else:
            v = random.choice([0xffffffff, 0x7fffffff, 0x80000000, 0x10000000, 1 << 20])
            d[p:p + 4] = v.to_bytes(4, 'little')
    open('%s/s%04d.vdb' % (out, t), 'wb').write(d)
PY
for f in "$tmp"/s*.vdb; do
  start=$(date +%s.%N)
  set +e
  timeout 60 "$conv" "$f" >"$tmp/out.nvdb" 2>/dev/null
  rc=$?
  set -e
  echo "$(basename "$f") $rc $(echo "$(date +%s.%N) - $start" | bc)"
done >"$tmp/log"
awk '{ n[$2]++ } $3 > worst { worst = $3; wf = $1 }
     END { crashed = 0; for (c in n) if (c + 0 > 128 && c != 124) crashed += n[c]
           printf "files %d: loaded %d, FORMAT %d, NOMEM %d, other refusals %d, crashed %d, timed out %d\n",
                  NR, n[0], n[3], n[7], NR - n[0] - n[3] - n[7] - crashed - n[124], crashed, n[124]
           printf "slowest: %s, %.2f s\n", wf, worst }' "$tmp/log"
