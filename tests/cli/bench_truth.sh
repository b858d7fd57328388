#!/usr/bin/env bash
# bench --truth pathtrace: the truth is cached in the cache folder and read
# back bit for bit; its key follows the settings, the scene file and the
# bytes of the data files it names; a damaged cache file is rendered again;
# --reference overrides it; at max_depth 1 it is reference's single
# scattering within its own stated noise. Args: LUCENT_BINARY SOURCE_DIR
set -eu
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
export LUCENT_CACHE_DIR=$tmp/cache
unset LUCENT_QUIET

# A small scene of its own: a raw grid and a PLY floor next to it, so the
# test can change a data file's bytes.
head -c 2048 /dev/zero | tr '\0' '\077' >"$tmp/g.raw"   # 8^3 floats of 0x3f3f3f3f = 0.747
cat >"$tmp/floor.ply" <<'EOF'
ply
format ascii 1.0
element vertex 4
property float x
property float y
property float z
element face 2
property list uchar int vertex_indices
end_header
-3.0 0.0 -3.0
3.0 0.0 -3.0
3.0 0.0 3.0
-3.0 0.0 3.0
3 0 2 1
3 0 3 2
EOF
cat >"$tmp/s.json" <<'EOF'
{"camera": {"position": [0, 1.5, 5], "look_at": [0, 0.8, 0], "fov_y_deg": 40, "width": 32, "height": 18},
 "background": [0.02, 0.02, 0.03],
 "lights": [{"type": "point", "position": [1, 3, 1], "intensity": [30, 30, 30]}],
 "media": [{"density": {"raw": "g.raw", "dims": [8, 8, 8], "voxel_size": 0.2, "origin": [-0.7, 0.1, -0.7]},
            "sigma_s": [6, 6, 6], "sigma_a": [0.3, 0.3, 0.3]}],
 "objects": [{"mesh": "floor.ply", "material": {"type": "diffuse", "albedo": [0.6, 0.6, 0.6]}}]}
EOF
b=(bench "$tmp/s.json" --methods reference,raymarch --frames 1 --warmup 0 --no-yardstick
   --truth pathtrace --set pathtrace.spp=4 --truth-max-spp 256)
rel() { awk -F, -v c="$(csv_col "$1" rel_l2_vs_pathtrace)" -v m="$2" '$2 == m { print $c }' "$1"; }

# 1. Rendered and written to the cache, then read back: the same errors.
"$lucent" "${b[@]}" --csv "$tmp/a.csv" >"$tmp/a.txt" 2>"$tmp/a.log" || fail "first run: $(cat "$tmp/a.log")"
file=$(sed -n 's/^lucent bench: truth written to cache \([^ ]*\) .*/\1/p' "$tmp/a.log")
[[ -n $file && -s $file ]] || fail "no cache file written: $(cat "$tmp/a.log")"
[[ $file == "$tmp/cache/"* ]] || fail "cache file $file is outside LUCENT_CACHE_DIR"
grep -q "pathtrace truth, .* spp: noise" "$tmp/a.log" || fail "no noise line: $(cat "$tmp/a.log")"
"$lucent" "${b[@]}" --csv "$tmp/b.csv" >"$tmp/b.txt" 2>"$tmp/b.log" || fail "second run"
grep -q "^lucent bench: truth from cache $file " "$tmp/b.log" || fail "second run did not read $file: $(cat "$tmp/b.log")"
grep -q "pathtrace truth, .* spp: noise" "$tmp/b.log" && fail "second run rendered the truth again"
for m in reference raymarch; do
  ra=$(rel "$tmp/a.csv" $m) rb=$(rel "$tmp/b.csv" $m)
  [[ -n $ra && $ra == "$rb" ]] || fail "$m: rel_l2 $ra first, $rb from the cache"
