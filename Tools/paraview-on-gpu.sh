#!/usr/bin/env bash
# ParaView (Debian 12's 5.11 build) carried to a GPU machine that has none: the recipe behind
# the plugin's GPU runs (issue "ParaView on a GPU"). Nothing it packs is committed; the packs
# live in the git-ignored folder .pvgpu/ of the checkout.
#
# Here (the Debian 12 development machine, ParaView SDK installed):
#   Tools/paraview-on-gpu.sh pack [PART_MIB]
#       Packs pvpython, pvbatch, Xvfb (+ xkbcomp, its keymaps and Mesa's software GLX, which
#       Xvfb needs to offer the GLX extension at all), Python 3.11 with ParaView's and
#       numpy's packages, and every shared library they load apart from glibc, libstdc++,
#       libgcc, the GL dispatch libraries (libglvnd: those come from the .gl/ debs the device
#       README names, so NVIDIA's GLX vendor library finds the matching dispatcher) and CUDA's
#       own libraries (the GPU machine has the toolkit and the driver).
#       Output: .pvgpu/part-NN (xz, split in PART_MIB pieces, default 44: each call to the
#       device carries at most 64 MiB with the working tree) and .pvgpu/MANIFEST.
#   Tools/paraview-on-gpu.sh plugin BUILD_DIR
#       Copies BUILD_DIR's plugin folder (built here with -DINR_ENABLE_CUDA=ON; nvcc compiles
#       for sm_90 without a GPU) to .pvgpu/plugin/, carried with the last part.
#
# There (the GPU machine; each step is one device call, made while the machine is warm):
#   Tools/paraview-on-gpu.sh receive      copies the carried .pvgpu/part-* to /tmp/pvgpu-parts
#   Tools/paraview-on-gpu.sh unpack       joins the parts received and unpacks them to /tmp/pvroot
#   source Tools/paraview-on-gpu.sh env   sets PATH (pvpython / pvbatch wrappers that set Python's
#                                         home), LD_LIBRARY_PATH, PV_PLUGIN_PATH; starts Xvfb on :99 with NVIDIA's
#                                         GLX vendor library for the clients (stop_xvfb ends it)
PVGPU_ROOT=${PVGPU_ROOT:-/tmp/pvroot}
PVGPU_PARTS=${PVGPU_PARTS:-/tmp/pvgpu-parts}

pvgpu_closure() {
  # Every shared library the given programs and modules load, as "needed-name path" lines.
  local f
  for f in "$@"; do ldd "$f" 2>/dev/null || true; done |
    awk '/=> \//{print $1, $3}' | sort -u -k1,1 |
    while read -r name path; do echo "$name $(realpath -s "$path")"; done |
    grep -vE '^(libc|libm|libpthread|libdl|librt|libresolv|libutil|ld-linux-x86-64|libstdc\+\+|libgcc_s|libGL|libGLX|libGLdispatch|libOpenGL|libEGL|libGLES|libcuda|libcudart|libcublas|libcublasLt|libnvidia[-a-z]*)\.so' |
    grep -v 'InrVolume' || true
}

pvgpu_pack() {
  local part_mib=${1:-44}
  local out=.pvgpu
  mkdir -p "$out"
  rm -f "$out"/part-* "$out"/MANIFEST
  local pydist=/usr/lib/python3/dist-packages
  local modules
  modules=$(find "$pydist/paraview" "$pydist/vtkmodules" "$pydist/numpy" -name '*.so')
  local programs="/usr/bin/pvpython /usr/bin/pvbatch /usr/bin/Xvfb /usr/bin/xkbcomp
    /usr/lib/x86_64-linux-gnu/dri/swrast_dri.so /usr/lib/x86_64-linux-gnu/libGLX_mesa.so.0"
  # shellcheck disable=SC2086
  pvgpu_closure $programs $modules > "$out/libs.txt"
  {
    echo "$programs" | tr ' ' '\n' | sed '/^$/d'
    awk '{print $2}' "$out/libs.txt"
    echo /usr/lib/x86_64-linux-gnu/libglapi.so.0
    echo /usr/share/X11/xkb
    echo "$pydist/paraview"
    echo "$pydist/vtkmodules"
    echo "$pydist/numpy"
    find /usr/lib/python3.11 -mindepth 1 -maxdepth 1 \
      ! -name test ! -name idlelib ! -name tkinter ! -name turtledemo ! -name ensurepip \
      ! -name lib2to3 ! -name pydoc_data ! -name '__pycache__' ! -name 'config-*'
  } | sed 's|^/||' > "$out/files.txt"
  echo "packing $(wc -l < "$out/files.txt") paths ..." >&2
  (cd / && tar -ch --exclude='__pycache__' -T "$OLDPWD/$out/files.txt") |
    xz -T0 -6 | split -b "${part_mib}M" -d - "$out/part-"
  (cd "$out" && ls -l part-* && sha256sum part-*) > "$out/MANIFEST"
  cat "$out/MANIFEST"
}

