#!/usr/bin/env bash
# Runs every test: the Rust workspace, then the Python tests that hold fluidcast against
# VTK itself (reader, vtkSPHInterpolator, camera, transfer function, VTK's volume rendering
# of the resampled field), then builds the VTK mapper and ParaView plugin and runs their
# ctest tests, then installs the Python package with the mapper into .venv-paraview and runs
# its pyvista tests, then the Python module in a plain venv with PyPI's VTK (tests/module).
# Installs missing system packages and sets up .venv/ first (idempotent).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
# Mesa's Vulkan and Qt want a runtime directory; CI shells often have none.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp/fluidcast-runtime-$(id -u)}"
mkdir -p -m 700 "$XDG_RUNTIME_DIR"
# The tests that read ../shared/data fail, not skip, when it is missing (CI lays it beside the
# clone; run elsewhere without it, unset this to skip those tests).
export FLUIDCAST_REQUIRE_DATA="${FLUIDCAST_REQUIRE_DATA:-1}"
# CI builds once, from a fresh clone: incremental caches would only take disk.
if [ "${CI:-}" = true ]; then export CARGO_INCREMENTAL=0; fi
# A fresh build and test run writes about 3 GiB (target/, build/, the venvs). Say so up front
# when the disk is short: cargo's own message is a compiler crash that names no cause.
avail_mib=$(( $(df -Pk . | awk 'NR==2 {print $4}') / 1024 ))
if [ "$avail_mib" -lt 4096 ]; then
  echo "scripts/test.sh: warning: only ${avail_mib} MiB free on this disk; a fresh build" \
    "and test run needs about 3 GiB, so it may fail with 'No space left on device'" >&2
fi
bash scripts/setup_system.sh
bash scripts/setup_python.sh
# Test reports of this run only (scripts/check_test_reports.py reads them at the end).
rm -rf build/reports
mkdir -p build/reports
cargo build --bin fluidcast
# setup_system.sh installed lavapipe, so the GPU tests must find an adapter, not skip.
FLUIDCAST_REQUIRE_GPU=1 cargo test --workspace
.venv/bin/ruff check python tests examples scripts
# No Rust function outside tests over 80 lines (prints the longest five).
.venv/bin/python scripts/function_lengths.py --fail
.venv/bin/python -m pytest -q tests/python --junitxml=build/reports/pytest-python.xml
# The VTK mapper in real VTK windows and the ParaView plugin in pvbatch (under Xvfb).
bash scripts/setup_vtk.sh
ctest --test-dir build --output-on-failure --output-junit reports/ctest.xml
# The package `fluidcast` (mapper + pyvista helper) in a pyvista Plotter, on ParaView's VTK.
bash scripts/setup_pyvista.sh
tests/vtk/with_xvfb.sh .venv-paraview/bin/python -m pytest -q tests/pyvista \
  --junitxml=build/reports/pytest-pyvista.xml
# The Python module fluidcast._core, and add_particles without the mapper: `pip install .` into a
# plain venv with PyPI's VTK and pyvista; then the same tests on ParaView's VTK, where both
# routes (mapper and module) run and are compared.
bash scripts/setup_pip_venv.sh
tests/vtk/with_xvfb.sh .venv-pip/bin/python -m pytest -q tests/module \
  --junitxml=build/reports/pytest-module-pip.xml
tests/vtk/with_xvfb.sh .venv-paraview/bin/python -m pytest -q tests/module \
  --junitxml=build/reports/pytest-module-paraview.xml
# The README's and docs' blocks marked runnable, on the shipped data: shell (the release CLI
# that setup_vtk.sh built), Python with pyvista (the pip-installed package) and pvbatch (the
# plugin).
tests/vtk/with_xvfb.sh .venv/bin/python scripts/run_doc_blocks.py --python .venv-pip/bin/python \
  --pvbatch pvbatch
# A skipped test, or a ctest test that CMake did not register (a program not found), fails the
# test command instead of passing quietly (skips are only listed with FLUIDCAST_REQUIRE_DATA=0).
skips=()
[ "$FLUIDCAST_REQUIRE_DATA" = 1 ] || skips=(--allow-skips)
.venv/bin/python scripts/check_test_reports.py --expect tests/vtk/expected_ctest.txt "${skips[@]}" \
  build/reports/pytest-python.xml build/reports/ctest.xml build/reports/pytest-pyvista.xml \
  build/reports/pytest-module-pip.xml build/reports/pytest-module-paraview.xml
