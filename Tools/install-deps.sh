#!/usr/bin/env bash
# Installs what INR Volume needs to build and test on Debian 12 (apt). Skips apt entirely when
# everything is already there, so it also works for a non-root user on a prepared machine.
set -euo pipefail
PACKAGES=(build-essential cmake ninja-build pkg-config
  libeigen3-dev nlohmann-json3-dev libgtest-dev libpng-dev
  python3 python3-numpy python3-torch
  xvfb xauth)
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
