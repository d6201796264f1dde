#!/usr/bin/env bash
# The whole test suite: installs dependencies, builds, starts ONE Xvfb for everything that
# renders, runs ctest. Exits non-zero on any failure. GPU tests (label `cuda`) report as skipped
# on machines without a usable GPU.
set -euo pipefail
cd "$(dirname "$0")/.."
bash Tools/install-deps.sh
bash Tools/build.sh "$@"
BUILD_DIR=${INR_BUILD_DIR:-build}
source Tools/xvfb.sh
trap stop_xvfb EXIT
start_xvfb
ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$(nproc)" --timeout 900
