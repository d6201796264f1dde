# The plugin on a GPU machine that has no ParaView (issue 27): run there after
# Tools/paraview-on-gpu.sh has carried and received ParaView's parts (see that script). The plugin
# and the inr program are built on the development machine with CUDA (nvcc compiles for sm_90
# without a GPU) in the build folder (default build-pvcuda, carried: BUILD/lib, BUILD/bin/inr,
# BUILD/Testing/Plugin); this suite builds nothing. STEPS, in order:
#   setup         .gl/ debs (libglvnd) into /, ParaView unpacked to /tmp/pvroot, pvpython and
#                 pvbatch linked into /usr/bin where the tests look for them
#   tests         the plugin's ctest tests (label plugin; the GUI, MPI and server ones left out
#                 unless PLUGIN_TESTS_EXCLUDE says otherwise) with the default backend (auto = CUDA)
#   session       Benchmarks/paraview/gpu_session.py on the shipped real models (GPU_SESSION_ARGS)
#   session-host  the same with INR_CUDA_GL_INTEROP=0 (image through host memory), for the
#                 per-render overhead before/after
#   timesteps     Benchmarks/paraview/time_step_cost.py (TIME_STEP_ARGS): where a time step's
#                 wall time goes (reader, view update, render), what Play pays per step
# Results under OUT/res, all of them in OUT/gpu_session_results.tar.gz.
SUITE_ABOUT="ParaView on a GPU: the plugin's tests, a pvpython session (time changes, drags, Play), time-step cost"
SUITE_COST="setup 1 min; session about 5 min per call on one H100; carrying ParaView takes several device calls"
SUITE_NEEDS="GPU + ParaView's parts carried (Tools/paraview-on-gpu.sh) + the plugin built with CUDA (build-pvcuda)"
SUITE_BEFORE=none
SUITE_DEFAULT_BUILD=build-pvcuda
SUITE_HELP='STEPS=session     any of: setup tests session session-host timesteps (in that order)
GPU_SESSION_ARGS= extra gpu_session.py arguments
TIME_STEP_ARGS=   extra time_step_cost.py arguments
PLUGIN_TESTS_EXCLUDE=gui|mpi|pvserver|panel   ctest -E for the tests step'

suite_run() {
  local step dir
  mkdir -p "$OUT/res"
  export PV_PLUGIN_PATH=$PWD/$BUILD/lib/paraview-plugins/InrVolume
  for step in ${STEPS:-session}; do
    stamp "$step"
    case "$step" in
      setup)
        for f in .gl/*.deb; do x dpkg -x "$f" /; done
        x ldconfig
        x bash Tools/paraview-on-gpu.sh unpack || return 1
        for p in pvpython pvbatch; do [ -e /usr/bin/$p ] || ln -s /tmp/pvroot/bin/$p /usr/bin/$p; done
        ;;
      tests)
        # shellcheck disable=SC1091
        [ "$DRY_RUN" = 1 ] || source Tools/paraview-on-gpu.sh env
        x ctest --test-dir "$BUILD/Testing/Plugin" -L plugin -E "${PLUGIN_TESTS_EXCLUDE:-gui|mpi|pvserver|panel}" -j4 --timeout 300 \
          --output-on-failure > "$OUT/res/plugin_tests.log" 2>&1
        tail -25 "$OUT/res/plugin_tests.log"
        [ "$DRY_RUN" = 1 ] || stop_xvfb
        ;;
      session | session-host)
        # shellcheck disable=SC1091
        [ "$DRY_RUN" = 1 ] || source Tools/paraview-on-gpu.sh env
        dir="$OUT/res/$step"
        [ "$step" = session-host ] && export INR_CUDA_GL_INTEROP=0
        # shellcheck disable=SC2086
        x env PYTHONUNBUFFERED=1 pvpython Benchmarks/paraview/gpu_session.py --inr "$BUILD/bin/inr" --out "$dir" \
          ${GPU_SESSION_ARGS:-} 2>&1 | tee "$dir.log" | grep -v "^\s*$" | tail -40
        unset INR_CUDA_GL_INTEROP
        [ "$DRY_RUN" = 1 ] || stop_xvfb
        ;;
      timesteps)
        # shellcheck disable=SC1091
        [ "$DRY_RUN" = 1 ] || source Tools/paraview-on-gpu.sh env
        # shellcheck disable=SC2086
        x env PYTHONUNBUFFERED=1 pvpython Benchmarks/paraview/time_step_cost.py ${TIME_STEP_ARGS:-} 2>&1 |
          tee "$OUT/res/time_step_cost.log" | grep -v "^\s*$" | tail -20
        [ "$DRY_RUN" = 1 ] || stop_xvfb
        ;;
      *) echo "paraview-gpu: unknown step $step (setup tests session session-host timesteps)" >&2; return 2 ;;
    esac
  done
  tar -czf "$OUT/gpu_session_results.tar.gz" -C "$OUT/res" .
}