done
# The columns name the truth; the truth column says how it was judged.
truth=$(awk -F, -v c="$(csv_col "$tmp/a.csv" truth)" 'NR == 2 { print $c }' "$tmp/a.csv")
[[ $truth =~ ^pathtrace(/8x8)?\([0-9.]+%\)$ ]] || fail "truth column \"$truth\""
[[ -n $(csv_col "$tmp/a.csv" speedup_vs_pathtrace) ]] || fail "csv header $(head -1 "$tmp/a.csv")"
grep -q "rel_l2_pt" "$tmp/a.txt" || fail "table header: $(cat "$tmp/a.txt")"

# 2. The key: a setting, the scene file, a data file's bytes (same size and
# mtime) each give a new cache file.
keyed() { # args: what, then extra bench args; the run must write a new file
  "$lucent" "${b[@]:0:1}" "$2" "${b[@]:2}" "${@:3}" >/dev/null 2>"$tmp/k.log" || fail "$1: $(cat "$tmp/k.log")"
  f=$(sed -n 's/^lucent bench: truth written to cache \([^ ]*\) .*/\1/p' "$tmp/k.log")
  [[ -n $f && $f != "$file" ]] || fail "$1 did not change the key: $(cat "$tmp/k.log")"
}
keyed "a pathtrace setting" "$tmp/s.json" --set pathtrace.max_depth=64
sed 's/"intensity": \[30, 30, 30\]/"intensity": [31, 30, 30]/' "$tmp/s.json" >"$tmp/s2.json"
keyed "the scene file" "$tmp/s2.json"
cp -p "$tmp/floor.ply" "$tmp/floor.orig"
sed -i 's/^-3.0 0.0 -3.0$/-3.0 0.1 -3.0/' "$tmp/floor.ply"
touch -r "$tmp/floor.orig" "$tmp/floor.ply"
[[ $(stat -c %s "$tmp/floor.ply") == $(stat -c %s "$tmp/floor.orig") ]] || fail "test setup: sizes differ"
keyed "the mesh file's bytes" "$tmp/s.json"
cp -p "$tmp/floor.orig" "$tmp/floor.ply"
keyed "the image size" "$tmp/s.json" --size 24x16

# 3. A truncated and a corrupted cache file are rendered again, with a message.
head -c 100 "$file" >"$tmp/t" && cat "$tmp/t" >"$file"
"$lucent" "${b[@]}" --csv "$tmp/c.csv" >/dev/null 2>"$tmp/c.log" || fail "truncated cache: $(cat "$tmp/c.log")"
grep -q "truth cache $file: truncated.*rendering it again" "$tmp/c.log" || fail "truncation: $(cat "$tmp/c.log")"
[[ $(rel "$tmp/c.csv" reference) == "$(rel "$tmp/a.csv" reference)" ]] || fail "re-rendered truth differs"
size=$(stat -c %s "$file")
printf '\x55\xaa\x55\xaa' | dd of="$file" bs=1 seek=$((size - 5)) conv=notrunc 2>/dev/null
"$lucent" "${b[@]}" >/dev/null 2>"$tmp/d.log" || fail "corrupt cache: $(cat "$tmp/d.log")"
grep -q "truth cache $file: checksum mismatch.*rendering it again" "$tmp/d.log" || fail "corruption: $(cat "$tmp/d.log")"
"$lucent" "${b[@]}" >/dev/null 2>"$tmp/e.log"
grep -q "truth from cache $file" "$tmp/e.log" || fail "rewritten cache not read: $(cat "$tmp/e.log")"

