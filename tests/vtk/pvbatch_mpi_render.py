"""pvbatch script run by pvbatch_mpi.py on 1, 2 and 3 MPI ranks: shows a multi-piece .pvtu
with the "fluidcast" representation and saves one screenshot per view.

    mpiexec -n N pvbatch --mpi pvbatch_mpi_render.py PLUGIN DATA.pvtu ARRAY OUTDIR TOLERANCE
            [RADIUS_ARRAY SCALE]

Writes OUTDIR/<view>.png for each view of VIEWS and OUTDIR/info.json (ranks, and rank 0's
owned and halo particle counts and box). Runs on rank 0 (pvbatch's other ranks serve).
"""
import json
import os
import sys

from paraview.simple import (
    ColorBy,
    CreateView,
    Delete,
    GetActiveCamera,
    GetColorTransferFunction,
    GetOpacityTransferFunction,
    LoadPlugin,
    OpenDataFile,
    Render,
    SaveScreenshot,
    Show,
)

from paraview import servermanager

plugin, data, array, out, tolerance = sys.argv[1:6]
radius = sys.argv[6:8]  # optional: FluidCastRadiusArray and FluidCastRadiusScale
W, H = 320, 240
# (name, azimuth, elevation) from ParaView's default view down -z: the pieces are slabs along
# x, and the ranks' boxes split the longest axis, so every view has rays that cross a box face
# inside the fluid ("x" looks straight along the slab axis).
VIEWS = [("front", 0, 0), ("x", 90, 0), ("top", 0, 89), ("oblique", 35, 25)]

LoadPlugin(plugin, remote=False, ns=globals())
reader = OpenDataFile(data)
view = CreateView("RenderView")
view.ViewSize = [W, H]
view.OrientationAxesVisibility = 0
# ParaView applies FXAA to the composited image on several ranks but not to a volume on one:
# the comparison is of the renderings, so none.
view.UseFXAA = 0
if hasattr(view, "UseColorPaletteForBackground"):
    view.UseColorPaletteForBackground = 0
view.Background = [1.0, 1.0, 1.0]
display = Show(reader, view)
display.SetRepresentationType("fluidcast")
ColorBy(display, ("POINTS", array, "Magnitude"))
lut = GetColorTransferFunction(array)
pwf = GetOpacityTransferFunction(array)
lut.ApplyPreset("Viridis (matplotlib)", True)
pwf.Points = [0.0, 0.05, 0.5, 0.0, 0.5, 0.3, 0.5, 0.0, 1.0, 0.8, 0.5, 0.0]
lo, hi = reader.PointData[array].GetRange(-1)
lut.RescaleTransferFunction(lo, hi)
pwf.RescaleTransferFunction(lo, hi)
display.ScalarOpacityFunction = pwf
display.ScalarOpacityUnitDistance = 0.1
display.FluidCastErrorTolerance = float(tolerance)
display.FluidCastBackend = "CPU"
if radius:
    display.FluidCastRadiusArray = radius[0]
    display.FluidCastRadiusScale = float(radius[1])
display.FluidCastAutoAdjustSampleDistances = 0

os.makedirs(out, exist_ok=True)
for name, azimuth, elevation in VIEWS:
    view.CameraPosition = [0, 0, 1]
    view.CameraFocalPoint = [0, 0, 0]
    view.CameraViewUp = [0, 1, 0]
    view.ResetCamera()
    cam = GetActiveCamera()
    cam.Azimuth(azimuth)
    cam.Elevation(elevation)
    cam.OrthogonalizeViewUp()
    view.ResetCamera()
    Render(view)
    SaveScreenshot(os.path.join(out, f"{name}.png"), view, ImageResolution=[W, H],
                   TransparentBackground=0)

display.UpdatePropertyInformation()
ranks = servermanager.vtkProcessModule.GetProcessModule().GetNumberOfLocalPartitions()
info = {"ranks": ranks, "owned": display.GetPropertyValue("FluidCastOwnedParticles"),
        "halo": display.GetPropertyValue("FluidCastHaloParticles"),
        "region": list(display.GetPropertyValue("FluidCastRegion")),
        "last_error": display.GetPropertyValue("FluidCastLastError")}
with open(os.path.join(out, "info.json"), "w") as f:
    json.dump(info, f)
print(json.dumps(info))
sys.stdout.flush()
Delete(display)
Delete(view)
del display, view

