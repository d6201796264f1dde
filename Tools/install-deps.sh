#!/usr/bin/env bash
# Installs what INR Volume needs to build and test on Debian 12 (apt). Skips apt entirely when
# everything is already there, so it also works for a non-root user on a prepared machine.
set -euo pipefail
PACKAGES=(build-essential cmake ninja-build pkg-config
  libeigen3-dev nlohmann-json3-dev libgtest-dev libpng-dev
  python3 python3-numpy python3-torch
  xvfb xauth
  clang libclang-rt-dev  # Tools/run-fuzz.sh: libFuzzer and the sanitizer runtimes for clang
  # ParaView plugin: Debian's ParaView 5.11 SDK. find_package(ParaView) makes every module's
  # dependency required, hence the -dev list (../shared/PLATFORM.md; do NOT add libvtk9-dev).
  paraview paraview-dev python3-paraview openmpi-bin mpi-default-dev libhdf5-mpi-dev
  qtbase5-dev qttools5-dev libqt5svg5-dev libqt5opengl5-dev libglm-dev libboost-dev libgdal-dev
  libnetcdf-dev libutfcpp-dev libavcodec-dev libavformat-dev libavutil-dev libswscale-dev
  libgl2ps-dev libglew-dev libtheora-dev libxml2-dev libexpat1-dev liblzma-dev liblz4-dev
  libdouble-conversion-dev libjpeg-dev libtiff-dev libfreetype-dev zlib1g-dev libx11-dev libxt-dev
  libgl-dev libpython3-dev python3-dev
  iproute2)  # `ip link set lo up` for the pvserver test in a private network namespace
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi
echo "install-deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install-deps: done"
