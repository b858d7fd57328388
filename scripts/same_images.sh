#!/usr/bin/env bash
# Proves that a change leaves every image as it was: renders every bundled
# scene with every method on every backend it runs on, once with the BEFORE
# binary and once with the AFTER binary, and requires
# `lucent compare --max-rel-l2 0` of each pair (bit for bit; the suite's own
# tolerances are no proof of equality). A method that refuses a scene must
# refuse it with both binaries, with the same message.
# Usage: scripts/same_images.sh BEFORE_LUCENT AFTER_LUCENT [WxH]
# SAME_IMAGES_ONLY=REGEX limits it to the scene-method-backend names that match.
# Small images keep it to minutes; the code paths are those of any size.
set -uo pipefail
cd "$(dirname "$0")/.."
before=${1:?usage: same_images.sh BEFORE_LUCENT AFTER_LUCENT [WxH]}
after=${2:?usage: same_images.sh BEFORE_LUCENT AFTER_LUCENT [WxH]}
size=${3:-48x27}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export LUCENT_QUIET=1
# Each binary gets its own ddod cache, so neither reads what the other wrote.
cache_b=$tmp/cache-before cache_a=$tmp/cache-after
# Cheap settings for the expensive methods; identical for both binaries.
sets=(--set pathtrace.spp=2 --set reference.env_samples=16 --set bssrdf.splats=1024
      --set bssrdf.env_max=2000 --set bssrdf.map_res=128 --set ddod.samples=4000
      --set raymarch.steps=64 --set raymarch.shadow_res=128
      --set afm.steps=64 --set afm.map_res=64 --set afm.shadow_res=128)
for g in gradient rbf pervoxel; do sets+=(--set $g.steps=64 --set $g.shadow_res=128); done
"$after" methods >"$tmp/methods.txt"
methods=$(awk '/^[a-z]+ \[/{print $1}' "$tmp/methods.txt")
pairs=0 same=0 refused=0 bad=0
for scene in scenes/*.json; do
  name=$(basename "$scene" .json)
  for m in $methods; do
    backends=$(awk -v m="$m" '$1==m{gsub(/[\[\]]/,"",$2); gsub(/,/," ",$2); print $2}' "$tmp/methods.txt")
    for be in $backends; do
      id="$name-$m-$be"
      [[ -n "${SAME_IMAGES_ONLY:-}" && ! "$id" =~ $SAME_IMAGES_ONLY ]] && continue
      LUCENT_CACHE_DIR=$cache_b "$before" render "$scene" --method "$m" --backend "$be" --size "$size" \
        "${sets[@]}" -o "$tmp/b.exr" >/dev/null 2>"$tmp/b.err"; rb=$?
      LUCENT_CACHE_DIR=$cache_a "$after" render "$scene" --method "$m" --backend "$be" --size "$size" \
        "${sets[@]}" -o "$tmp/a.exr" >/dev/null 2>"$tmp/a.err"; ra=$?
      pairs=$((pairs + 1))
      if ((rb != 0 || ra != 0)); then
        eb=$(grep -v '^note' "$tmp/b.err" | tail -1) ea=$(grep -v '^note' "$tmp/a.err" | tail -1)
        if ((rb == ra)) && [[ "$eb" == "$ea" ]]; then
          refused=$((refused + 1))
        else
          echo "DIFFERENT $id: exit $rb vs $ra: '$eb' vs '$ea'"; bad=$((bad + 1))
        fi
        rm -f "$tmp/b.exr" "$tmp/a.exr"
        continue
      fi
      if "$after" compare "$tmp/a.exr" "$tmp/b.exr" --max-rel-l2 0 >"$tmp/c.txt" 2>&1; then
        same=$((same + 1))
      else
        echo "DIFFERENT $id: $(tr '\n' ' ' <"$tmp/c.txt")"; bad=$((bad + 1))
      fi
    done
  done
done
echo "same_images: $pairs scene/method/backend triples at $size: $same identical, $refused refused by both, $bad different"
((bad == 0))
