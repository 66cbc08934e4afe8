"""How fast the fluidcast representation answers in ParaView: still renders and interactive
renders (what ParaView does while the camera moves) of one data set while the camera orbits.

    tests/vtk/with_xvfb.sh env LD_PRELOAD=$PWD/build/lib/libfluidcast_expat_fix.so \\
        PYTHONPATH=build/python pvbatch examples/pvbatch_interactive.py \\
        build/lib/paraview-plugins/fluidcast/fluidcast.so DATA.vtu \\
        [--array velocity] [--size 1024x768] [--frames 6] [--auto 1|0]

Prints a table of milliseconds per frame (wall clock around the view's render call) and the
mapper's image sample distance. A benchmark, not a test: run it on a quiet machine.
"""
import argparse
import statistics
import time

from fluidcast import vtkFluidCastVolumeMapper  # noqa: F401 (its Python wrapping)
from paraview.simple import (
    ColorBy,
    CreateView,
    GetActiveCamera,
    GetOpacityTransferFunction,
    LoadPlugin,
    OpenDataFile,
    Render,
    Show,
)

p = argparse.ArgumentParser()
p.add_argument("plugin")
p.add_argument("data")
p.add_argument("--array", default="velocity")
p.add_argument("--size", default="1024x768")
p.add_argument("--frames", type=int, default=6)
p.add_argument("--auto", type=int, default=1, help="FluidCastAutoAdjustSampleDistances")
a = p.parse_args()
W, H = (int(v) for v in a.size.split("x"))

LoadPlugin(a.plugin, remote=False, ns=globals())
reader = OpenDataFile(a.data)
view = CreateView("RenderView")
view.ViewSize = [W, H]
display = Show(reader, view)
display.SetRepresentationType("fluidcast")
ColorBy(display, ("POINTS", a.array, "Magnitude"))
display.RescaleTransferFunctionToDataRange(True, False)
display.ScalarOpacityFunction = GetOpacityTransferFunction(a.array)
display.FluidCastAutoAdjustSampleDistances = a.auto
view.ResetCamera()
cam = GetActiveCamera()
cam.Elevation(20)
Render(view)
volumes = view.GetClientSideObject().GetRenderer().GetVolumes()
volumes.InitTraversal()
mapper = volumes.GetNextVolume().GetMapper()


def timed(render):
    t = time.perf_counter()
    render()
    return 1e3 * (time.perf_counter() - t), mapper.GetLastImageSampleDistance()


first = (mapper.GetLastRenderMilliseconds(), 1)
rows = []
for _ in range(a.frames):
    cam.Azimuth(360 / a.frames)
    view.StillRender()  # the data is ready; what follows times the renders alone
    cam.Azimuth(1)
    rows.append((timed(view.StillRender), timed(view.InteractiveRender)))
print(f"{a.data}: {mapper.GetLastParticleCount()} particles, {W}x{H}, "
      f"auto adjust {a.auto}, device {mapper.GetLastDevice()}")
print(f"first render (mapper alone): {first[0]:.0f} ms")
print("frame  still ms  interactive ms  sample distance")
for i, (still, inter) in enumerate(rows):
    print(f"{i:5d}  {still[0]:8.0f}  {inter[0]:14.0f}  {inter[1]:15d}")
s = statistics.median(r[0][0] for r in rows)
t = statistics.median(r[1][0] for r in rows)
print(f"median: still {s:.0f} ms, interactive {t:.0f} ms, ratio {s / t:.1f}x")
