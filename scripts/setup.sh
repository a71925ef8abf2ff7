#!/usr/bin/env bash
# Installs bgkmap's build and test dependencies from Debian 12's archive. Idempotent and
# non-interactive: does nothing when everything is already installed.
set -euo pipefail

packages=(
  build-essential cmake pkg-config
  libeigen3-dev libpcl-dev liboctomap-dev libnanoflann-dev
  ocl-icd-opencl-dev opencl-clhpp-headers opencl-c-headers pocl-opencl-icd clinfo
  libgtest-dev libbenchmark-dev
  libcli11-dev nlohmann-json3-dev libyaml-cpp-dev zlib1g-dev libssl-dev
  libcairo2-dev
  libnlopt-cxx-dev  # bgkmap tune: NLopt's DIRECT-L and BOBYQA
  librosbag-storage-dev libsensor-msgs-dev libtf2-dev libtf2-msgs-dev libgeometry-msgs-dev libroscpp-core-dev libbz2-dev  # ROS 1 bags
  libopenmpi-dev openmpi-bin
  python3 python3-dev pybind11-dev python3-pybind11 python3-numpy python3-pytest
  python3-setuptools python3-wheel python3-pip python3-venv  # pip install . (pyproject.toml, setup.py)
  clang-14 libclang-rt-14-dev  # scripts/fuzz.sh: libFuzzer and clang's sanitizer runtimes
  chromium python3-pil  # the browser test of bgkmap view (a page and its screenshot)
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#packages[@]} packages already installed"
  exit 0
fi

sudo=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "setup: need root (or sudo) to install: ${missing[*]}" >&2; exit 1; }
  sudo="sudo"
fi
echo "setup: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -q
$sudo apt-get install -y -q --no-install-recommends "${missing[@]}"
