# shellcheck shell=bash
# Sourced (bash) from a carry folder made by `scripts/bench_gpu.sh --prepare
# DIR` (this file is DIR/env.sh there): makes DIR/bin/lucent runnable on a
# machine that has none of its libraries.
#
#   . DIR/env.sh && lucent info --gpu
#
# - Unpacks DIR/lib.tar.gz once into $LUCENT_CARRY_LIB (default
#   ${TMPDIR:-/tmp}/lucent-carry-<checksum>), outside DIR, so the folder stays
#   as small as it was carried.
# - Puts DIR/bin on PATH and the carried libraries first on LD_LIBRARY_PATH,
#   then the NVIDIA driver's folders where they exist (/usr/local/nvidia/lib64,
#   /usr/local/nvidia/lib), whose libEGL_nvidia the carried glvnd loader opens.
# - Unless __EGL_VENDOR_LIBRARY_DIRS or __EGL_VENDOR_LIBRARY_FILENAMES is set,
#   points the loader at every EGL vendor folder of the machine that exists
#   (/etc/glvnd/egl_vendor.d, /usr/share/glvnd/egl_vendor.d and the same under
#   /usr/local and /usr/local/nvidia): the vendor's ICD json, never a carried one.
# - libstdc++ and libgcc_s are used from the machine; the carried copies
#   (lib/compat) only when the binary cannot start without them.
# Returns non-zero, with the loader's complaint, when the binary cannot start.
lucent_carry_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
lucent_carry_sum=$(cksum <"$lucent_carry_dir/lib.tar.gz" | cut -d' ' -f1)
export LUCENT_CARRY_LIB=${LUCENT_CARRY_LIB:-${TMPDIR:-/tmp}/lucent-carry-$lucent_carry_sum}
if [ ! -f "$LUCENT_CARRY_LIB/.complete" ]; then
  mkdir -p "$LUCENT_CARRY_LIB" &&
    tar -xzf "$lucent_carry_dir/lib.tar.gz" -C "$LUCENT_CARRY_LIB" --strip-components=1 &&
    touch "$LUCENT_CARRY_LIB/.complete" ||
    { echo "env.sh: cannot unpack $lucent_carry_dir/lib.tar.gz into $LUCENT_CARRY_LIB" >&2; return 1; }
fi
lucent_carry_path=$LUCENT_CARRY_LIB
for d in /usr/local/nvidia/lib64 /usr/local/nvidia/lib; do
  [ -d "$d" ] && lucent_carry_path=$lucent_carry_path:$d
done
export LD_LIBRARY_PATH=$lucent_carry_path${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
export PATH=$lucent_carry_dir/bin${PATH:+:$PATH}
if [ -z "${__EGL_VENDOR_LIBRARY_DIRS:-}" ] && [ -z "${__EGL_VENDOR_LIBRARY_FILENAMES:-}" ]; then
  lucent_carry_vendors=
  for d in /etc/glvnd/egl_vendor.d /usr/share/glvnd/egl_vendor.d /usr/local/share/glvnd/egl_vendor.d \
    /usr/local/nvidia/share/glvnd/egl_vendor.d; do
    [ -d "$d" ] && lucent_carry_vendors=${lucent_carry_vendors:+$lucent_carry_vendors:}$d
  done
  if [ -n "$lucent_carry_vendors" ]; then
    export __EGL_VENDOR_LIBRARY_DIRS=$lucent_carry_vendors
  else
    echo "env.sh: no EGL vendor folder (glvnd/egl_vendor.d) on this machine: no GPU context can be made" >&2
  fi
fi
if ! "$lucent_carry_dir/bin/lucent" --version >/dev/null 2>&1; then
  export LD_LIBRARY_PATH=$LUCENT_CARRY_LIB:$LUCENT_CARRY_LIB/compat:${LD_LIBRARY_PATH#"$LUCENT_CARRY_LIB:"}
  if ! "$lucent_carry_dir/bin/lucent" --version >/dev/null 2>&1; then
    echo "env.sh: $lucent_carry_dir/bin/lucent cannot start here: $("$lucent_carry_dir/bin/lucent" --version 2>&1 | head -1)" >&2
    return 1
  fi
  echo "env.sh: using the carried libstdc++/libgcc_s (lib/compat): the machine's are missing or older" >&2
fi
unset lucent_carry_sum lucent_carry_path lucent_carry_vendors d
