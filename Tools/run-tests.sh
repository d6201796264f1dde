#!/usr/bin/env bash
# The whole test suite: installs dependencies, builds, starts ONE Xvfb for everything that
# renders, runs ctest; then the checking builds: the model loader fuzzed for 200000 executions
# (Tools/run-fuzz.sh, clang) and the engine's CPU tests under ASan+UBSan (Tools/run-sanitizers.sh).
# The sanitizer build starts at the lowest priority while ctest runs (ctest leaves cores idle:
# the tests that share the one X display run one at a time; log: build-asan.log in the build
# folder); after ctest it is stopped and resumed in the foreground at the command's own priority
# (ninja keeps what it finished). Exits non-zero on any failure. GPU tests (label `cuda`) report as skipped on
# machines without a usable GPU. INR_SKIP_FUZZ=1 / INR_SKIP_SANITIZERS=1 leave out the checking
# builds.
set -euo pipefail
cd "$(dirname "$0")/.."
bash Tools/install-deps.sh
# Without a usable GPU the GPU tests skip, so the CUDA code only has to compile: a compile check
# (INR_CUDA_COMPILE_CHECK: PTX for sm_90, the wgmma kernel compute_90a, NVVM's optimiser off).
# The front end (types, templates, static_asserts) and NVVM see every kernel; ptxas (register
# allocation, inline-PTX operands) runs only where a GPU is. Optimised device code was about two
# thirds of a 2-core build's compiler time (Docs/testing.md). The option is passed either way, so
# a build folder first made without a GPU builds optimised kernels once one is there; giving
# CMAKE_CUDA_ARCHITECTURES or INR_CUDA_COMPILE_CHECK here decides instead.
cuda_archs=()
if [[ " $* " != *CMAKE_CUDA_ARCHITECTURES* && " $* " != *INR_CUDA_COMPILE_CHECK* ]]; then
  if nvidia-smi -L >/dev/null 2>&1; then
    cuda_archs=("-DINR_CUDA_COMPILE_CHECK=OFF")
  else
    cuda_archs=("-DINR_CUDA_COMPILE_CHECK=ON")
    echo "run-tests: no usable GPU: CUDA code (if nvcc is found) is only compile-checked (PTX for sm_90, device optimiser off)"
  fi
fi
# The example (Tools/run-example.sh) configures the same folder without tests and benchmarks.
suite_args=()
[[ " $* " == *INR_BUILD_TESTS* ]] || suite_args+=(-DINR_BUILD_TESTS=ON)
[[ " $* " == *INR_BUILD_BENCHMARKS* ]] || suite_args+=(-DINR_BUILD_BENCHMARKS=ON)
bash Tools/build.sh "${cuda_archs[@]}" "${suite_args[@]}" "$@"
BUILD_DIR=${INR_BUILD_DIR:-build}
source Tools/xvfb.sh
SAN_PID=""
stop_background_build() {  # the build's own process group (setsid): bash, cmake, ninja, compilers
  if [ -n "$SAN_PID" ]; then
    kill -TERM -- "-$SAN_PID" 2>/dev/null || true
    wait "$SAN_PID" 2>/dev/null || true
    SAN_PID=""
  fi
}
cleanup() {
  stop_xvfb
  stop_background_build
}
trap cleanup EXIT
if [ "${INR_SKIP_SANITIZERS:-0}" != 1 ]; then
  nice -n 19 setsid bash Tools/run-sanitizers.sh --build-only > "$BUILD_DIR/build-asan.log" 2>&1 &
  SAN_PID=$!
fi
start_xvfb
failed=()
ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$(nproc)" --timeout 900 || failed+=(ctest)
stop_xvfb
stop_background_build
step() {  # name, command...: runs it, timed; a failure is recorded, not fatal
  local name=$1 t0
  shift
  t0=$(date +%s)
  echo "run-tests: $name"
  "$@" || failed+=("$name")
  echo "run-tests: $name took $(( $(date +%s) - t0 )) s"
}
[ "${INR_SKIP_FUZZ:-0}" = 1 ] || step fuzz bash Tools/run-fuzz.sh 200000
if [ "${INR_SKIP_SANITIZERS:-0}" != 1 ]; then
  step sanitizer-build bash Tools/run-sanitizers.sh --build-only
  case " ${failed[*]} " in
    *" sanitizer-build "*) ;;
    *) step sanitizers bash Tools/run-sanitizers.sh --no-build ;;
  esac
fi
trap - EXIT
if [ ${#failed[@]} -ne 0 ]; then
  echo "run-tests: FAILED: ${failed[*]}" >&2
  exit 1
fi
echo "run-tests: all passed"
