#!/usr/bin/env bash
# Configures and builds INR Volume (optimised) into ${INR_BUILD_DIR:-build}. Extra arguments go
# to CMake, e.g. -DINR_ENABLE_CUDA=OFF or -DOptiX_INSTALL_DIR=/path/to/optix.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${INR_BUILD_DIR:-build}
cmake -S . -B "$BUILD_DIR" -G Ninja "$@"
cmake --build "$BUILD_DIR" -j "$(nproc)"
