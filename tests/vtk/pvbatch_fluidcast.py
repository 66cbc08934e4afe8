"""pvbatch test: load the fluidcast plugin, show a particle file with the "fluidcast"
representation, save a screenshot and compare it with `fluidcast render` for the same camera,
colour map and opacity function.

    pvbatch pvbatch_fluidcast.py PLUGIN.so DATA.vtu ARRAY OUTDIR FLUIDCAST_CLI TOLERANCE [BACKEND]
            [--properties] [--iso] [--memory-limit]

TOLERANCE is the representation's error tolerance (a number; 0 = full rate). The images must
agree within 2/255 per channel at full rate, 2 E_I + 1/255 when adaptive (as the VTK window
test). BACKEND (Auto, CPU or GPU; default Auto) sets FluidCastBackend; with GPU the view is
also rendered with CPU and the two screenshots must agree within 2/255. --properties then
sets FluidCastSupportRadius, FluidCastKernel and a vector component (ColorBy ... "Z") away
from their defaults: each screenshot must agree with the CLI render that uses the same
option, and that CLI render must differ from the default screenshot by more than the
agreement allows (so a property the representation ignored would fail). --memory-limit sets
FluidCastMemoryLimit just above what the image and tiling take, so that the view renders in
screen tiles: the screenshot must equal the default one exactly; a 1 MiB limit must draw
nothing (an error), and 0 draws the view again. --iso shows the
free surface instead (FluidCastIsosurfaceValues 0.5 of the colour field, shaded, with
FluidCastSpecularPower away from its default), compared with `fluidcast render --iso 0.5
--specular-power 20`; the volume-only CLI render must differ from it. Exit code 0 pass,
1 fail, 77 skipped (data not present).
"""
import json
import math
import os
import subprocess
import sys

from mpi_views import read_png, white_view, write_camera  # tests/vtk, the script's folder
from paraview.simple import (
    ColorBy,
    GetActiveCamera,
    GetColorTransferFunction,
    GetOpacityTransferFunction,
    LoadPlugin,
    OpenDataFile,
    Render,
    SaveScreenshot,
    Show,
)
from pvbatch_mpi import missing_data

flags = ("--properties", "--iso", "--memory-limit")
args = [a for a in sys.argv[1:] if a not in flags]
properties = "--properties" in sys.argv
memory_limit = "--memory-limit" in sys.argv
iso = "--iso" in sys.argv
# The CLI options that match the representation's iso-surface properties below.
iso_extra = ("--iso", "0.5", "--specular-power", "20") if iso else ()
plugin, data, array, out, cli, tolerance = args[:6]
backend = args[6] if len(args) > 6 else "Auto"
tolerance = float(tolerance)
if (missing := missing_data(data)) is not None:
    sys.exit(missing)
W, H = 320, 240

LoadPlugin(plugin, remote=False, ns=globals())
reader = OpenDataFile(data)
view = white_view(W, H)

display = Show(reader, view)
display.SetRepresentationType("fluidcast")
assert display.Representation == "fluidcast", display.Representation
ColorBy(display, ("POINTS", array, "Magnitude"))
lut = GetColorTransferFunction(array)
pwf = GetOpacityTransferFunction(array)
lut.ColorSpace = "RGB"  # fluidcast interpolates colour maps in RGB
lut.Discretize = 0
lut.RGBPoints = [0.0, 0.267, 0.005, 0.329, 0.25, 0.229, 0.322, 0.546, 0.5, 0.128, 0.567, 0.551,
                 0.75, 0.369, 0.789, 0.383, 1.0, 0.993, 0.906, 0.144]
pwf.Points = [0.0, 0.05, 0.5, 0.0, 0.5, 0.3, 0.5, 0.0, 1.0, 0.8, 0.5, 0.0]
lo, hi = reader.PointData[array].GetRange(-1)
lut.RescaleTransferFunction(lo, hi)
pwf.RescaleTransferFunction(lo, hi)
display.ScalarOpacityFunction = pwf
display.ScalarOpacityUnitDistance = 0.1
display.FluidCastErrorTolerance = tolerance
display.FluidCastBackend = backend
# No radius set: the file's support_radius field data (or the spacing-based suggestion).
if iso:
    display.FluidCastIsosurfaceValues = [0.5]
    display.FluidCastSpecularPower = 20

