"""How fast the fluidcast representation answers in ParaView: still renders and interactive
renders (what ParaView does while the camera moves) of one data set while the camera orbits.

    tests/vtk/with_xvfb.sh env LD_PRELOAD=$PWD/build/lib/libfluidcast_expat_fix.so \\
        PYTHONPATH=build/python pvbatch examples/pvbatch_interactive.py \\
        build/lib/paraview-plugins/fluidcast/fluidcast.so DATA.vtu \\
        [--array velocity] [--size 1024x768] [--frames 6] [--auto 1|0] [--max-distance 8]
        [--cli [--cli-out DIR]]

Prints a table of milliseconds per frame (wall clock around the view's render call) and the
mapper's image sample distance. With --cli it then renders the last view once more and times
`fluidcast render` (the CLI the build made) on the same image: the view's camera, transfer
function, opacity unit distance and tolerance, and prints the ratio and the largest pixel
difference. A benchmark, not a test: run it on a quiet machine.
"""
import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

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
p.add_argument("--max-distance", type=int, default=8,
               help="FluidCastMaximumImageSampleDistance: the coarsest interactive render")
p.add_argument("--cli", action="store_true", help="also time the CLI on the last still image")
p.add_argument("--cli-out", type=Path,
               help="with --cli: keep both images, the camera and the transfer function here")
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
display.FluidCastMaximumImageSampleDistance = a.max_distance
view.ResetCamera()
cam = GetActiveCamera()
cam.Elevation(20)
Render(view)
volumes = view.GetClientSideObject().GetRenderer().GetVolumes()
volumes.InitTraversal()
# The view holds ParaView's other volumes too: find fluidcast's.
candidates = [volumes.GetNextVolume() for _ in range(volumes.GetNumberOfItems())]
volume = next(v for v in candidates if v.GetMapper().IsA("vtkFluidCastVolumeMapper"))
mapper = volume.GetMapper()


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


def cli_comparison(out: Path):
    """Still-renders the current view, then times `fluidcast render` of the same image."""
    import vtk
    from fluidcast.camera import save_camera
    from fluidcast.cli import fluidcast_binary, run_fluidcast
    from fluidcast.images import difference, read_png
    from fluidcast.transfer import tf_to_preset

    view.OrientationAxesVisibility = 0
    if hasattr(view, "UseColorPaletteForBackground"):
        view.UseColorPaletteForBackground = 0  # ParaView >= 5.10 takes the palette's otherwise
    view.Background = [1, 1, 1]
    still, _ = timed(view.StillRender)
    shot = vtk.vtkWindowToImageFilter()
    shot.SetInput(view.GetRenderWindow())
    shot.ReadFrontBufferOff()
    writer = vtk.vtkPNGWriter()
    writer.SetInputConnection(shot.GetOutputPort())
    writer.SetFileName(str(out / "paraview.png"))
    writer.Write()
    prop = volume.GetProperty()
    ctf, otf = prop.GetRGBTransferFunction(0), prop.GetScalarOpacity(0)
    (out / "tf.json").write_text(json.dumps([tf_to_preset(ctf, otf)]))
    lo, hi = ctf.GetRange()
    tol = mapper.GetErrorTolerance()
    binary = fluidcast_binary(Path(__file__).resolve().parents[1])
    t = time.perf_counter()
    run_fluidcast("render", a.data, "--array", f"{a.array}:mag", "--tf", out / "tf.json",
                  "--range", f"{lo!r},{hi!r}", "--camera", save_camera(cam, out / "camera.json"),
                  "--size", f"{W}x{H}", "--background", "1,1,1",
                  "--opacity-unit-distance", repr(prop.GetScalarOpacityUnitDistance()),
                  "--error-tolerance", "off" if tol == 0 else repr(tol),
                  "--backend", "cpu", "-o", out / "cli.png", binary=binary)
    cli = 1e3 * (time.perf_counter() - t)
    diff = difference(read_png(out / "paraview.png"), read_png(out / "cli.png"))
    print(f"same image: pvbatch still {still:.0f} ms, `fluidcast render` {cli:.0f} ms "
          f"(process wall time, file read included), still / CLI {still / cli:.2f}; "
          f"max pixel difference {round(255 * diff['max_abs'])}/255 ({binary})")


if a.cli and a.cli_out:
    a.cli_out.mkdir(parents=True, exist_ok=True)
    cli_comparison(a.cli_out)
elif a.cli:
    with tempfile.TemporaryDirectory() as d:
        cli_comparison(Path(d))
