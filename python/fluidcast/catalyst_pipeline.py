"""The Catalyst pipeline that fluidcast.insitu runs (a Catalyst 2 style script, loaded by
`paraview.catalyst.bridge.add_pipeline(..., 2)`): the adaptor's particles (the producer
named `input`) shown with the fluidcast representation, coloured by the configured array
with the CLI's transfer function (its default: Viridis, opacity ramp 0 to 1) and opacity
unit distance (the support bounds' diagonal over the cube root of the particle count, over
all ranks), over a range fixed for the run, one PNG per step. Its settings come from the
JSON file named by $FLUIDCAST_INSITU_CONFIG.
"""
import json
import math
import os

from paraview.simple import (
    ColorBy,
    CreateView,
    GetActiveCamera,
    GetColorTransferFunction,
    GetOpacityTransferFunction,
    LoadPlugin,
    SaveScreenshot,
    SetActiveView,
    Show,
    TrivialProducer,
)

from paraview import catalyst

with open(os.environ["FLUIDCAST_INSITU_CONFIG"]) as _f:
    CONFIG = json.load(_f)
LoadPlugin(CONFIG["plugin"], remote=False, ns=globals())

producer = TrivialProducer(registrationName="input")
W, H = CONFIG["size"]
view = CreateView("RenderView")
view.ViewSize = [W, H]
view.OrientationAxesVisibility = 0
if hasattr(view, "UseColorPaletteForBackground"):
    view.UseColorPaletteForBackground = 0
view.Background = CONFIG["background"]
# Several ranks composite with FXAA, one does not: none, so that ranks compare.
view.UseFXAA = 0
SetActiveView(view)
display = Show(producer, view)
display.SetRepresentationType("fluidcast")
ARRAY = CONFIG["array"]
options = catalyst.Options()
state = {"range": CONFIG["range"], "camera": False}


def _reduce(values, op):
    """`values` (floats) reduced over all ranks with `op` ("min", "max" or "sum")."""
    from vtkmodules.vtkCommonCore import vtkDoubleArray
    from vtkmodules.vtkParallelCore import vtkCommunicator, vtkMultiProcessController

    c = vtkMultiProcessController.GetGlobalController()
    if c is None or c.GetNumberOfProcesses() < 2:
        return list(values)
    send, recv = vtkDoubleArray(), vtkDoubleArray()
    for v in values:
        send.InsertNextValue(v)
    codes = {"min": vtkCommunicator.MIN_OP, "max": vtkCommunicator.MAX_OP,
             "sum": vtkCommunicator.SUM_OP}
    c.AllReduce(send, recv, codes[op])
    return [recv.GetValue(k) for k in range(len(values))]


def _summary(grid):
    """Over all ranks: the particles' count, support bounds (points +- the support radius)
    and the array's magnitude range. A rank with no particles adds nothing."""
    inf = float("inf")
    n = grid.GetNumberOfPoints()
    h = grid.GetFieldData().GetArray("support_radius")
    radius = h.GetValue(0) if h is not None and h.GetNumberOfTuples() else 0.0
    lo, hi, rng = [inf] * 3, [-inf] * 3, [inf, -inf]
    if n:
        b = grid.GetBounds()
        lo = [b[2 * k] - radius for k in range(3)]
        hi = [b[2 * k + 1] + radius for k in range(3)]
        a = grid.GetPointData().GetArray(ARRAY)
        if a is not None:
            rng = list(a.GetRange(-1))
    total = _reduce([n], "sum")[0]
    lo = _reduce(lo + [rng[0]], "min")
    hi = _reduce(hi + [rng[1]], "max")
    return total, lo[:3], hi[:3], (lo[3], hi[3])


def _tables(lo, hi):
    """The CLI's transfer function (CONFIG["tf"]: a built-in preset or a ParaView preset file)
    over lo..hi as ParaView's RGBPoints and opacity Points: sampled at 257 points, which
    hold every control point of the built-in 33-point tables, so the piecewise-linear maps
    are the CLI's own."""
    from fluidcast._core import preset_table

    rgb, alpha = preset_table(CONFIG["tf"], 257)
    xs = [lo + (hi - lo) * k / 256 for k in range(257)]
    colours = [v for x, c in zip(xs, rgb) for v in (x, *map(float, c))]
    opacity = [v for x, a in zip(xs, alpha) for v in (x, float(a), 0.5, 0.0)]
    return colours, opacity


def _unit_distance(n, lo, hi):
    """The CLI's default opacity unit distance: support bounds' diagonal / cbrt(particles)."""
    diag = math.sqrt(sum((hi[k] - lo[k]) ** 2 for k in range(3)))
    return diag / max(n, 1) ** (1.0 / 3.0)


def _rank():
    from vtkmodules.vtkParallelCore import vtkMultiProcessController

    c = vtkMultiProcessController.GetGlobalController()
    return c.GetLocalProcessId() if c is not None else 0


def _first_step():
    """Fixes the camera and the range for the run and writes them (rank 0) for post-hoc
    renders."""
    out = CONFIG["outdir"]
    cam = GetActiveCamera()
    if CONFIG["camera"]:
        with open(CONFIG["camera"]) as f:
            c = json.load(f)
        cam.SetPosition(c["position"])
        cam.SetFocalPoint(c["focal_point"])
        cam.SetViewUp(c["view_up"])
        cam.SetViewAngle(c.get("view_angle", 30.0))
    else:
        view.ResetCamera(False)
    state["camera"] = True
    if _rank() != 0:
        return
    with open(os.path.join(out, "camera.json"), "w") as f:
        json.dump({"position": list(cam.GetPosition()), "focal_point": list(cam.GetFocalPoint()),
                   "view_up": list(cam.GetViewUp()), "view_angle": cam.GetViewAngle(),
                   "parallel_projection": bool(cam.GetParallelProjection()),
                   "parallel_scale": cam.GetParallelScale()}, f)
    with open(os.path.join(out, "range.txt"), "w") as f:
        f.write("{!r},{!r}\n".format(*state["range"]))


def catalyst_execute(info):
    producer.UpdatePipeline(info.time)
    grid = producer.GetClientSideObject().GetOutputDataObject(0)
    n, lo, hi, rng = _summary(grid)
    if n == 0:
        raise RuntimeError("fluidcast in situ: no rank passed any particle")
    if not rng[0] <= rng[1]:
        raise RuntimeError(f"fluidcast in situ: the particles have no point array '{ARRAY}'")
    if state["range"] is None:
        state["range"] = [rng[0], rng[1]] if rng[0] < rng[1] else [rng[0] - 0.5, rng[0] + 0.5]
    ColorBy(display, ("POINTS", ARRAY, "Magnitude"))
    lut = GetColorTransferFunction(ARRAY)
    pwf = GetOpacityTransferFunction(ARRAY)
    lut.AutomaticRescaleRangeMode = "Never"
    lut.ColorSpace = "RGB"
    lut.Discretize = 0
    lut.RGBPoints, pwf.Points = _tables(*state["range"])
    display.ScalarOpacityFunction = pwf
    display.ScalarOpacityUnitDistance = _unit_distance(n, lo, hi)
    # paraview.simple.Render resets the camera on its first call: the view renders itself.
    view.Update()
    if not state["camera"]:
        _first_step()
    view.StillRender()
    path = os.path.join(CONFIG["outdir"], f"insitu_{info.timestep:04d}.png")
    SaveScreenshot(path, view, ImageResolution=[W, H], TransparentBackground=0)
