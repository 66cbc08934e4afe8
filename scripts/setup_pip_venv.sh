#!/usr/bin/env bash
# Creates (or refreshes) .venv-pip: a plain `python3 -m venv` with PyPI's VTK and pyvista
# (scripts/requirements-pip.txt), into which `pip install .` builds the package as a user's
# pip would (build isolation: scikit-build-core from PyPI; the Python module fluidcast._core
# and the CLI with cargo; no VTK mapper, since pip's VTK has no development files, which the
# build says in a note). tests/module run here. Idempotent: the environment is made once per
# requirements file; the package is reinstalled each run (cargo's target/ and the build
# folder only rebuild what changed).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
venv="$root/.venv-pip"
req="$root/scripts/requirements-pip.txt"
stamp="$venv/.requirements.sha256"
want="$(sha256sum "$req" | cut -d' ' -f1)"
if [[ ! -x "$venv/bin/python" || ! -f "$stamp" || "$(cat "$stamp")" != "$want" ]]; then
  rm -rf "$venv"
  python3 -m venv "$venv"
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$req"
  echo "$want" > "$stamp"
fi
log="$root/build/pip-venv-install.log"
mkdir -p "$root/build"
"$venv/bin/python" -m pip install --disable-pip-version-check --force-reinstall --no-deps \
  -Cbuild-dir="$root/build/pip-plain" "$root" > "$log" 2>&1 || { tail -60 "$log"; exit 1; }
"$venv/bin/python" -c "import fluidcast, fluidcast._core, vtkmodules, pyvista; \
print(f'fluidcast {fluidcast.__version__} (module) on VTK {vtkmodules.__version__}, \
pyvista {pyvista.__version__}: $venv')"
