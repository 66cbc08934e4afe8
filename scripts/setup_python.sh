#!/usr/bin/env bash
# Creates (or refreshes) the project's Python environment at .venv/ with the pinned
# packages of scripts/requirements.txt (pip's VTK 9.5: the oracle the tests in tests/python
# hold fluidcast against), and installs the package `fluidcast` into it editable and without
# the VTK mapper (pip's VTK has no development files; the mapper lives in .venv-paraview, see
# scripts/setup_pyvista.sh): its helpers (cameras, transfer functions, VTK's SPH pipeline)
# then come from python/fluidcast as it is, and its Python module fluidcast._core is built.
# Idempotent: the environment is made once per requirements; the package reinstalled each run.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
venv="$root/.venv"
req="$root/scripts/requirements.txt"
stamp="$venv/.requirements.sha256"
want="$(cat "$req" "$root/pyproject.toml" | sha256sum | cut -d' ' -f1)"
if [[ ! -x "$venv/bin/python" || ! -f "$stamp" || "$(cat "$stamp")" != "$want" ]]; then
  python3 -m venv "$venv"
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check --upgrade pip
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$req"
  echo "$want" > "$stamp"
fi
# The package each run (its Python module is rebuilt by cargo where the Rust code changed).
log="$root/build/pip-helpers.log"
mkdir -p "$root/build"
"$venv/bin/python" -m pip install --disable-pip-version-check --no-deps --no-build-isolation \
  -Ccmake.define.FLUIDCAST_PYTHON_MAPPER=OFF -Cbuild-dir="$root/build/pip-helpers" \
  -e "$root" > "$log" 2>&1 || { tail -60 "$log"; exit 1; }
"$venv/bin/python" -c "import fluidcast._core" || { echo "fluidcast._core does not import in $venv" >&2; exit 1; }
