#!/usr/bin/env bash
# render writes every format; compare reads them back and its metrics are
# exact for an image against itself. Args: LUCENT_BINARY SOURCE_DIR
set -eu
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"

"$lucent" render "$src/scenes/smoke_glow.json" --size 24x18 -o "$tmp/a.exr" 2>/dev/null
"$lucent" render "$src/scenes/smoke_glow.json" --size 24x18 -o "$tmp/a.pfm" 2>/dev/null
"$lucent" render "$src/scenes/smoke_glow.json" --size 24x18 -o "$tmp/a.png" 2>/dev/null
for f in a.exr a.pfm a.png; do [[ -s $tmp/$f ]] || { echo "FAIL: $f not written"; exit 1; }; done

# EXR and PFM hold the same floats: zero error.
"$lucent" compare "$tmp/a.pfm" "$tmp/a.exr" --json >"$tmp/m.json"
grep -q '"rel_l2": 0,' "$tmp/m.json" || { echo "FAIL: EXR vs PFM differ: $(cat "$tmp/m.json")"; exit 1; }

# A different quality setting gives a small but non-zero error, and the
# threshold flag turns it into exit status 3.
"$lucent" render "$src/scenes/smoke_glow.json" --size 24x18 --set reference.max_depth=0 --set reference.steps=0.5 -o "$tmp/b.exr" 2>/dev/null
"$lucent" compare "$tmp/b.exr" "$tmp/a.exr" -o "$tmp/diff.png" >"$tmp/m.txt"
rel=$(awk '/^rel_l2/ {print $2}' "$tmp/m.txt")
awk -v r="$rel" 'BEGIN { exit !(r > 0 && r < 0.05) }' || { echo "FAIL: rel_l2 $rel not in (0, 0.05)"; exit 1; }
[[ -s $tmp/diff.png ]] || { echo "FAIL: no diff image"; exit 1; }
set +e
"$lucent" compare "$tmp/b.exr" "$tmp/a.exr" --max-rel-l2 0 >/dev/null 2>&1
rc=$?
set -e
[[ $rc -eq 3 ]] || { echo "FAIL: --max-rel-l2 exit $rc, expected 3"; exit 1; }

# info reads what render wrote.
"$lucent" info "$tmp/a.exr" | grep -q "image     24 x 18" || { echo "FAIL: info on exr"; exit 1; }
echo ok
