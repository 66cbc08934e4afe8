#!/usr/bin/env bash
# Creates (or refreshes) .venv-paraview: Debian's Python with ParaView's VTK 9.2 and a pinned
# pyvista (scripts/requirements-paraview.txt), then builds and installs the package `fluidcast`
# into it (`pip install .`: the Rust core with cargo, the VTK mapper with CMake against that
# VTK, the pyvista helper and the CLI). This is the environment where
# `import fluidcast; fluidcast.add_particles(plotter, ...)` works (tests/pyvista).
# Idempotent: the environment is made once per requirements file; the package is reinstalled
# each run, and its build folder (build/pip-*) and cargo's target/ only rebuild what changed.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
bash scripts/setup_system.sh
venv="$root/.venv-paraview"
req="$root/scripts/requirements-paraview.txt"
stamp="$venv/.requirements.sha256"
want="$(sha256sum "$req" | cut -d' ' -f1)"
if [[ ! -x "$venv/bin/python" || ! -f "$stamp" || "$(cat "$stamp")" != "$want" ]]; then
  /usr/bin/python3 -m venv --system-site-packages "$venv"
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps -r "$req"
  echo "$want" > "$stamp"
fi
log="$root/build/pip-install.log"
mkdir -p "$root/build"
"$venv/bin/python" -m pip install --disable-pip-version-check --no-deps --no-build-isolation \
  --force-reinstall "$root" > "$log" 2>&1 || { tail -60 "$log"; exit 1; }
"$venv/bin/python" -c "import fluidcast, vtkmodules; fluidcast.vtkFluidCastVolumeMapper; \
print(f'fluidcast {fluidcast.__version__} with its VTK mapper on VTK {vtkmodules.__version__}: $venv')"
