#!/usr/bin/env bash
# Builds isohex (if needed) and runs the whole test suite: GoogleTest unit
# tests and end-to-end tests that check the built binary with VTK, meshio,
# gmsh and CalculiX. Run ./setup.sh once first.
set -euo pipefail
cd "$(dirname "$0")"
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build build -j"$(nproc)"
ctest --test-dir build --output-on-failure --no-tests=error -j"$(nproc)"
