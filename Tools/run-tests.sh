#!/usr/bin/env bash
# The whole test suite: installs dependencies, builds, starts ONE Xvfb for everything that
# renders, runs ctest; then the checking builds: the model loader fuzzed for 200000 executions
# (Tools/run-fuzz.sh, clang) and the engine's CPU tests under ASan+UBSan (Tools/run-sanitizers.sh).
# Exits non-zero on any failure. GPU tests (label `cuda`) report as skipped on machines without a
# usable GPU. INR_SKIP_FUZZ=1 / INR_SKIP_SANITIZERS=1 leave out the checking builds.
set -euo pipefail
cd "$(dirname "$0")/.."
bash Tools/install-deps.sh
bash Tools/build.sh "$@"
BUILD_DIR=${INR_BUILD_DIR:-build}
source Tools/xvfb.sh
trap stop_xvfb EXIT
start_xvfb
failed=()
ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$(nproc)" --timeout 900 || failed+=(ctest)
stop_xvfb
trap - EXIT
step() {  # name, command...: runs it, timed; a failure is recorded, not fatal
  local name=$1 t0
  shift
  t0=$(date +%s)
  echo "run-tests: $name"
  "$@" || failed+=("$name")
  echo "run-tests: $name took $(( $(date +%s) - t0 )) s"
}
[ "${INR_SKIP_FUZZ:-0}" = 1 ] || step fuzz bash Tools/run-fuzz.sh 200000
[ "${INR_SKIP_SANITIZERS:-0}" = 1 ] || step sanitizers bash Tools/run-sanitizers.sh
if [ ${#failed[@]} -ne 0 ]; then
  echo "run-tests: FAILED: ${failed[*]}" >&2
  exit 1
fi
echo "run-tests: all passed"