# 4. --reference FILE overrides --truth pathtrace.
"$lucent" render "$tmp/s.json" --method reference -o "$tmp/ref.exr" 2>/dev/null
"$lucent" "${b[@]}" --reference "$tmp/ref.exr" --csv "$tmp/f.csv" >/dev/null 2>"$tmp/f.log" || fail "--reference"
grep -q "pathtrace truth\|truth from cache" "$tmp/f.log" && fail "--reference still used the pathtrace truth"
awk -F, -v c="$(csv_col "$tmp/f.csv" truth)" 'NR > 1 && $c != "file" { exit 1 }' "$tmp/f.csv" || fail "truth column with --reference"
r0=$(awk -F, -v c="$(csv_col "$tmp/f.csv" rel_l2)" '$2 == "reference" { print $c }' "$tmp/f.csv")
[[ $r0 == 0 ]] || fail "reference against its own image: rel_l2 $r0"

# 5. Usage errors.
set +e
"$lucent" bench "$tmp/s.json" --truth foo >/dev/null 2>"$tmp/u.log"; rc=$?
"$lucent" bench "$tmp/s.json" --truth pathtrace --no-truth >/dev/null 2>&1; rc2=$?
"$lucent" bench "$tmp/s.json" --truth pathtrace --motion orbit --stability >/dev/null 2>&1; rc3=$?
set -e
[[ $rc == 2 ]] || fail "--truth foo: exit $rc"
grep -q 'truth "foo": expected reference or pathtrace' "$tmp/u.log" || fail "--truth foo message: $(cat "$tmp/u.log")"
[[ $rc2 == 2 && $rc3 == 2 ]] || fail "--truth with --no-truth: $rc2, with --stability: $rc3"

# 6. Limit case: pathtrace at max_depth 1 is single scattering, what
# reference computes exactly, so reference's distance from that truth is
# the truth's own noise: within 3x the noise the truth states.
"$lucent" "${b[@]}" --set pathtrace.max_depth=1 --csv "$tmp/g.csv" >/dev/null 2>"$tmp/g.log" || fail "max_depth 1"
t1=$(awk -F, -v c="$(csv_col "$tmp/g.csv" truth)" '$2 == "reference" { print $c }' "$tmp/g.csv")
noise=$(sed 's/.*(\([0-9.]*\)%)/\1/' <<<"$t1")
r1=$(rel "$tmp/g.csv" reference)
awk -v r="$r1" -v n="$noise" 'BEGIN { exit !(r <= 3 * n / 100) }' ||
  fail "single-scattering truth: reference at rel_l2 $r1, truth noise $noise%"
# 7. The noise estimate ||A - B|| / (2 ||M||) is the truth's distance from a
# far less noisy one: a 64-spp truth against a 4096-spp one is
# sqrt(n64^2 + n4096^2) apart (their noises add; the 4096 one shares the
# first 64 samples, which makes it a little less). A factor sqrt(2) or 2
# in the rule would put the ratio outside [0.8, 1.25].
noise_at() { sed -n 's/.*pathtrace truth, \([0-9]*\) spp: noise \([0-9.]*\)% per pixel.*/\1 \2/p' "$1" | tail -1; }
for m in 64 4096; do
  "$lucent" "${b[@]:0:${#b[@]}-1}" "$m" --save-images "$tmp/n$m" >/dev/null 2>"$tmp/n$m.log" || fail "truth at $m spp"
done
read -r s64 n64 <<<"$(noise_at "$tmp/n64.log")"
read -r s4k n4k <<<"$(noise_at "$tmp/n4096.log")"
[[ $s64 == 64 && -n $n4k ]] || fail "noise lines: $(cat "$tmp/n64.log" "$tmp/n4096.log")"
d=$("$lucent" compare "$tmp/n64/truth.exr" "$tmp/n4096/truth.exr" | awk '/^rel_l2/ { print $2 }')
awk -v d="$d" -v a="$n64" -v b="$n4k" 'BEGIN { e = sqrt(a * a + b * b) / 100; exit !(d >= 0.8 * e && d <= 1.25 * e) }' ||
  fail "64-spp truth is $d from the $s4k-spp one; the noise estimates say $n64% and $n4k%"
echo "ok (noise: 64 spp $n64%, measured $d; single-scattering truth: reference at $r1, noise $noise%)"
