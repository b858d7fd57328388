#!/usr/bin/env bash
# Every measurement behind docs/bssrdf.md, in one run (ratios are only
# compared within a run). Needs a built lucent (build/lucent or $LUCENT), the
# npm data (scripts/setup.sh) and gnuplot for the plots. Writes CSVs and logs
# under docs/bssrdf/ and PNGs under docs/images/bssrdf/.
#
#   scripts/bench_bssrdf.sh            everything (about an hour on 2 busy cores)
#   scripts/bench_bssrdf.sh totals     only section (1); likewise: sweep, relax, images, reference, plots
set -euo pipefail
cd "$(dirname "$0")/.."
L=${LUCENT:-build/lucent}
OUT=docs/bssrdf
IMG=docs/images/bssrdf
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
mkdir -p "$OUT" "$IMG"
export LUCENT_QUIET=1
what=${1:-all}
run() { [[ $what == all || $what == "$1" ]]; }

# ---- (1) total diffuse reflectance of every preset; the random walk ------------------
if run totals; then
  "$L" profile --all >"$OUT/totals.csv"
  "$L" profile --all --mc 100000 --bins 64 >"$OUT/totals_mc.csv"
  for p in marble skin1 ketchup; do
    "$L" profile --preset "$p" --mc 400000 --bins 80 --csv "$OUT/profile_$p.csv" >"$OUT/profile_$p.txt"
  done
  "$L" profile --preset marble --model multipole --thickness 4 --mc 400000 --bins 80 \
    --csv "$OUT/profile_marble_slab4mm.csv" >"$OUT/profile_marble_slab4mm.txt"
  "$L" profile --preset skin1 --model burley --mc 400000 --bins 80 --csv "$OUT/profile_skin1_burley.csv" \
    >"$OUT/profile_skin1_burley.txt"
  # Normalised diffusion in the set-up its fit was made for: index-matched (eta 1), pencil beam.
  for p in marble skin1 ketchup apple wholemilk; do
    "$L" profile --preset "$p" --eta 1 --model burley --mc 200000 --bins 48 >"$OUT/burley_eta1_$p.txt"
  done
fi

# ---- (2) frame time vs splat count, 512^2, dipole and multipole, CPU and GPU --------
# rel_l2 is against the same configuration at 65536 splats (its own converged image).
stats_row() { # file backend -> "splats,env,pairs,maps_ms,samples_ms,gbuffer_ms,binning_ms,splat_ms,cpu_ms"
  grep "($2)" "$1" | tail -1 | sed -E 's/.*maps ([0-9.]+) ms.*samples ([0-9.]+) ms \(([0-9]+) splats, ([0-9]+) environment\), G-buffer ([0-9.]+) ms, binning ([0-9.]+) ms \(([0-9]+) splat-tile pairs\), splat\+shade ([0-9.]+) ms; processor time ([0-9.]+) ms/\3,\4,\7,\1,\2,\5,\6,\8,\9/'
}
if run sweep; then
  echo "scene,profile,backend,splats_requested,splats,env_splats,splat_tile_pairs,maps_ms,samples_ms,gbuffer_ms,binning_ms,splat_shade_ms,frame_cpu_ms,frame_ms,rel_l2_vs_65536" >"$OUT/sweep.csv"
  for scene in bunny_marble dragon_marble; do
    for profile in dipole multipole; do
      ref="$TMP/ref_${scene}_$profile.exr"
      "$L" render "scenes/$scene.json" --method bssrdf --set bssrdf.profile=$profile --set bssrdf.splats=65536 \
        --size 512x512 -o "$ref" 2>>"$OUT/sweep.log"
      for n in 1024 2048 4096 8192 16384; do
        backends=cpu
        [[ $n == 1024 || $n == 4096 ]] && backends="cpu gpu"
        for b in $backends; do
          "$L" bench "scenes/$scene.json" --methods bssrdf --backends $b --size 512x512 --frames 1 --warmup 1 \
            --set bssrdf.profile=$profile --set bssrdf.splats=$n --set bssrdf.stats=1 --reference "$ref" \
            --csv "$TMP/b.csv" >/dev/null 2>"$TMP/b.err"
          s=$(stats_row "$TMP/b.err" $b)
          f=$(awk -F, 'NR == 2 { print $5 "," $11 }' "$TMP/b.csv")
          echo "$scene,$profile,$b,$n,$s,$f" >>"$OUT/sweep.csv"
          cat "$TMP/b.err" >>"$OUT/sweep.log"
        done
      done
    done
  done
fi

