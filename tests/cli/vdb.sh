#!/usr/bin/env bash
# .vdb input from the command line: `lucent info` reads a .vdb, a scene
# reading a .vdb renders bit for bit what the scene reading its .nvdb twin
# (nanovdb_convert's) renders, and bad .vdb input or a missing converter
# gets one line naming the file and exit status 1. The files come from
# lu_vdb_gen (tests/vdb_gen.cpp) in the build folder, the working folder.
# Args: LUCENT_BINARY SOURCE_DIR
set -u
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
if [[ ! -x ./lu_vdb_gen ]]; then
  echo "skipped: built without libopenvdb-dev (no lu_vdb_gen, no converter)"
  exit 77
fi
./lu_vdb_gen "$tmp" || { echo "FAIL: lu_vdb_gen"; exit 1; }

expect 0 "" -- "$lucent" info "$tmp/fog.vdb"
grep -q 'grid      "temperature" 4 x 1 x 1 voxels' "$tmp/out" || { echo "FAIL: info fog.vdb: $(cat "$tmp/out")"; fail=1; }

scene() {
  cat <<JSON
{"camera": {"position": [0.1, 0.3, 3], "look_at": [0.05, 0, 0.05], "fov_y_deg": 35, "width": 40, "height": 32},
 "lights": [{"type": "point", "position": [2, 2, 2], "intensity": [30, 30, 30]}],
 "media": [{"density": {"file": "$1", "grid": "density"}, "sigma_s": [3, 2.5, 2], "sigma_a": [0.3, 0.4, 0.5],
            "phase_g": 0.3}]}
JSON
}
if command -v nanovdb_convert >/dev/null; then
  nanovdb_convert -f "$tmp/twin.vdb" "$tmp/twin.nvdb" >/dev/null || { echo "FAIL: nanovdb_convert"; fail=1; }
  scene twin.vdb >"$tmp/a.json"
  scene twin.nvdb >"$tmp/b.json"
  for method in reference raymarch; do
    "$lucent" render "$tmp/a.json" --method "$method" -o "$tmp/a.pfm" 2>"$tmp/err" ||
      { echo "FAIL: render .vdb with $method: $(cat "$tmp/err")"; fail=1; }
    "$lucent" render "$tmp/b.json" --method "$method" -o "$tmp/b.pfm" 2>"$tmp/err" ||
      { echo "FAIL: render .nvdb with $method: $(cat "$tmp/err")"; fail=1; }
    cmp -s "$tmp/a.pfm" "$tmp/b.pfm" || { echo "FAIL: $method: the .vdb and .nvdb scenes differ"; fail=1; }
  done
else
  echo "note: nanovdb_convert not installed, render comparison skipped"
fi

head -c 3000 /dev/urandom >"$tmp/junk.vdb"
scene junk.vdb >"$tmp/junk.json"
expect 1 "junk.vdb" -- "$lucent" render "$tmp/junk.json" -o "$tmp/c.png"
expect 1 "\$.media[0].density" -- "$lucent" render "$tmp/junk.json" -o "$tmp/c.png"
scene fog.vdb | sed 's/"density"}/"nope"}/' >"$tmp/nope.json"
expect 1 "no grid named \"nope\"" -- "$lucent" render "$tmp/nope.json" -o "$tmp/c.png"
head -c 700 "$tmp/tiny_zip.vdb" >"$tmp/cut.vdb"
expect 1 "cut.vdb" -- "$lucent" info "$tmp/cut.vdb"
expect 1 "no/such/convert" -- env LUCENT_VDB_CONVERTER=/no/such/convert "$lucent" info "$tmp/twin.vdb"
[[ ! -e $tmp/c.png ]] || { echo "FAIL: a failed render left c.png"; fail=1; }
exit $fail