view.ResetCamera()
cam = GetActiveCamera()
cam.Azimuth(30)
cam.Elevation(20)
cam.OrthogonalizeViewUp()
view.ResetCamera()


def screenshot(name=""):
    """Renders the view and saves it as OUTDIR/paraview[_NAME].png; returns the path."""
    Render(view)
    path = os.path.join(out, f"paraview_{name}.png" if name else "paraview.png")
    SaveScreenshot(path, view, ImageResolution=[W, H], TransparentBackground=0)
    return path


shot = screenshot()

write_camera(cam, os.path.join(out, "camera.json"))


def cli_render(png, component="mag", extra=(), surfaces=True):
    """`fluidcast render` of the view (camera, colour map, range of the shown component), with
    the iso-surfaces of --iso unless `surfaces` is false."""
    with open(os.path.join(out, "tf.json"), "w") as f:
        json.dump([{"Name": "from ParaView", "ColorSpace": "RGB",
                    "RGBPoints": list(lut.RGBPoints), "Points": list(pwf.Points)}], f)
    cmd = [cli, "render", data, "--array", f"{array}:{component}", "--tf",
           os.path.join(out, "tf.json"), "--range", f"{lut.RGBPoints[0]!r},{lut.RGBPoints[-4]!r}",
           "--camera", os.path.join(out, "camera.json"), "--size", f"{W}x{H}",
           "--opacity-unit-distance", "0.1", "--background", "1,1,1",
           "--error-tolerance", "off" if tolerance <= 0 else str(tolerance), "--backend", "cpu",
           *(iso_extra if surfaces else ()), *extra, "-o", png]
    print(" ".join(cmd))
    subprocess.run(cmd, check=True)


cli_png = os.path.join(out, "cli.png")
cli_render(cli_png)


a, b = read_png(shot), read_png(cli_png)
if a.shape != b.shape:
    print(f"FAIL: sizes differ {a.shape} vs {b.shape}")
    sys.exit(1)
d = abs(a - b)
drawn = int((a != 255).any(axis=1).sum())
allowed = math.ceil(2 * tolerance * 255) + 1 if tolerance > 0 else 2
print(f"ParaView vs CLI: max abs {d.max()}/255, mean {d.mean():.4f}/255, "
      f"{int((d > 2).sum())} channels above 2/255; {drawn} pixels drawn; allowed {allowed}/255")
status = 0 if d.max() <= allowed else 1
if backend == "GPU":
    display.FluidCastBackend = "CPU"
    g = abs(read_png(screenshot("cpu")) - a)
    print(f"FluidCastBackend GPU vs CPU: max abs {g.max()}/255, mean {g.mean():.5f}/255")
    status = status or (0 if g.max() <= 2 else 1)
    # The properties reach the mapper: a GPU adapter nobody has draws nothing (an error).
    display.FluidCastBackend = "GPU"
    display.FluidCastAdapter = "no-such-gpu"
    drawn_none = int((read_png(screenshot("no_adapter")) != 255).any(axis=1).sum())
    print(f"FluidCastAdapter 'no-such-gpu': {drawn_none} pixels drawn (expected none)")
    status = status or (0 if drawn_none == 0 else 1)
if iso:
    volume_png = os.path.join(out, "cli_volume.png")
    cli_render(volume_png, surfaces=False)
    moved = int(abs(a - read_png(volume_png)).max())
    print(f"iso-surface screenshot vs the CLI's volume: max {moved}/255 (must exceed {allowed})")
    if moved <= allowed:
        print("FAIL: the representation drew no surface")
        status = 1
if drawn < W * H // 20:
    print("FAIL: the representation drew almost nothing")
    status = 1


def property_follows_cli(name, component="mag", extra=()):
    """The screenshot agrees with the CLI under the same option; the default does not."""
    shot_p = read_png(screenshot(name))
    cli_p = os.path.join(out, f"cli_{name}.png")
    cli_render(cli_p, component, extra)
    theirs = read_png(cli_p)
    agree, moved = int(abs(shot_p - theirs).max()), int(abs(a - theirs).max())
    print(f"{name}: ParaView vs CLI max {agree}/255 (allowed {allowed}); "
          f"default screenshot vs this CLI max {moved}/255")
    ok = agree <= allowed and moved > allowed
    if not ok:
        print(f"FAIL: {name}: the representation does not follow the CLI's option")
    return ok


