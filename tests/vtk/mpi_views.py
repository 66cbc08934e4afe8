"""The views the MPI tests render (pvbatch_mpi_render.py under pvbatch, pvserver_mpi.py as a
client): a particle file with the "fluidcast" representation, four camera directions, one
screenshot each. Imported by those scripts (they put this folder on sys.path), and by the
other pvbatch scripts for the bare white view they all compare screenshots in, the PNG
reader and the camera file they share."""
import json
import os

from paraview.simple import (
    ColorBy,
    CreateView,
    Delete,
    GetActiveCamera,
    GetColorTransferFunction,
    GetOpacityTransferFunction,
    OpenDataFile,
    Render,
    SaveScreenshot,
    Show,
)
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkIOImage import vtkPNGReader

W, H = 320, 240
# (name, azimuth, elevation) from ParaView's default view down -z: the pieces are slabs along
# x, and the ranks' boxes split the longest axis, so every view has rays that cross a box face
# inside the fluid ("x" looks straight along the slab axis).
VIEWS = [("front", 0, 0), ("x", 90, 0), ("top", 0, 89), ("oblique", 35, 25)]


def white_view(width, height):
    """A render view of `width` x `height` pixels on a plain white background, without the
    orientation axes: what the tests' screenshots are compared in."""
    view = CreateView("RenderView")
    view.ViewSize = [width, height]
    view.OrientationAxesVisibility = 0
    if hasattr(view, "UseColorPaletteForBackground"):
        view.UseColorPaletteForBackground = 0
    view.Background = [1.0, 1.0, 1.0]
    return view


def read_png(path):
    """The RGB of a PNG's pixels, as an (n, 3) integer array in VTK's row order."""
    r = vtkPNGReader()
    r.SetFileName(path)
    r.Update()
    return vtk_to_numpy(r.GetOutput().GetPointData().GetScalars())[:, :3].astype(int)


def write_camera(cam, path):
    """`cam` (a vtkCamera or ParaView's camera) as the camera file `fluidcast render --camera`
    reads."""
    with open(path, "w") as f:
        json.dump({"position": list(cam.GetPosition()), "focal_point": list(cam.GetFocalPoint()),
                   "view_up": list(cam.GetViewUp()), "view_angle": cam.GetViewAngle(),
                   "parallel_projection": bool(cam.GetParallelProjection()),
                   "parallel_scale": cam.GetParallelScale()}, f)


def render_views(data, array, out, tolerance, radius=(), remote_render_threshold=None):
    """Saves OUT/<view>.png for each of VIEWS; returns the representation's information
    properties (rank 0's owned and halo particles, its box, the last error)."""
    reader = OpenDataFile(data)
    view = white_view(W, H)
    # ParaView applies FXAA to the composited image on several ranks but not to a volume on
    # one: the comparison is of the renderings, so none.
    view.UseFXAA = 0
    if remote_render_threshold is not None:
        view.RemoteRenderThreshold = remote_render_threshold
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
    info = {"owned": display.GetPropertyValue("FluidCastOwnedParticles"),
            "halo": display.GetPropertyValue("FluidCastHaloParticles"),
            "region": list(display.GetPropertyValue("FluidCastRegion")),
            "last_error": display.GetPropertyValue("FluidCastLastError")}
    # Deleting the view before exit spares Debian's pvbatch a GLXBadContext at teardown.
    Delete(display)
    Delete(view)
    Delete(reader)
    return info
