#!/usr/bin/env bash
# export-grid writes a medium's grid under its world map: a scene that reads
# the exported .nvdb (no transform) renders the same image as the scene that
# made the grid through a rotated, scaled, shifted transform. Bad input gets
# one line and a non-zero exit, and leaves no file. Args: LUCENT_BINARY SOURCE_DIR
set -u
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

cat >"$tmp/src.json" <<'JSON'
{"camera": {"position": [0.4, 0.6, 4], "look_at": [0, 0, 0], "fov_y_deg": 40, "width": 24, "height": 20},
 "lights": [{"type": "point", "position": [2, 2, 2], "intensity": [20, 20, 20]}],
 "media": [{"density": {"constant": 1}, "sigma_s": [1, 1, 1], "sigma_a": [0.1, 0.1, 0.1],
            "boundary": {"mesh": {"procedural": "sphere", "radius": 0.3}}},
           {"density": {"procedural": "gaussians", "size": [2, 1.5, 1], "resolution": 20, "count": 5, "seed": 4},
            "transform": {"translate": [0.2, -0.1, 0.3], "rotate_deg": [10, 35, -20], "scale": 1.3},
            "sigma_s": [0.9, 0.8, 0.7], "sigma_a": [0.1, 0.2, 0.3], "phase_g": 0.2}]}
JSON
# The same scene with medium 1 read from the exported file.
sed 's|{"procedural": "gaussians"[^}]*}|{"file": "grid.nvdb"}|; s|"transform": {[^}]*},||' "$tmp/src.json" >"$tmp/from_file.json"
grep -q '"file": "grid.nvdb"' "$tmp/from_file.json" && ! grep -q transform "$tmp/from_file.json" ||
  { echo "FAIL: could not write the file-based scene"; exit 1; }

"$lucent" export-grid "$tmp/src.json" --medium 1 -o "$tmp/grid.nvdb" >"$tmp/out" 2>"$tmp/err" ||
  { echo "FAIL: export-grid: $(cat "$tmp/err")"; exit 1; }
grep -q "sigma_s 0.9 0.8 0.7, sigma_a 0.1 0.2 0.3, g 0.2" "$tmp/out" || { echo "FAIL: export line: $(cat "$tmp/out")"; fail=1; }
# The voxel size is the generator's side / resolution times the scale: 2 / 20 * 1.3.
grep -q "voxel 0.13 x 0.13 x 0.13" "$tmp/out" || { echo "FAIL: voxel size: $(cat "$tmp/out")"; fail=1; }

"$lucent" render "$tmp/src.json" -o "$tmp/a.exr" 2>/dev/null || { echo "FAIL: render src"; exit 1; }
"$lucent" render "$tmp/from_file.json" -o "$tmp/b.exr" 2>/dev/null || { echo "FAIL: render from file"; exit 1; }
rel=$("$lucent" compare "$tmp/b.exr" "$tmp/a.exr" | awk '$1 == "rel_l2" { print $2 }')
# Only float rounding of the composed maps may differ (the file's grid starts at its first active voxel).
awk -v r="$rel" 'BEGIN { exit !(r < 1e-5) }' || { echo "FAIL: exported grid renders rel_l2 $rel off"; fail=1; }
# And medium 1 matters: without its scattering the image is far off.
sed 's|"sigma_s": \[0.9, 0.8, 0.7\]|"sigma_s": [0, 0, 0]|' "$tmp/from_file.json" >"$tmp/empty.json"
"$lucent" render "$tmp/empty.json" -o "$tmp/c.exr" 2>/dev/null || { echo "FAIL: render empty"; exit 1; }
rel=$("$lucent" compare "$tmp/c.exr" "$tmp/a.exr" | awk '$1 == "rel_l2" { print $2 }')
awk -v r="$rel" 'BEGIN { exit !(r > 0.05) }' || { echo "FAIL: medium 1 changes the image by only $rel"; fail=1; }
rm -f "$tmp"/*.exr "$tmp/empty.json"

expect 0 "" -- "$lucent" export-grid --help
grep -q "usage: lucent export-grid" "$tmp/out" || { echo "FAIL: export-grid --help prints no usage"; fail=1; }
expect 2 "missing -o" -- "$lucent" export-grid "$tmp/src.json"
expect 2 "missing SCENE.json" -- "$lucent" export-grid -o "$tmp/x.nvdb"
expect 2 "must end in .nvdb" -- "$lucent" export-grid "$tmp/src.json" -o "$tmp/x.vdb"
expect 2 "--medium takes an index" -- "$lucent" export-grid "$tmp/src.json" --medium one -o "$tmp/x.nvdb"
expect 2 "--medium takes an index" -- "$lucent" export-grid "$tmp/src.json" --medium -1 -o "$tmp/x.nvdb"
expect 1 "src.json has 2 media; there is no medium 2" -- "$lucent" export-grid "$tmp/src.json" --medium 2 -o "$tmp/x.nvdb"
expect 1 "medium 0 has a constant density" -- "$lucent" export-grid "$tmp/src.json" -o "$tmp/x.nvdb"
expect 1 "no/such.json" -- "$lucent" export-grid "$tmp/no/such.json" -o "$tmp/x.nvdb"
expect 1 "no/dir/x.nvdb" -- "$lucent" export-grid "$tmp/src.json" --medium 1 -o "$tmp/no/dir/x.nvdb"

leftover=$(ls "$tmp" | grep -v -E '^(out|err|src.json|from_file.json|grid.nvdb)$' || true)
[[ -z $leftover ]] || { echo "FAIL: files left behind by failed commands: $leftover"; fail=1; }
[[ $fail -eq 0 ]] && echo ok
exit $fail