if memory_limit:
    # The image planes (2 x 32 bytes a pixel), 9 bytes a particle and 2 MiB of tiles: the
    # tiles hold about 16,000 particles each (128 bytes a particle).
    n = reader.GetDataInformation().GetNumberOfPoints()
    mib = (W * H * 64 + 9 * n + (2 << 20)) / 2**20
    display.FluidCastMemoryLimit = mib
    tiled = abs(read_png(screenshot("memory_limit")) - a).max()
    print(f"FluidCastMemoryLimit {mib:.2f} MiB ({n} particles): vs no limit max {tiled}/255")
    display.FluidCastMemoryLimit = 1.0
    drawn_none = int((read_png(screenshot("memory_limit_1")) != 255).any(axis=1).sum())
    print(f"FluidCastMemoryLimit 1 MiB: {drawn_none} pixels drawn (expected none)")
    display.FluidCastMemoryLimit = 0.0
    again = abs(read_png(screenshot("memory_limit_0")) - a).max()
    ok = tiled == 0 and drawn_none == 0 and again == 0
    if not ok:
        print("FAIL: FluidCastMemoryLimit changed the image or was not applied")
    status = status or (0 if ok else 1)
if properties:
    # Each property alone, then back to its default.
    h = float(display.GetProperty("FluidCastSupportRadius").GetData() or 0.0)
    display.FluidCastSupportRadius = 0.064
    status = status or (0 if property_follows_cli("support_radius", extra=(
        "--support-radius", "0.064")) else 1)
    display.FluidCastSupportRadius = h
    display.FluidCastKernel = "Gaussian"
    status = status or (0 if property_follows_cli("kernel", extra=("--kernel", "gaussian"))
                        else 1)
    display.FluidCastKernel = "Cubic spline"
    # Particle level of detail: the same cut of the view as the CLI's --lod.
    display.FluidCastLODTolerance = 12.0
    status = status or (0 if property_follows_cli("lod", extra=("--lod", "12")) else 1)
    display.FluidCastLODTolerance = 0.0
    # The RBF field: still renders of the view accumulate passes up to Progressive Passes,
    # which then equal the CLI's --spp (the same passes), with and without shadows.
    display.FluidCastField = "RBF"
    display.FluidCastProgressivePasses = 8
    for _ in range(8):
        Render(view)
    status = status or (0 if property_follows_cli("rbf", extra=(
        "--field", "rbf", "--spp", "8")) else 1)
    display.FluidCastRBFRadiusMap = [0.0, 1.0, 1.0, 0.5]
    for _ in range(8):
        Render(view)
    status = status or (0 if property_follows_cli("rbf_radius_map", extra=(
        "--field", "rbf", "--spp", "8", "--radius-map", "0,1,1,0.5")) else 1)
    display.FluidCastRBFRadiusMap = []
    display.FluidCastShadows = 1
    display.FluidCastLightDirection = [0.0, 1.0, 0.0]
    for _ in range(8):
        Render(view)
    status = status or (0 if property_follows_cli("rbf_shadows", extra=(
        "--field", "rbf", "--spp", "8", "--shadows", "--light", "0,1,0")) else 1)
    display.FluidCastShadows = 0
    display.FluidCastField = "CSPH"
    display.FluidCastProgressivePasses = 1
    ColorBy(display, ("POINTS", array, "Z"))
    zlo, zhi = reader.PointData[array].GetRange(2)
    lut.RescaleTransferFunction(zlo, zhi)
    pwf.RescaleTransferFunction(zlo, zhi)
    status = status or (0 if property_follows_cli("vector_component", component="2") else 1)
# Leave without ParaView's teardown: under Xvfb, Debian's pvbatch dies with "GLXBadContext"
# while destroying its window at exit, which would turn a pass into a failure.
sys.stdout.flush()
os._exit(status)
