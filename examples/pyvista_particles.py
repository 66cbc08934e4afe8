#!/usr/bin/env python3
"""fluidcast in a pyvista Plotter: SPH particles volume rendered beside ordinary meshes.

    .venv-paraview/bin/python examples/pyvista_particles.py [DATA.vtu] [-o OUT.png]

(.venv-paraview: `bash scripts/setup_pyvista.sh`; needs a display, e.g. under
tests/vtk/with_xvfb.sh, since Debian's VTK draws through X even offscreen.) Without -o the
plotter opens a window you can rotate.
"""
import argparse
from pathlib import Path

import fluidcast
import pyvista as pv

HERE = Path(__file__).resolve().parent

p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
p.add_argument("data", nargs="?", default=HERE / "data" / "sample_column.vtu")
p.add_argument("-o", "--out", type=Path, help="write a screenshot instead of opening a window")
a = p.parse_args()

particles = fluidcast.read(a.data)                      # fluidcast's checked reader
plotter = pv.Plotter(off_screen=a.out is not None, window_size=[640, 480])
plotter.set_background("white")
volume = fluidcast.add_particles(
    plotter, particles, "velocity",                     # a vector: its magnitude
    cmap="inferno", opacity="linear", error_tolerance=0.004,
    scalar_bar_args={"title": "speed", "color": "black"})
plotter.add_mesh(pv.Box(bounds=volume.bounds).outline(), color="black")
floor = pv.Plane(center=(0.14, -0.02, 0.19), direction=(0, 1, 0), i_size=0.6, j_size=0.8)
plotter.add_mesh(floor, color="tan")
plotter.view_xy()                                       # the column stands along +y
plotter.camera.azimuth, plotter.camera.elevation = 35, 25
mapper = volume.mapper                                  # vtkFluidCastVolumeMapper
if a.out:
    plotter.screenshot(a.out)
    print(f"{a.out}: {mapper.GetLastParticleCount()} particles, "
          f"{mapper.GetLastRenderMilliseconds():.0f} ms on {mapper.GetLastDevice()}")
else:
    plotter.show()
