#!/usr/bin/env bash
# The plugin on a GPU machine that has no ParaView (issue "ParaView on a GPU"): run there, from
# the checkout's root, after Tools/paraview-on-gpu.sh has carried and received ParaView's parts
# (see that script). The plugin and the inr program are built here with CUDA (nvcc compiles
# for sm_90 without a GPU) in BUILD (default build-pvcuda, carried: BUILD/lib, BUILD/bin/inr,
# BUILD/Testing/Plugin).
#
#   bash Benchmarks/paraview/run_gpu_session.sh STEP... 
#     setup          .gl/ debs (libglvnd) into /, ParaView unpacked to /tmp/pvroot, pvpython and
#                    pvbatch linked into /usr/bin where the tests look for them
#     tests          the plugin's ctest tests (label plugin; the GUI, MPI and server ones left out
#                    unless PLUGIN_TESTS says otherwise) with the default backend (auto = CUDA)
#     session        Benchmarks/paraview/gpu_session.py on the shipped real models (GPU_SESSION_ARGS)
#     session-host   the same with INR_CUDA_GL_INTEROP=0 (image through host memory), for the
#                    per-render overhead before/after
#     timesteps      Benchmarks/paraview/time_step_cost.py (TIME_STEP_ARGS): where a time step's
#                    wall time goes (reader, view update, render), what Play pays per step
# Results under $OUT (or ./gpu-session-out): logs, CSV/JSON and screenshots in one tarball.
set -uo pipefail
BUILD=${BUILD:-build-pvcuda}
OUT=${OUT:-$PWD/gpu-session-out}
mkdir -p "$OUT/res"
export PV_PLUGIN_PATH=$PWD/$BUILD/lib/paraview-plugins/InrVolume

for step in "$@"; do
  case "$step" in
    setup)
      for f in .gl/*.deb; do dpkg -x "$f" /; done
      ldconfig
      bash Tools/paraview-on-gpu.sh unpack || exit 1
      for p in pvpython pvbatch; do [ -e /usr/bin/$p ] || ln -s /tmp/pvroot/bin/$p /usr/bin/$p; done
      ;;
    tests)
      # shellcheck disable=SC1091
      source Tools/paraview-on-gpu.sh env
      (cd "$BUILD/Testing/Plugin" &&
        ctest -L plugin -E "${PLUGIN_TESTS_EXCLUDE:-gui|mpi|pvserver|panel}" -j4 --timeout 300 \
          --output-on-failure) > "$OUT/res/plugin_tests.log" 2>&1
      tail -25 "$OUT/res/plugin_tests.log"
      stop_xvfb
      ;;
    session | session-host)
      # shellcheck disable=SC1091
      source Tools/paraview-on-gpu.sh env
      dir="$OUT/res/$step"
      [ "$step" = session-host ] && export INR_CUDA_GL_INTEROP=0
      PYTHONUNBUFFERED=1 pvpython Benchmarks/paraview/gpu_session.py --inr "$BUILD/bin/inr" --out "$dir" \
        ${GPU_SESSION_ARGS:-} 2>&1 | tee "$dir.log" | grep -v "^\s*$" | tail -40
      unset INR_CUDA_GL_INTEROP
      stop_xvfb
      ;;
    timesteps)
      # shellcheck disable=SC1091
      source Tools/paraview-on-gpu.sh env
      PYTHONUNBUFFERED=1 pvpython Benchmarks/paraview/time_step_cost.py ${TIME_STEP_ARGS:-} 2>&1 |
        tee "$OUT/res/time_step_cost.log" | grep -v "^\s*$" | tail -20
      stop_xvfb
      ;;
    *) echo "unknown step $step" >&2; exit 2 ;;
  esac
done
tar -czf "$OUT/gpu_session_results.tar.gz" -C "$OUT/res" .
ls -la "$OUT"
