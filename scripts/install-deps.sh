#!/usr/bin/env bash
# Installs every build and test dependency of strut from Debian packages.
# Idempotent: packages already present are left alone; apt runs only when something is missing.
set -euo pipefail
packages=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev libhdf5-dev hdf5-tools libspdlog-dev libfmt-dev libcli11-dev
  libmodbus-dev libgtest-dev libgmock-dev libsundials-dev liblapack-dev clang-14 libclang-rt-14-dev
  nlohmann-json3-dev libtomlplusplus-dev libmatio-dev libsqlite3-dev libcpp-httplib-dev
  python3-h5py python3-numpy
  python3-dev pybind11-dev python3-pybind11 python3-pandas python3-pytest
  chromium
  python3-pymodbus python3-serial-asyncio
  libpq-dev postgresql slurm-wlm munge
)
# npm fetches uPlot for the HTML reports at configure time (report/web/package-lock.json); it comes
# with the machine's Node.js, and Debian's package provides it where Node.js is missing.
command -v npm >/dev/null 2>&1 || packages+=(npm)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "install-deps: installing ${missing[*]}"
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
