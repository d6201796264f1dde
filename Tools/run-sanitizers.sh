#!/usr/bin/env bash
# Builds the engine, the CLI and their CPU tests with AddressSanitizer + UndefinedBehaviorSanitizer
# (INR_SANITIZE=address,undefined; CUDA and ParaView off) in ${INR_SANITIZE_BUILD_DIR:-build-asan}
# and runs them. Exits non-zero on any test failure or sanitizer report.
#
#   Tools/run-sanitizers.sh [--build-only | --no-build] [extra ctest arguments, e.g. -R model]
#
# --build-only configures and builds, --no-build runs the tests of an existing build (what
# Tools/run-tests.sh does: it builds in the background while the main ctest runs). Only what the
# tests need is built (no benchmark programs). The tests run with INR_TEST_SMALL=1: the CLI tests
# whose checks hold at any size render smaller images (instrumented code is several times slower).
#
# Left out: the labels cuda (no CUDA in this build), paraview (needs the plugin) and python (PyTorch
# reference runs: slow, and the C++ they reach is covered by the cli tests); the bit-for-bit
# fingerprints of RenderRegression (recorded for the release flags; instrumented code contracts and
# vectorises floating point differently, so its images differ in the last bits); and
# cli.every_shipped_model (over 5 minutes instrumented; ModelRender.ShippedModels* renders the
# same models); and cli.brick_composite_{2,4}_shadows (110-120 s each instrumented, a third of
# the sanitizer run: 1400+ frames per render to converge; the brick and shadow code they reach is
# instrumented in BrickDecomposition.BricksCompositeToTheWholeImageWithAndWithoutShadows, and the
# CLI's --brick path in cli.brick_composite_{2,4}).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${INR_SANITIZE_BUILD_DIR:-build-asan}
SANITIZERS=${INR_SANITIZE:-address,undefined}
JOBS=${INR_SANITIZE_JOBS:-$(nproc)}
PHASE=all
case "${1:-}" in --build-only) PHASE=build; shift ;; --no-build) PHASE=test; shift ;; esac
start=$(date +%s)
EXCLUDE='^(RenderRegression\.|cli\.every_shipped_model$|cli\.brick_composite_[0-9]+_shadows$)'
if [ "$PHASE" != test ]; then
  # -g1: line tables for the reports at a fraction of -g's compile time.
  cmake -S . -B "$BUILD_DIR" -G Ninja -DINR_SANITIZE="$SANITIZERS" -DINR_ENABLE_CUDA=OFF \
    -DINR_ENABLE_PARAVIEW=OFF -DINR_BUILD_TESTS=ON -DINR_BUILD_BENCHMARKS=OFF \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" >/dev/null
  cmake --build "$BUILD_DIR" -j "$JOBS"
fi
if [ "$PHASE" = test ] && [ ! -f "$BUILD_DIR/build.ninja" ]; then
  echo "run-sanitizers: --no-build, but $BUILD_DIR holds no build" >&2
  exit 1
fi
built=$(date +%s)
if [ "$PHASE" = build ]; then
  echo "run-sanitizers ($SANITIZERS): built in $((built - start)) s"
  exit 0
fi

# A report ends the process with status 86, which no test expects; the reports are also searched
# for in the output of every test (passed ones included), so a test that accepts any failure
# status cannot hide one.
export ASAN_OPTIONS="halt_on_error=1:detect_leaks=1:exitcode=86"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:exitcode=86"
export INR_TEST_SMALL=1
set +e
ctest --test-dir "$BUILD_DIR" -LE "cuda|paraview|python" -E "$EXCLUDE" --output-on-failure -j "$JOBS" \
  --timeout 900 "$@"
rc=$?
set -e
LOG="$BUILD_DIR/Testing/Temporary/LastTest.log"
PATTERN='ERROR: (Address|Leak|UndefinedBehavior)Sanitizer|:[0-9]+:[0-9]+: runtime error: '
reports=$(grep -cE "$PATTERN" "$LOG" || true)
echo "run-sanitizers ($SANITIZERS): ctest exit status $rc, $reports sanitizer report(s);" \
     "build $((built - start)) s, tests $(($(date +%s) - built)) s"
if [ "$reports" -ne 0 ]; then
  grep -nE -A 25 "$PATTERN" "$LOG" | head -n 200 >&2
  exit 1
fi
exit "$rc"
