#!/usr/bin/env bash
# Bad input gets one clear line and a non-zero exit, never a crash or a
# half-written file. Args: LUCENT_BINARY SOURCE_DIR
set -u
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
cat >"$tmp/unknown_key.json" <<'JSON'
{"camera": {"position": [0,0,5], "look_at": [0,0,0], "width": 8, "height": 8},
 "lights": [{"type": "point", "position": [0,0,0], "intensity": 1, "radius": 2}],
 "media": []}
JSON
printf '{"camera": {"position": [0,0,5],\n "look_at": [0,0,0]\n' >"$tmp/truncated.json"

expect_usage_lenient 2 "usage" -- "$lucent"
expect_usage_lenient 2 "unknown command" -- "$lucent" paint
expect_usage_lenient 2 "missing -o" -- "$lucent" render "$src/scenes/demo.json"
expect_usage_lenient 2 "cannot tell the image format" -- "$lucent" render "$src/scenes/demo.json" -o "$tmp/x.bmp"
expect_usage_lenient 2 "unknown or incomplete option" -- "$lucent" render "$src/scenes/demo.json" --fast -o "$tmp/x.png"
expect_usage_lenient 1 "\$.lights[0].radius" -- "$lucent" render "$tmp/unknown_key.json" -o "$tmp/a.png"
expect_usage_lenient 1 "truncated.json:3:" -- "$lucent" render "$tmp/truncated.json" -o "$tmp/b.png"
expect_usage_lenient 1 "no/such/scene.json" -- "$lucent" render no/such/scene.json -o "$tmp/c.png"
expect_usage_lenient 1 "no method named \"magic\"" -- "$lucent" render "$src/scenes/demo.json" --method magic -o "$tmp/d.png"
expect_usage_lenient 1 "has no such parameter" -- "$lucent" render "$src/scenes/demo.json" --set reference.quality=3 -o "$tmp/e.png"
expect_usage_lenient 1 "outside" -- "$lucent" render "$src/scenes/demo.json" --set reference.spp=0 -o "$tmp/f.png"
expect_usage_lenient 1 "no/such/dir/out.png" -- "$lucent" render "$src/scenes/demo.json" --size 4x3 -o no/such/dir/out.png
expect_usage_lenient 1 "no-such.exr" -- "$lucent" compare "$tmp/no-such.exr" "$tmp/no-such2.exr"
expect_usage_lenient 1 "cannot open" -- "$lucent" info "$tmp/missing.ply"

# No failed command left any file behind (final or temporary).
leftover=$(ls "$tmp" | grep -v -E '^(out|err|unknown_key.json|truncated.json)$' || true)
if [[ -n $leftover ]]; then
  echo "FAIL: files left behind by failed commands: $leftover"
  fail=1
fi

# --help works everywhere and exits 0.
for cmd in render compare bench info methods; do
  expect_usage_lenient 0 "" -- "$lucent" "$cmd" --help
  grep -q "usage: lucent $cmd" "$tmp/out" || { echo "FAIL: $cmd --help prints no usage"; fail=1; }
done
exit $fail
