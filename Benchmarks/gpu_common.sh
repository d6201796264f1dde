# Sourced by run_gpu.sh and run_gpu_pipeline.sh: works from the repository root, results in
# $OUT (default gpu-results), build in $BUILD (INR_BUILD_DIR, default build-gpu), and
#   gpu_configure [extra CMake args]  configures for this machine's GPU (log in $OUT/configure.log)
#   gpu_ctest [extra ctest args]      runs the GPU tests (ctest -L cuda, log in $OUT/ctest_cuda.log)
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
