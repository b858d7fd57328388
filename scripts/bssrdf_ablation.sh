#!/usr/bin/env bash
# The ablation of docs/bssrdf.md, "Where the error comes from": `bssrdf` with
# each diffusion profile against the `pathtrace` truth (same smooth dielectric
# boundary: boundary=auto refracts at translucent objects) on the scenes
# scenes/ablate_*.json, 160x160, both images averaged over 8x8 blocks.
#
#   scripts/bssrdf_ablation.sh [truth|bssrdf|exitance|table|all]   (default all)
#
# truth   two pathtrace renders per scene (seeds 1 and 2, SPP passes each),
#         their average is the truth. Kept under $OUT/truth and not redone
#         while present (delete a file to redo it). A render written with
#         --progressive-every may be stopped early: $OUT/truth/S.sN.spp holds
#         the passes its file contains.
# bssrdf  every profile on every scene (a profile this build lacks is skipped
#         and shows as "pending"), the dipole also at 65,536 splats.
# exitance  the half-space's exitance under normal light, pathtrace (eta 1.5
#         and 1) and bssrdf: the radiance seen from 4 Gauss-Legendre
#         directions (4x4 pixels, 0.5 degree field of view, XSPP passes),
#         integrated over the hemisphere; compare `lucent profile --mc`.
# table   the markdown tables of docs/bssrdf.md from what is there.
#
# Environment: LUCENT (default build/lucent), OUT (default out/bssrdf_ablation,
# git-ignored), SPP (truth passes per seed, default 1024), XSPP (exitance
# passes, default 2048), NICE (default 10).
# The truths are the cost: at 160x160 about 0.5-3 s per pass and scene on
# one core of a 2-core machine, far more in the half-space (long walks).
set -euo pipefail
cd "$(dirname "$0")/.."
LUCENT=${LUCENT:-build/lucent}
OUT=${OUT:-out/bssrdf_ablation}
SPP=${SPP:-1024}
XSPP=${XSPP:-2048}
NICE=${NICE:-10}
SCENES=(halfspace sphere bunny_front bunny_back bunny_floor)
PROFILES=(dipole multipole burley pbd)
analyze="python3 scripts/pathtrace_analyze.py"
mkdir -p "$OUT/truth" "$OUT/bssrdf"

truth() {
  for s in "${SCENES[@]}"; do
    for seed in 1 2; do
      f=$OUT/truth/$s.s$seed.pfm
      [[ -s $f ]] && continue
      nice -n "$NICE" "$LUCENT" render "scenes/ablate_$s.json" --method pathtrace --size 160x160 \
        --set pathtrace.spp="$SPP" --set pathtrace.seed=$seed --progressive-every 8 -o "$f" \
        2>"$OUT/truth/$s.s$seed.log"
      echo "$SPP" >"$OUT/truth/$s.s$seed.spp"
    done
    $analyze average "$OUT/truth/$s.pfm" "$OUT/truth/$s.s1.pfm" "$OUT/truth/$s.s2.pfm"
  done
}

bssrdf() {
  for s in "${SCENES[@]}"; do
    for p in "${PROFILES[@]}"; do
      nice -n "$NICE" "$LUCENT" render "scenes/ablate_$s.json" --method bssrdf --size 160x160 \
        --set bssrdf.profile=$p -o "$OUT/bssrdf/$s.$p.pfm" 2>"$OUT/bssrdf/$s.$p.log" ||
        rm -f "$OUT/bssrdf/$s.$p.pfm"
    done
    nice -n "$NICE" "$LUCENT" render "scenes/ablate_$s.json" --method bssrdf --size 160x160 \
      --set bssrdf.splats=65536 -o "$OUT/bssrdf/$s.dipole64k.pfm" 2>"$OUT/bssrdf/$s.dipole64k.log"
  done
}

# Gauss-Legendre on [0, 1], 4 nodes: weight:node
GL4=(0.1739274226:0.0694318442 0.3260725774:0.3300094782 0.3260725774:0.6699905218 0.1739274226:0.9305681558)

