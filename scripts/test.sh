#!/usr/bin/env bash
# Runs every test: the Rust workspace, then the Python tests that hold fluidcast against
# VTK itself (reader, vtkSPHInterpolator, camera, transfer function, VTK's volume rendering
# of the resampled field), then builds the VTK mapper and ParaView plugin and runs their
# ctest tests, then installs the Python package with the mapper into .venv-paraview and runs
# its pyvista tests. Installs missing system packages and sets up .venv/ first (idempotent).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
# Mesa's Vulkan and Qt want a runtime directory; CI shells often have none.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp/fluidcast-runtime-$(id -u)}"
mkdir -p -m 700 "$XDG_RUNTIME_DIR"
# The tests that read ../shared/data fail, not skip, when it is missing (CI lays it beside the
# clone; run elsewhere without it, unset this to skip those tests).
export FLUIDCAST_REQUIRE_DATA="${FLUIDCAST_REQUIRE_DATA:-1}"
bash scripts/setup_system.sh
bash scripts/setup_python.sh
cargo build --bin fluidcast
# setup_system.sh installed lavapipe, so the GPU tests must find an adapter, not skip.
FLUIDCAST_REQUIRE_GPU=1 cargo test --workspace
.venv/bin/ruff check python tests examples
.venv/bin/python -m pytest -q tests/python
# The VTK mapper in real VTK windows and the ParaView plugin in pvbatch (under Xvfb).
bash scripts/setup_vtk.sh
ctest --test-dir build --output-on-failure
# The package `fluidcast` (mapper + pyvista helper) in a pyvista Plotter, on ParaView's VTK.
bash scripts/setup_pyvista.sh
tests/vtk/with_xvfb.sh .venv-paraview/bin/python -m pytest -q tests/pyvista
