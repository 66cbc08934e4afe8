"""Run by the ParaView GUI (`paraview --script=... --exit`): load the plugin, show a particle
file with the "fluidcast" representation in the GUI's own view, save a screenshot, and check
that the particles were drawn. Arguments come from the environment: FLUIDCAST_PLUGIN,
FLUIDCAST_DATA, FLUIDCAST_OUT. Writes FLUIDCAST_OUT/result.txt ("pass ..." or "fail ...")
and exits the GUI with 0 or 1; the ctest checks the file, so a script that never ran fails."""
import os
import sys

from paraview.simple import (
    ColorBy,
    GetActiveView,
    GetOpacityTransferFunction,
    LoadPlugin,
    OpenDataFile,
    Render,
    SaveScreenshot,
    Show,
)
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkIOImage import vtkPNGReader

status = 1
try:
    LoadPlugin(os.environ["FLUIDCAST_PLUGIN"], remote=False, ns=globals())
    display = Show(OpenDataFile(os.environ["FLUIDCAST_DATA"]))
    display.SetRepresentationType("fluidcast")
    ColorBy(display, ("POINTS", "velocity", "Magnitude"))
    display.ScalarOpacityFunction = GetOpacityTransferFunction("velocity")
    view = GetActiveView()
    view.OrientationAxesVisibility = 0
    view.ResetCamera()
    Render()
    shot = os.path.join(os.environ["FLUIDCAST_OUT"], "gui.png")
    SaveScreenshot(shot, view, ImageResolution=[400, 300])
    r = vtkPNGReader()
    r.SetFileName(shot)
    r.Update()
    px = vtk_to_numpy(r.GetOutput().GetPointData().GetScalars())[:, :3].astype(int)
    background = px[0]
    drawn = int((abs(px - background).max(axis=1) > 8).sum())
    message = f"representation {display.Representation}, {drawn} of {len(px)} pixels drawn"
    status = 0 if display.Representation == "fluidcast" and drawn > len(px) // 20 else 1
except Exception as e:  # report, then fail
    message = f"error: {e}"
with open(os.path.join(os.environ["FLUIDCAST_OUT"], "result.txt"), "w") as f:
    f.write(("pass " if status == 0 else "fail ") + message + "\n")
sys.stdout.flush()
os._exit(status)
