#!/usr/bin/env bash
# The installed package: `cmake --install` into a fresh prefix, then
# examples/embed (a project outside lucent's) built twice against it, with
# find_package(lucent) and with pkg-config, and run. Each build must render
# the bundled demo scene exactly as `lucent render` does (rel-L2 0); with
# GLFW, embed_window renders into its own window's texture under Xvfb. A shared
# liblucent, when the build made one, must export lu_ names only.
# Args: LUCENT_BINARY SOURCE_DIR
set -u
source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"
build=$(cd "$(dirname "$lucent")" && pwd)
export LUCENT_QUIET=1
args=("$src/scenes/demo.json" raymarch 40x30 raymarch.steps=48)

cmake --install "$build" --prefix "$tmp/prefix" >"$tmp/install.log" 2>&1 ||
  { cat "$tmp/install.log"; echo "FAIL: cmake --install"; exit 1; }
for f in include/lucent/lucent.h lib/cmake/lucent/lucentConfig.cmake lib/cmake/lucent/lucentConfigVersion.cmake \
         lib/pkgconfig/lucent.pc; do
  [[ -f "$tmp/prefix/$f" ]] || { echo "FAIL: $f not installed"; fail=1; }
done

# .vdb input: the converter goes to libexec/lucent, and the installed lucent
# finds it there relative to itself (this prefix is not the configured one).
if [[ -x $build/lucent-vdb-convert ]]; then
  conv=$(ls "$tmp"/prefix/libexec/lucent/lucent-vdb-convert 2>/dev/null)
  [[ -n $conv ]] || { echo "FAIL: lucent-vdb-convert not installed under libexec/lucent"; fail=1; }
  mkdir -p "$tmp/vdb" && "$build/lu_vdb_gen" "$tmp/vdb" >/dev/null || { echo "FAIL: lu_vdb_gen"; fail=1; }
  "$tmp/prefix/bin/lucent" info "$tmp/vdb/twin.vdb" >"$tmp/vdb.log" 2>&1 && grep -q '"density"' "$tmp/vdb.log" ||
    { cat "$tmp/vdb.log"; echo "FAIL: the installed lucent cannot read .vdb"; fail=1; }
fi

"$lucent" render "${args[0]}" --method "${args[1]}" --size "${args[2]}" --set "${args[3]}" -o "$tmp/cli.pfm" \
  2>"$tmp/cli.log" || { cat "$tmp/cli.log"; echo "FAIL: lucent render"; exit 1; }

# find_package(lucent)
if cmake -S "$src/examples/embed" -B "$tmp/cm" -DCMAKE_PREFIX_PATH="$tmp/prefix" -DCMAKE_BUILD_TYPE=Release \
     >"$tmp/cm.log" 2>&1 && cmake --build "$tmp/cm" >>"$tmp/cm.log" 2>&1; then
  if "$tmp/cm/embed" "${args[0]}" "$tmp/cm.pfm" "${args[@]:1}" >"$tmp/run.log" 2>&1; then
    grep -q "allocations through the host" "$tmp/run.log" || { cat "$tmp/run.log"; echo "FAIL: embed (cmake) output"; fail=1; }
    "$lucent" compare "$tmp/cm.pfm" "$tmp/cli.pfm" --max-rel-l2 0 >/dev/null ||
      { echo "FAIL: embed (cmake) image differs from lucent render"; fail=1; }
  else
    cat "$tmp/run.log"; echo "FAIL: embed (cmake) failed"; fail=1
  fi
else
  tail -20 "$tmp/cm.log"; echo "FAIL: examples/embed does not build with find_package(lucent)"; fail=1
fi

# embed_window: the GPU methods in the program's own window context, frames
# into its texture; the texture read back equals lucent render on the GPU.
if [[ -x "$tmp/cm/embed_window" ]] && command -v xvfb-run >/dev/null &&
   "$lucent" render "$src/scenes/smoke_glow.json" --method raymarch --backend gpu --size 40x30 \
     -o "$tmp/gpu.pfm" 2>/dev/null; then
  if xvfb-run -a -s "-screen 0 320x240x24" "$tmp/cm/embed_window" "$src/scenes/smoke_glow.json" "$tmp/win.pfm" \
       raymarch 40x30 3 >"$tmp/win.log" 2>&1; then
    grep -q "texture_direct" "$tmp/win.log" || { cat "$tmp/win.log"; echo "FAIL: embed_window: not direct"; fail=1; }
    "$lucent" compare "$tmp/win.pfm" "$tmp/gpu.pfm" --max-rel-l2 0 >/dev/null ||
      { echo "FAIL: embed_window's texture differs from lucent render --backend gpu"; fail=1; }
    echo "embed_window: $(head -1 "$tmp/win.log")"
  else
    cat "$tmp/win.log"; echo "FAIL: embed_window failed"; fail=1
  fi
else
  echo "embed_window: skipped (not built without GLFW, or no xvfb-run or GPU context)"
fi

# pkg-config (static linking needs --static; a shared liblucent needs nothing more)
pc="env PKG_CONFIG_PATH=$tmp/prefix/lib/pkgconfig pkg-config"
if $pc --exists lucent && [[ $($pc --modversion lucent) == $("$lucent" --version | awk '{print $2}') ]]; then
  if cc -std=c11 "$src/examples/embed/embed.c" -o "$tmp/pc_embed" $($pc --cflags --libs --static lucent) \
       -Wl,-rpath,"$tmp/prefix/lib" 2>"$tmp/pc.log"; then
    if "$tmp/pc_embed" "${args[0]}" "$tmp/pc.pfm" "${args[@]:1}" >"$tmp/run.log" 2>&1; then
      "$lucent" compare "$tmp/pc.pfm" "$tmp/cli.pfm" --max-rel-l2 0 >/dev/null ||
        { echo "FAIL: embed (pkg-config) image differs from lucent render"; fail=1; }
    else
      cat "$tmp/run.log"; echo "FAIL: embed (pkg-config) failed"; fail=1
    fi
  else
    cat "$tmp/pc.log"; echo "FAIL: examples/embed does not build with pkg-config lucent"; fail=1
  fi
else
  echo "FAIL: pkg-config lucent missing or of another version than lucent --version"; fail=1
fi

# the shared library's exports
so=$(ls "$tmp/prefix/lib"/liblucent.so.* 2>/dev/null | head -1)
if [[ -n "$so" ]]; then
  others=$(nm -D --defined-only "$so" | awk '{print $3}' | grep -v '^lu_' | grep -vE '^(_init|_fini|LUCENT_.*)$')
  [[ -z "$others" ]] || { echo "FAIL: liblucent.so exports non-lu_ symbols: $(echo $others | head -c 300)"; fail=1; }
  nm -D --defined-only "$so" | grep -q ' lu_renderer_make$' || { echo "FAIL: lu_renderer_make not exported"; fail=1; }
  echo "shared: $(nm -D --defined-only "$so" | grep -c ' lu_') lu_ symbols exported"
fi
[[ $fail == 0 ]] && echo "install: ok"
exit $fail
