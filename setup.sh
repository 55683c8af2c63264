#!/usr/bin/env bash
# Installs what isohex needs from Debian 12's archive (nothing else is
# downloaded), builds it in ./build, and runs it on a bundled sample.
#   ./setup.sh            as root (or with sudo available)
#   ./setup.sh --no-demo  install and build only
set -euo pipefail
cd "$(dirname "$0")"

PACKAGES=(
  # toolchain
  cmake ninja-build g++ pkg-config
  # libraries isohex links
  libopenvdb-dev libboost-iostreams-dev libinsighttoolkit5-dev libnifti2-dev libeigen3-dev libtbb-dev
  libopenexr-dev libassimp-dev libcli11-dev nlohmann-json3-dev zlib1g-dev libtiff-dev libgdcm-dev libcsv-dev
  libvtk9-dev libgmsh-dev libexodusii-dev libnetcdf-dev libcgal-dev
  libgtest-dev
  # independent tools the tests check isohex's output with
  python3 python3-numpy python3-vtk9 python3-meshio gmsh calculix-ccx snakemake
  # a single-node SLURM cluster for workflow/Snakefile's test (tests/py/test_slurm_cohort.py
  # starts its own munged, slurmctld and slurmd; nothing is started here)
  slurmctld slurmd slurm-client munge
  # the bench's heap profile at peak (bench/memory_peak.py)
  heaptrack
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing ${#missing[@]} Debian package(s): ${missing[*]}"
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build -j"$(nproc)"

if [ "${1:-}" != "--no-demo" ]; then
  mkdir -p out
  echo
  echo "setup: built ./build/cli/isohex; meshing the bundled skull CT (samples/skull_ct.nii.gz):"
  echo "+ ./build/cli/isohex mesh samples/skull_ct.nii.gz --iso 2.9 -o out/skull.vtu -o out/skull.inp --report out/skull.json --plot out/skull.svg --force"
  ./build/cli/isohex mesh samples/skull_ct.nii.gz --iso 2.9 -o out/skull.vtu -o out/skull.inp \
    --report out/skull.json --plot out/skull.svg --force
fi
