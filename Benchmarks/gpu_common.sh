# Sourced by the run_*.sh scripts of this folder: works from the repository root, results in
# $OUT (default gpu-results), build in $BUILD (INR_BUILD_DIR, default build-gpu), and
#   gpu_configure [extra CMake args]  configures for this machine's GPU (log in $OUT/configure.log)
#   gpu_ctest [extra ctest args]      runs the GPU tests (ctest -L cuda, log in $OUT/ctest_cuda.log)
#   gpu_configure_release SRC BUILD [extra CMake args]  an sm_90 Release build of SRC's engine
#   gpu_source_of COMMIT DIR          that commit's tree in DIR (git archive), built beside this one
#   gpu_start_before_build LOGDIR JOBS SECONDS TARGETS  $BEFORE's tree configured in
#                                     /tmp/before-build (returns 1 where that fails) and TARGETS
#                                     built there in the background (pid in gpu_before_pid; logs
#                                     LOGDIR/configure_before.log, build_before.log)
#   gpu_build_with_before LOGDIR BEFORE_TARGETS -- TARGETS  builds TARGETS here in $BUILD (16 jobs)
#                                     and, when $BEFORE names a commit, BEFORE_TARGETS of its tree
#                                     in /tmp/before-build beside it (4 jobs); prints the spills
#   gpu_hopper_spills BUILD_LOG       the Hopper kernels' spills and any wgmma serialisation
#                                     warning (ptxas C75xx) in a build's log
#   stamp MESSAGE                     a step's heading with the seconds since the script began
#   TIME_TO_IMAGE_ARGS, TIME_TO_IMAGE_MODELS  query_reduction_benchmark's time-to-image protocol
#                                     (issue 26) and the shipped full-size models it runs on
set -uo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
OUT=${OUT:-gpu-results}
mkdir -p "$OUT"
BUILD=${INR_BUILD_DIR:-build-gpu}

gpu_configure() {
  local arch
  arch=$(nvidia-smi --query-gpu=compute_cap --format=csv,noheader 2>/dev/null | head -1 | tr -d .)
  cmake -S . -B "$BUILD" -G Ninja -DINR_ENABLE_PARAVIEW=OFF -DCMAKE_CUDA_ARCHITECTURES="${arch:-90}" "$@" \
    > "$OUT/configure.log" 2>&1 || { tail -30 "$OUT/configure.log"; exit 1; }
}

gpu_ctest() {
  echo "== GPU tests"
  ctest --test-dir "$BUILD" -L cuda --output-on-failure "$@" 2>&1 | tee "$OUT/ctest_cuda.log" \
    | grep -vE "^\s*(Start|Test command)" | tail -40
}

gpu_hopper_spills() {
  grep -E "spill|C75[0-9][0-9]" "$1" | grep -iE "hopper|C75" | sed 's/.*function //' | cut -c1-200
}

gpu_start=$(date +%s)

# Time to a clean image (run_time_to_image.sh, run_gradient_opacity_time_to_image.sh): 1024^2,
# 1.5 s of summed frame times (at least 8 frames) per configuration against a 4096-frame
# delta-tracking reference, no orbit or heatmaps, the GPU ray marcher at four steps.
TIME_TO_IMAGE_ARGS=(--backend cuda --size 1024 --seconds 1.5 --min-frames 8 --reference-frames 4096 --orbit-steps 0
                    --heatmap-frames 0 --march-steps 64,128,256,512)
TIME_TO_IMAGE_MODELS="Testing/Data/real/siren_cylinder_vorticity.inr Testing/Data/real/ffn_mri_head.inr Testing/Data/real/coordnet_cylinder_u.inr"
stamp() { echo "== $1 ($(($(date +%s) - gpu_start)) s)"; }

gpu_configure_release() {
  local src=$1 build=$2
  shift 2
  cmake -S "$src" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DINR_ENABLE_PARAVIEW=OFF -DINR_ENABLE_CUDA=ON \
    -DCMAKE_CUDA_ARCHITECTURES=90 "$@"
}

gpu_source_of() {
  rm -rf "$2" && mkdir -p "$2" && git archive "$1" | tar -x -C "$2"
}

gpu_start_before_build() {
  local log=$1 jobs=$2 seconds=$3
  shift 3
  gpu_before_pid=
  gpu_source_of "$BEFORE" /tmp/before-src
  gpu_configure_release /tmp/before-src /tmp/before-build \
    ${OptiX_INSTALL_DIR:+-DOptiX_INSTALL_DIR="$OptiX_INSTALL_DIR"} > "$log/configure_before.log" 2>&1 \
    || { tail -30 "$log/configure_before.log"; return 1; }
  timeout "$seconds" ninja -C /tmp/before-build -j"$jobs" "$@" > "$log/build_before.log" 2>&1 &
  gpu_before_pid=$!
}

gpu_build_with_before() {
  local log=$1 before_targets=() targets=()
  shift
  while [ $# -gt 0 ] && [ "$1" != -- ]; do before_targets+=("$1"); shift; done
  shift
  targets=("$@")
  gpu_configure_release . "$BUILD" ${OptiX_INSTALL_DIR:+-DOptiX_INSTALL_DIR="$OptiX_INSTALL_DIR"} \
    > "$log/configure.log" 2>&1 || { tail -30 "$log/configure.log"; exit 1; }
  gpu_before_pid=
  if [ -n "${BEFORE:-}" ]; then
    gpu_start_before_build "$log" 4 500 "${before_targets[@]}" || exit 1
  fi
  timeout 500 ninja -C "$BUILD" -j16 "${targets[@]}" > "$log/build.log" 2>&1 \
    || { grep -E "error|FAILED" "$log/build.log" | head -30; exit 1; }
  if [ -n "$gpu_before_pid" ]; then
    wait "$gpu_before_pid" || { grep -E "error|FAILED" "$log/build_before.log" | head; exit 1; }
  fi
  grep -iE "spill" "$log/build.log" | sed 's/.*function//' | sort | uniq -c | head -20
}
