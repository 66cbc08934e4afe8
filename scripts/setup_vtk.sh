#!/usr/bin/env bash
# Builds fluidcast's C++ side: the VTK volume mapper (cpp_bridge/), the ParaView plugin
# (paraview/) and their tests (tests/vtk/), in build/. Installs the Debian packages first
# (scripts/setup_system.sh). Idempotent: a second run only rebuilds what changed.
#
# Afterwards:  ctest --test-dir build --output-on-failure
#              LD_PRELOAD=$PWD/build/lib/libfluidcast_expat_fix.so paraview   (then Tools >
#              Manage Plugins > Load New: build/lib/paraview-plugins/fluidcast/fluidcast.so)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
bash scripts/setup_system.sh
mkdir -p build
log=build/setup.log
cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo > "$log" 2>&1 || { cat "$log"; exit 1; }
cmake --build build -j"$(nproc)" >> "$log" 2>&1 || { tail -60 "$log"; exit 1; }
echo "built: build/lib/libfluidcastRendering.so, build/lib/paraview-plugins/fluidcast/fluidcast.so"