pvgpu_plugin() {
  local build=${1:?usage: paraview-on-gpu.sh plugin BUILD_DIR}
  local src="$build/lib/paraview-plugins/InrVolume"
  [ -f "$src/InrVolume.so" ] || { echo "no plugin at $src: build target InrVolume first" >&2; return 1; }
  rm -rf .pvgpu/plugin && mkdir -p .pvgpu/plugin && cp -a "$src"/. .pvgpu/plugin/
  strip --strip-unneeded .pvgpu/plugin/*.so 2>/dev/null || true
  # What the plugin loads beyond pvpython's libraries (the GUI's Qt and pq* libraries: the
  # plugin carries its GUI behaviour), packed beside it.
  [ -f .pvgpu/libs.txt ] || { echo "run 'pack' first" >&2; return 1; }
  pvgpu_closure .pvgpu/plugin/*.so | grep -v -F -f <(awk '{print $1 " "}' .pvgpu/libs.txt) |
    awk '{print $2}' | sed 's|^/||' > .pvgpu/plugin-libs.txt
  (cd / && tar -ch -T "$OLDPWD/.pvgpu/plugin-libs.txt") | xz -T0 -6 > .pvgpu/plugin/libs.tar.xz
  echo "plugin: $(wc -l < .pvgpu/plugin-libs.txt) more libraries"
  du -sh .pvgpu/plugin
}

pvgpu_receive() {
  mkdir -p "$PVGPU_PARTS"
  local p n=0
  for p in .pvgpu/part-*; do
    [ -f "$p" ] || continue
    cp "$p" "$PVGPU_PARTS/" && n=$((n + 1))
  done
  echo "received $n part(s); now held: $(ls "$PVGPU_PARTS" | tr '\n' ' ')"
}

pvgpu_unpack() {
  pvgpu_receive
  if [ -f .pvgpu/MANIFEST ]; then
    (cd "$PVGPU_PARTS" && grep -E '^[0-9a-f]{64} ' "$OLDPWD/.pvgpu/MANIFEST" | sha256sum -c --quiet) ||
      { echo "parts missing or damaged: send them again (see .pvgpu/MANIFEST)" >&2; return 1; }
  fi
  mkdir -p "$PVGPU_ROOT"
  cat "$PVGPU_PARTS"/part-* | xz -d -T0 | tar -x -C "$PVGPU_ROOT"
  if [ -f .pvgpu/plugin/libs.tar.xz ]; then xz -d -c .pvgpu/plugin/libs.tar.xz | tar -x -C "$PVGPU_ROOT"; fi
  # pvpython and pvbatch find Debian's Python 3.11 through wrappers, so that PYTHONHOME does not
  # reach other programs (the machine's own python3).
  local r=$PVGPU_ROOT p
  mkdir -p "$r/bin"
  for p in pvpython pvbatch; do
    printf '#!/bin/sh\nPYTHONHOME=%s/usr PYTHONPATH=%s/usr/lib/python3/dist-packages exec %s/usr/bin/%s "$@"\n' \
      "$r" "$r" "$r" "$p" > "$r/bin/$p"
    chmod +x "$r/bin/$p"
  done
  du -sh "$PVGPU_ROOT"
}

pvgpu_env() {
  local r=$PVGPU_ROOT
  export PATH="$r/bin:$PATH"
  export PV_PLUGIN_PATH="${PV_PLUGIN_PATH:-$PWD/.pvgpu/plugin}"
  export LD_LIBRARY_PATH="$PV_PLUGIN_PATH:$r/usr/lib/x86_64-linux-gnu:$r/lib/x86_64-linux-gnu:$r/lib:/usr/local/cuda/lib64${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
  export LIBGL_DRIVERS_PATH="$r/usr/lib/x86_64-linux-gnu/dri"
  # Xvfb offers GLX through Mesa's software renderer; the clients (pvpython, pvbatch) take
  # NVIDIA's vendor library, so ParaView's OpenGL context is on the GPU.
  mkdir -p /tmp/.X11-unix
  # Xvfb runs xkbcomp from the folder it was built with (/usr/bin) to compile its keymap.
  [ -e /usr/bin/xkbcomp ] || ln -s "$r/usr/bin/xkbcomp" /usr/bin/xkbcomp
  "$r/usr/bin/Xvfb" :99 -screen 0 1920x1080x24 -nolisten tcp -xkbdir "$r/usr/share/X11/xkb" \
    >/tmp/xvfb.log 2>&1 &
  PVGPU_XVFB_PID=$!
  local i
  for i in $(seq 50); do [ -e /tmp/.X11-unix/X99 ] && break; sleep 0.1; done
  export DISPLAY=:99 __GLX_VENDOR_LIBRARY_NAME=nvidia
}

stop_xvfb() { [ -n "${PVGPU_XVFB_PID:-}" ] && kill "$PVGPU_XVFB_PID" 2>/dev/null || true; }

if [ "${BASH_SOURCE[0]}" = "$0" ]; then
  set -euo pipefail
  cmd=${1:-}; shift || true
  case "$cmd" in
    pack) pvgpu_pack "$@" ;;
    plugin) pvgpu_plugin "$@" ;;
    receive) pvgpu_receive ;;
    unpack) pvgpu_unpack ;;
    *) sed -n '2,30p' "$0"; exit 2 ;;
  esac
elif [ "${1:-}" = env ]; then
  set +eu
  pvgpu_env
fi
