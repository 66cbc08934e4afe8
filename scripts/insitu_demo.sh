#!/usr/bin/env bash
# In situ demo (issue 50): SPlisHSPlasH's double dam break rendered through ParaView Catalyst
# by fluidcast while it runs, no particle files needed.
#
#   scripts/insitu_demo.sh OUTDIR RANKS STEPS [EVERY]
#
# RANKS = 1: SPlisHSPlasH in this process (examples/insitu_splash.py); RANKS > 1: the MPI
# stand-in (mpiexec, each rank its own slab of the same simulation; see that script). Writes
# OUTDIR/insitu_%04d.png every EVERY (10) steps and, for checking, the same steps' particles
# as OUTDIR/step_%04d.vtu with OUTDIR/camera.json, range.txt and array.txt, so that
#   fluidcast render OUTDIR/step_K.vtu --camera OUTDIR/camera.json \
#     --range $(cat OUTDIR/range.txt) --array $(cat OUTDIR/array.txt) --size 400x300
# draws the same image. Needs the build (cmake --build build) and .venv-paraview with
# pysplishsplash (scripts/setup_pyvista.sh).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
if [[ $# -lt 3 ]]; then
  echo "usage: $0 OUTDIR RANKS STEPS [EVERY]" >&2
  exit 2
fi
outdir="$1" ranks="$2" steps="$3" every="${4:-10}"
plugin="$root/build/lib/paraview-plugins/fluidcast/fluidcast.so"
python="$root/.venv-paraview/bin/python"
for f in "$plugin" "$python"; do
  [[ -e "$f" ]] || { echo "error: $f is missing: run cmake --build build and scripts/setup_pyvista.sh" >&2; exit 1; }
done
mkdir -p "$outdir" "${XDG_RUNTIME_DIR:=/tmp/xdg-$UID}"
chmod 700 "$XDG_RUNTIME_DIR"
export XDG_RUNTIME_DIR FLUIDCAST_PARAVIEW_PLUGIN="$plugin"
# pysplishsplash's wheel segfaults on import without libGLdispatch preloaded; ParaView's
# plugins need the expat symbols fix that the build makes.
export LD_PRELOAD="/lib/x86_64-linux-gnu/libGLdispatch.so.0:$root/build/lib/libfluidcast_expat_fix.so"
run=("$root/tests/vtk/with_xvfb.sh" "$python" "$root/examples/insitu_splash.py" "$outdir" "$steps"
     --every "$every" --write-particles)
if [[ "$ranks" == 1 ]]; then
  "${run[@]}"
else
  # One OpenMP thread per rank: every rank runs the same simulation and must stay identical.
  mpiexec --allow-run-as-root --oversubscribe -n "$ranks" env OMP_NUM_THREADS=1 "${run[@]}"
fi
