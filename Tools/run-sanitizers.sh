#!/usr/bin/env bash
# Builds the engine, the CLI and their CPU tests with AddressSanitizer + UndefinedBehaviorSanitizer
# (INR_SANITIZE=address,undefined; CUDA and ParaView off) in ${INR_SANITIZE_BUILD_DIR:-build-asan}
# and runs them. Exits non-zero on any test failure or sanitizer report (reports are collected in
# <build>/sanitizer-reports, so an error that a test expects cannot hide one).
#
#   Tools/run-sanitizers.sh [extra ctest arguments, e.g. -R model]
#
# Labels left out: cuda (no CUDA in this build), paraview (needs the plugin), python (PyTorch
# reference runs: slow, and the C++ they reach is covered by the cli tests).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${INR_SANITIZE_BUILD_DIR:-build-asan}
SANITIZERS=${INR_SANITIZE:-address,undefined}
JOBS=${INR_SANITIZE_JOBS:-$(nproc)}
start=$(date +%s)
# -g1: line tables for the reports at a fraction of -g's compile time.
cmake -S . -B "$BUILD_DIR" -G Ninja -DINR_SANITIZE="$SANITIZERS" -DINR_ENABLE_CUDA=OFF \
  -DINR_ENABLE_PARAVIEW=OFF -DINR_BUILD_TESTS=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" >/dev/null
cmake --build "$BUILD_DIR" -j "$JOBS"
built=$(date +%s)

REPORTS="$(pwd)/$BUILD_DIR/sanitizer-reports"
rm -rf "$REPORTS"
mkdir -p "$REPORTS"
export ASAN_OPTIONS="halt_on_error=1:detect_leaks=1:log_path=$REPORTS/asan"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:log_path=$REPORTS/ubsan"
set +e
ctest --test-dir "$BUILD_DIR" -LE "cuda|paraview|python" --output-on-failure -j "$JOBS" --timeout 900 "$@"
rc=$?
set -e
reports=$(find "$REPORTS" -type f | wc -l)
echo "run-sanitizers ($SANITIZERS): ctest exit status $rc, $reports sanitizer report(s);" \
     "build $((built - start)) s, tests $(($(date +%s) - built)) s"
if [ "$reports" -ne 0 ]; then
  for f in "$REPORTS"/*; do
    echo "=== $f" >&2
    head -n 60 "$f" >&2
  done
  exit 1
fi
exit "$rc"
