#!/usr/bin/env bash
# Creates (or refreshes) the project's Python environment at .venv/ with the pinned
# packages of scripts/requirements.txt (pip's VTK 9.5: the oracle the tests in tests/python
# hold fluidcast against), and installs the package `fluidcast` into it editable and without
# the VTK mapper (pip's VTK has no development files; the mapper lives in .venv-paraview, see
# scripts/setup_pyvista.sh): its helpers (cameras, transfer functions, VTK's SPH pipeline)
# then come from python/fluidcast as it is. Idempotent: a second run only checks the pins.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
venv="$root/.venv"
req="$root/scripts/requirements.txt"
stamp="$venv/.requirements.sha256"
want="$(cat "$req" "$root/pyproject.toml" | sha256sum | cut -d' ' -f1)"
if [[ -x "$venv/bin/python" && -f "$stamp" && "$(cat "$stamp")" == "$want" ]]; then
  exit 0
fi
python3 -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check --upgrade pip
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$req"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps \
  --no-build-isolation -Ccmake.define.FLUIDCAST_PYTHON_MAPPER=OFF -Cbuild-dir="$root/build/pip-helpers" \
  -e "$root"
echo "$want" > "$stamp"
echo "python environment ready: $venv"
