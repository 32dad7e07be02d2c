#!/usr/bin/env bash
# Installs the Debian packages stiffid needs to build, test and benchmark. Idempotent: it only
# calls apt-get when a package is missing. Run as root (CI and developer machines are root).
set -euo pipefail

packages=(
  build-essential cmake pkg-config
  libeigen3-dev libfftw3-dev libceres-dev libnlopt-dev libnlopt-cxx-dev coinor-libipopt-dev
  libboost-test-dev libboost-math-dev libboost-dev
  libcli11-dev nlohmann-json3-dev libfast-float-dev libsqlite3-dev libtbb-dev
  libopenmpi-dev openmpi-bin
  python3-numpy python3-scipy
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if ((${#missing[@]} == 0)); then
  echo "setup: all ${#packages[@]} packages present"
  exit 0
fi

echo "setup: installing ${missing[*]}"
SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
