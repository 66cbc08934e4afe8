"""pvbatch script run by pvbatch_mpi.py on 1, 2 and 3 MPI ranks: shows a multi-piece .pvtu
with the "fluidcast" representation and saves one screenshot per view (mpi_views.py).

    mpiexec -n N pvbatch --mpi pvbatch_mpi_render.py PLUGIN DATA.pvtu ARRAY OUTDIR TOLERANCE
            [RADIUS_ARRAY SCALE]

Writes OUTDIR/<view>.png and OUTDIR/info.json (ranks, and rank 0's owned and halo particle
counts and box). Runs on rank 0 (pvbatch's other ranks serve).
"""
import json
import os
import sys

from paraview.simple import LoadPlugin

from paraview import servermanager

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from mpi_views import render_views  # noqa: E402

plugin, data, array, out, tolerance = sys.argv[1:6]
radius = sys.argv[6:8]  # optional: FluidCastRadiusArray and FluidCastRadiusScale
LoadPlugin(plugin, remote=False, ns=globals())
info = render_views(data, array, out, tolerance, radius)
info["ranks"] = servermanager.vtkProcessModule.GetProcessModule().GetNumberOfLocalPartitions()
with open(os.path.join(out, "info.json"), "w") as f:
    json.dump(info, f)
print(json.dumps(info))