exitance() {
  local X=$OUT/exitance
  mkdir -p "$X"
  for eta in 1.5 1.0; do
    for wm in "${GL4[@]}"; do
      mu=${wm#*:}
      f=$X/eta$eta.mu$mu
      # Camera 30 units away: a 4x4 view at 0.5 degrees stays 1.9 units from
      # the middle even at grazing, so every point it sees is a half-space.
      sed "s/\"eta\": 1.5/\"eta\": $eta/" "scenes/ablate_halfspace.json" |
        python3 -c "
import json, math, sys
s = json.load(sys.stdin)
mu = $mu
s['camera'] = {'position': [0, 30 * mu, 30 * math.sqrt(1 - mu * mu)], 'look_at': [0, 0, 0], 'fov_y_deg': 0.5,
               'width': 4, 'height': 4}
s['lights'] = [{'type': 'directional', 'direction': [0, 1, 0], 'irradiance': [1, 1, 1]}]
print(json.dumps(s))" >"$f.json"
      [[ -s $f.pathtrace.pfm ]] || nice -n "$NICE" "$LUCENT" render "$f.json" --method pathtrace \
        --set pathtrace.spp="$XSPP" --set pathtrace.seed=7 -o "$f.pathtrace.pfm" 2>/dev/null
      [[ $eta == 1.0 ]] && continue
      for p in "${PROFILES[@]}"; do
        [[ -s $f.$p.pfm ]] || nice -n "$NICE" "$LUCENT" render "$f.json" --method bssrdf \
          --set bssrdf.profile=$p -o "$f.$p.pfm" 2>/dev/null || rm -f "$f.$p.pfm"
      done
    done
  done
}

# "rel-L2 (mean ratio)" of A against REF after 8x8 blocks, or "pending".
# With a third argument D, the seeds' difference: REF, their mean, carries
# noise of about D/2 rel-L2, which adds in quadrature; "rel-L2 / less the
# noise (mean ratio)".
cmp8() {
  [[ -s $1 && -s $2 ]] || { echo pending; return; }
  "$LUCENT" compare "$1" "$2" --block 8 | awk -v d="${3:-}" '$1 == "rel_l2" { r = $2 } $1 == "mean_ratio" { m = $2 }
    END { c = r * r - d * d / 4; if (c < 0) c = 0
          if (d == "") printf "%.3f (%.3f)", r, m; else printf "%.3f / %.3f (%.3f)", r, sqrt(c), m }'
}

# The same over the blocks inside (or, with --outside, outside) the object
# mask M: the pixels the dipole render of the floorless bunny covers.
cmp8m() {
  [[ -s $1 && -s $2 ]] || { echo pending; return; }
  $analyze boxcmp "$1" "$2" --box 8 --ratio --mask "$3" ${4:-} | awk '{ printf "%.3f (%.3f)", $1, $2 }'
}

table() {
  local T=$OUT/truth B=$OUT/bssrdf X=$OUT/exitance
  echo "| scene | truth spp per seed | seeds 1 vs 2 | dipole | multipole | Burley | pbd | dipole, 65,536 splats |"
  echo "|---|---|---|---|---|---|---|---|"
  for s in "${SCENES[@]}"; do
    spp="$(cat "$T/$s.s1.spp" 2>/dev/null || echo "?") / $(cat "$T/$s.s2.spp" 2>/dev/null || echo "?")"
    seeds=$(cmp8 "$T/$s.s1.pfm" "$T/$s.s2.pfm")
    row="| $s | $spp | $seeds"
    for p in "${PROFILES[@]}" dipole64k; do row+=" | $(cmp8 "$B/$s.$p.pfm" "$T/$s.pfm" "${seeds%% *}")"; done
    echo "$row |"
  done
  echo
  echo "| half-space exitance under E = 1 at normal incidence | R | G | B |"
  echo "|---|---|---|---|"
  for row in "1.5 pathtrace" "1.5 dipole" "1.5 multipole" "1.5 burley" "1.5 pbd" "1.0 pathtrace"; do
    set -- $row
    args=()
    for wm in "${GL4[@]}"; do args+=("$wm:$X/eta$1.mu${wm#*:}.$2.pfm"); done
    m=$($analyze exitance "${args[@]}" 2>/dev/null) || m=pending
    echo "| $2, eta $1 | ${m// / | } |"
  done
  echo
  local M=$B/bunny_front.dipole.pfm
  echo "| bunny front-lit, 8x8 blocks | on the bunny | on the floor |"
  echo "|---|---|---|"
  echo "| truth with floor vs truth without | $(cmp8m "$T/bunny_floor.pfm" "$T/bunny_front.pfm" "$M") | |"
  for p in "${PROFILES[@]}"; do
    echo "| $p with floor vs truth with floor | $(cmp8m "$B/bunny_floor.$p.pfm" "$T/bunny_floor.pfm" "$M") |" \
      "$(cmp8m "$B/bunny_floor.$p.pfm" "$T/bunny_floor.pfm" "$M" --outside) |"
    echo "| $p without floor vs truth without | $(cmp8m "$B/bunny_front.$p.pfm" "$T/bunny_front.pfm" "$M") | |"
  done
}

case ${1:-all} in
  truth) truth ;;
  exitance) exitance ;;
  bssrdf) bssrdf ;;
  table) table ;;
  all) truth && bssrdf && exitance && table ;;
  *) echo "usage: $0 [truth|bssrdf|exitance|table|all]" >&2; exit 2 ;;
esac