# ---- (3) relaxation: 10k samples on the dragon, and 4k on a cube (thesis Table 5.4) -
if run relax; then
  cat >"$TMP/cube.json" <<'EOF'
{"camera": {"position": [0, 0, 5], "look_at": [0, 0, 0], "width": 16, "height": 16},
 "lights": [{"type": "environment", "file": "REPO/scenes/sky.pfm"}],
 "objects": [{"mesh": {"procedural": "box", "size": [2, 2, 2]},
              "material": {"type": "translucent", "preset": "marble", "mm_per_unit": 30}}]}
EOF
  sed -i "s|REPO|$PWD|" "$TMP/cube.json"
  echo "model,triangles,samples,step,iterations,converged,seconds,last_rms_move,nn_cv_before,nn_cv_after" >"$OUT/relax.csv"
  for model in dragon cube; do
    if [[ $model == dragon ]]; then sc=scenes/dragon_env.json; n=10000; tris=47794; else sc=$TMP/cube.json; n=4000; tris=12; fi
    for k in 0.001 0.01 0.1; do
      "$L" render "$sc" --method bssrdf --size 16x16 --set bssrdf.env_samples=$n --set bssrdf.relax_step=$k \
        --set bssrdf.relax_iters=400 --set bssrdf.stats=1 -o "$TMP/r.png" 2>"$TMP/r.err"
      line=$(grep relaxation "$TMP/r.err")
      it=$(sed -E 's/.*relaxation ([0-9]+) iterations.*/\1/' <<<"$line")
      conv=$(grep -q "(converged" <<<"$line" && echo yes || echo no)
      rms=$(sed -E 's/.*last RMS move ([0-9.e+-]+) r.*/\1/' <<<"$line")
      sec=$(sed -E 's/.* in ([0-9.]+) s,.*/\1/' <<<"$line")
      cv=$(sed -E 's/.*CV ([0-9.]+) -> ([0-9.]+).*/\1,\2/' <<<"$line")
      echo "$model,$tris,$n,$k,$it,$conv,$sec,$rms,$cv" >>"$OUT/relax.csv"
    done
  done
fi

# ---- (4) images (thesis Figs. 6.6-6.9, 6.12) ---------------------------------------------
if run images; then
  r() { "$L" render "scenes/$1.json" --method bssrdf --set bssrdf.splats=16384 "${@:3}" -o "$IMG/$2.png" 2>>"$OUT/images.log"; }
  r dragon_marble dragon_marble_front_dipole --set bssrdf.profile=dipole
  r dragon_marble dragon_marble_front_multipole --set bssrdf.profile=multipole
  r dragon_marble_backlit dragon_marble_back_dipole --set bssrdf.profile=dipole
  r dragon_marble_backlit dragon_marble_back_multipole --set bssrdf.profile=multipole
  r dragon_jade dragon_jade_front --set bssrdf.profile=multipole
  r dragon_jade_backlit dragon_jade_back --set bssrdf.profile=multipole
  r bunny_marble bunny_single --set bssrdf.profile=multipole
  r bunny_coated bunny_coated
  r dragon_env dragon_env
  r bssrdf_spheres spheres --set bssrdf.profile=multipole
  r dragon_marble dragon_marble_front_burley --set bssrdf.profile=burley
  # The thesis' point-evaluated profiles with jittered samples, for comparison.
  r bunny_coated bunny_coated_thesis_sampling --set bssrdf.prefilter=0 --set bssrdf.jitter=1
fi

# ---- (5) against the reference (single scattering in the same media) -------------------
if run reference; then
  "$L" bench scenes/bssrdf_spheres.json --methods reference,bssrdf --backends cpu,gpu --size 160x100 --frames 1 \
    --warmup 1 --set bssrdf.profile=multipole --save-images "$TMP" --csv "$OUT/vs_reference.csv" >"$OUT/vs_reference.txt" 2>&1
  "$L" render scenes/bssrdf_spheres.json --method reference --size 160x100 -o "$TMP/truth.exr" 2>/dev/null
  "$L" compare "$TMP/bssrdf-cpu.exr" "$TMP/truth.exr" -o "$IMG/spheres_vs_reference_diff.png" >>"$OUT/vs_reference.txt"
  "$L" render scenes/bssrdf_spheres.json --method reference --size 512x320 -o "$IMG/spheres_reference.png" 2>/dev/null
fi

# ---- plots --------------------------------------------------------------------------------
if run plots && command -v gnuplot >/dev/null; then
  gnuplot scripts/plot_bssrdf.gp
fi
echo "bench_bssrdf: wrote $OUT and $IMG"
