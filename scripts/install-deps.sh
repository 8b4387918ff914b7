#!/usr/bin/env bash
# Installs every Debian 12 package FEMesher needs to build, test and benchmark.
# Idempotent: apt-get skips what is already there. Run as root (or with sudo).
set -euo pipefail

PACKAGES=(
  # toolchain
  build-essential cmake ninja-build ccache pkg-config git
  # libraries
  libinsighttoolkit5-dev libvtk9-dev libvtk9-qt-dev libcgal-dev libtet1.5-dev
  libtbb-dev libeigen3-dev libgmp-dev libmpfr-dev libboost-dev zlib1g-dev
  nlohmann-json3-dev libcli11-dev
  qtbase5-dev libqt5opengl5-dev
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  # real readers / solvers used by the tests
  python3 python3-numpy python3-meshio gmsh calculix-ccx
  # GUI tests
  xvfb xauth imagemagick
  # cohorts: the Snakemake workflow, and the single-node Slurm its test starts
  snakemake slurm-wlm munge
)

SUDO=""
if [ "$(id -u)" != "0" ]; then SUDO="sudo"; fi

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages already installed"
  exit 0
fi

echo "install-deps: installing ${#missing[@]} packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
