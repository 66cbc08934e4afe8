"""Parity of the front-ends: for each option of the render plan, the CLI, the VTK mapper in a
VTK window and ParaView's representation draw the same image of one shared frame.

    PYTHONPATH=BUILD/python pvbatch pvbatch_parity.py PLUGIN.so DATA.vtu ARRAY OUTDIR CLI

The frame: DATA's ARRAY (magnitude) at 200x150 on white, a fixed colour map and opacity
function, error tolerance 0.1 (coarse enough that the plan's switches show), without the
probe (with it, a frame whose supports are this few pixels wide is rendered at full rate,
where no plan switch shows). Per option (mode, field, tolerance, probe, relaxation, strict
bound, bundle, depth samples, sampling scale, backend, level of detail, tiles, iso-surfaces,
RBF post and pre, noise, seed, step, shadows, shadow samples, samples per pixel; RBF,
shadows and iso-surfaces on the GPU) the three images must agree within 2/255 per channel,
and the option must move the image by more than that from the image it is compared against
(the base frame; for RBF pre and shadows the RBF post image; for spp the shadows'), so that
a front-end that drops the option fails. Options that keep the image by design check what
they must change instead: the GPU backend the device the frame rendered on (and, with the
RBF field, shadows or iso-surfaces, the image of the same option on the CPU within 2/255),
tiles the tile count (the representation reports them as FluidCastLastDevice,
FluidCastLastTiles).
Exit code 0 pass, 1 fail, 77 skipped (data not present).
"""
import json
import os
import subprocess
import sys

from fluidcast import vtkFluidCastVolumeMapper
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
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonDataModel import vtkPiecewiseFunction
from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
from vtkmodules.vtkRenderingCore import (
    vtkColorTransferFunction,
    vtkRenderer,
    vtkRenderWindow,
    vtkVolume,
    vtkVolumeProperty,
    vtkWindowToImageFilter,
)

plugin, data, array, out, cli = sys.argv[1:6]
# A small scene for the RBF field on a software GPU (lavapipe ends a shader invocation after
# 65,535 loop iterations): the mapper with Backend GPU against `fluidcast render --field rbf
# --backend gpu`.
small = sys.argv[6] if len(sys.argv) > 6 else None
if (missing := missing_data(data)) is not None:
    sys.exit(missing)
W, H = 200, 150
AGREE = 2  # /255 per channel
TOLERANCE = 0.1
# The base frame runs without the probe (`--no-probe`); the CLI option that leaves that out.
PROBE_ON = "(probe on)"
SPECULAR_POWER = 20.0

LoadPlugin(plugin, remote=False, ns=globals())
reader = OpenDataFile(data)
view = white_view(W, H)
display = Show(reader, view)
display.SetRepresentationType("fluidcast")
ColorBy(display, ("POINTS", array, "Magnitude"))
lut = GetColorTransferFunction(array)
pwf = GetOpacityTransferFunction(array)
lut.ColorSpace = "RGB"
lut.Discretize = 0
lut.RGBPoints = [0.0, 0.267, 0.005, 0.329, 0.5, 0.128, 0.567, 0.551, 1.0, 0.993, 0.906, 0.144]
pwf.Points = [0.0, 0.05, 0.5, 0.0, 0.5, 0.3, 0.5, 0.0, 1.0, 0.8, 0.5, 0.0]
lo, hi = reader.PointData[array].GetRange(-1)
lut.RescaleTransferFunction(lo, hi)
pwf.RescaleTransferFunction(lo, hi)
display.ScalarOpacityFunction = pwf
display.ScalarOpacityUnitDistance = 0.1
display.FluidCastErrorTolerance = TOLERANCE
display.FluidCastSpecularPower = SPECULAR_POWER
display.FluidCastBackend = "CPU"
view.ResetCamera()
cam = GetActiveCamera()
cam.Azimuth(30)
cam.Elevation(20)
cam.OrthogonalizeViewUp()
view.ResetCamera()
write_camera(cam, os.path.join(out, "camera.json"))
with open(os.path.join(out, "tf.json"), "w") as f:
    json.dump([{"Name": "parity", "ColorSpace": "RGB", "RGBPoints": list(lut.RGBPoints),
                "Points": list(pwf.Points)}], f)


# --- the VTK window: the wrapped mapper with the same data, camera and transfer function ---
vtk_reader = vtkXMLUnstructuredGridReader()
vtk_reader.SetFileName(data)
mapper = vtkFluidCastVolumeMapper()
mapper.SetInputConnection(vtk_reader.GetOutputPort())
mapper.SelectScalarArray(array)
mapper.SetScalarModeToUsePointFieldData()
mapper.SetVectorMode(0)  # vtkSmartVolumeMapper::MAGNITUDE
mapper.SetAutoAdjustSampleDistances(0)
mapper.SetErrorTolerance(TOLERANCE)
mapper.SetBackend(1)
ctf = vtkColorTransferFunction()
rgb = list(lut.RGBPoints)
for k in range(0, len(rgb), 4):
    ctf.AddRGBPoint(*rgb[k:k + 4])
otf = vtkPiecewiseFunction()
pts = list(pwf.Points)
for k in range(0, len(pts), 4):
    otf.AddPoint(*pts[k:k + 4])
prop = vtkVolumeProperty()
prop.SetColor(ctf)
prop.SetScalarOpacity(otf)
prop.SetScalarOpacityUnitDistance(0.1)
prop.SetInterpolationTypeToLinear()
prop.ShadeOn()
prop.SetAmbient(0.1)
prop.SetDiffuse(0.7)
prop.SetSpecular(0.2)
prop.SetSpecularPower(SPECULAR_POWER)
volume = vtkVolume()
volume.SetMapper(mapper)
volume.SetProperty(prop)
ren = vtkRenderer()
ren.SetBackground(1, 1, 1)
ren.AddVolume(volume)
win = vtkRenderWindow()
win.SetOffScreenRendering(1)
win.SetMultiSamples(0)
win.AddRenderer(ren)
win.SetSize(W, H)
vc = ren.GetActiveCamera()
vc.SetPosition(cam.GetPosition())
vc.SetFocalPoint(cam.GetFocalPoint())
vc.SetViewUp(cam.GetViewUp())
vc.SetViewAngle(cam.GetViewAngle())
ren.ResetCameraClippingRange()


def vtk_image(name):
    win.Render()
    grab = vtkWindowToImageFilter()
    grab.SetInput(win)
    grab.ShouldRerenderOff()
    grab.Update()
    img = vtk_to_numpy(grab.GetOutput().GetPointData().GetScalars())[:, :3].astype(int)
    if mapper.GetLastError():
        print(f"{name}: VTK mapper error: {mapper.GetLastError()}")
    return img


def paraview_image(name):
    Render(view)
    path = os.path.join(out, f"paraview_{name}.png")
    SaveScreenshot(path, view, ImageResolution=[W, H], TransparentBackground=0)
    return read_png(path)


def cli_image(name, extra):
    png = os.path.join(out, f"cli_{name}.png")
    cmd = [cli, "render", data, "--array", f"{array}:mag", "--tf",
           os.path.join(out, "tf.json"), "--range", f"{lut.RGBPoints[0]!r},{lut.RGBPoints[-4]!r}",
           "--camera", os.path.join(out, "camera.json"), "--size", f"{W}x{H}",
           "--opacity-unit-distance", "0.1", "--background", "1,1,1",
           "--specular-power", str(SPECULAR_POWER), *extra, "-o", png]
    if "--backend" not in extra:
        cmd[-2:-2] = ["--backend", "cpu"]
    if "--error-tolerance" not in extra:
        cmd[-2:-2] = ["--error-tolerance", str(TOLERANCE)]
    if PROBE_ON in cmd:
        cmd.remove(PROBE_ON)
    else:
        cmd[-2:-2] = ["--no-probe"]
    subprocess.run(cmd, check=True, stderr=subprocess.DEVNULL)
    return read_png(png)


def pv_last(what):
    """The representation's information property FluidCastLast<what> after a render."""
    display.UpdatePropertyInformation()
    return display.GetPropertyValue(f"FluidCastLast{what}")


# --- the options: (name, CLI options, mapper settings, ParaView properties, compared with) ---

def rbf_vtk(m, classification="post", spp=1, shadows=False):
    m.SetField("rbf")
    m.SetRBFClassification(classification)
    m.SetSamplesPerPixel(spp)
    m.SetShadows(1 if shadows else 0)
    m.SetLightDirection(0.0, 1.0, 0.0)


def rbf_pv(classification="Post (blend values)", spp=1, shadows=False):
    return {"FluidCastField": "RBF", "FluidCastRBFClassification": classification,
            "FluidCastSamplesPerPixel": spp, "FluidCastShadows": int(shadows),
            "FluidCastLightDirection": [0.0, 1.0, 0.0]}


def iso_vtk(m):
    m.SetBlendModeToIsoSurface()
    prop.GetIsoSurfaceValues().SetNumberOfContours(1)
    prop.GetIsoSurfaceValues().SetValue(0, 0.5)


OPTIONS = [
    ("mode_reference", ["--mode", "reference"], lambda m: m.SetMode("reference"),
     {"FluidCastMode": "Reference"}, "base"),
    ("mode_perspective_grid", ["--mode", "perspective-grid", "--grid-cell", "2"],
     lambda m: (m.SetMode("perspective-grid"), m.SetGridCell(2)),
     {"FluidCastMode": "Perspective grid", "FluidCastGridCell": 2}, "base"),
    ("field_sph", ["--field", "sph"], lambda m: m.SetField("sph"), {"FluidCastField": "SPH"},
     "base"),
    ("tolerance_off", ["--error-tolerance", "off"], lambda m: m.SetErrorTolerance(0.0),
     {"FluidCastErrorTolerance": 0.0}, "base"),
    ("probe_on", [PROBE_ON], lambda m: m.SetProbe(1), {"FluidCastProbe": 1}, "base"),
    ("lod", ["--lod", "16"], lambda m: m.SetLODTolerance(16.0), {"FluidCastLODTolerance": 16.0},
     "base"),
    ("iso", ["--iso", "0.5"], iso_vtk, {"FluidCastIsosurfaceValues": [0.5]}, "base"),
    ("rbf_post", ["--field", "rbf"], rbf_vtk, rbf_pv(), "base"),
    ("rbf_pre", ["--field", "rbf", "--classification", "pre"],
     lambda m: rbf_vtk(m, classification="pre"), rbf_pv("Pre (blend colours)"), "rbf_post"),
    ("shadows", ["--field", "rbf", "--shadows", "--light", "0,1,0"],
     lambda m: rbf_vtk(m, shadows=True), rbf_pv(shadows=True), "rbf_post"),
    # One lit pass is noisy; four average it (the shadows' own image is the one to move from).
    ("spp", ["--field", "rbf", "--shadows", "--light", "0,1,0", "--spp", "4"],
     lambda m: rbf_vtk(m, spp=4, shadows=True), rbf_pv(spp=4, shadows=True), "shadows"),
    ("relax_0", ["--relax", "0"], lambda m: m.SetRelax(0.0), {"FluidCastRelax": 0.0}, "base"),
    ("strict", ["--strict"], lambda m: m.SetStrict(1), {"FluidCastStrict": 1}, "base"),
    ("bundle_4", ["--bundle", "4"], lambda m: m.SetBundleSize(4), {"FluidCastBundleSize": 4},
     "base"),
    ("depth_samples_4", ["--depth-samples", "4"], lambda m: m.SetDepthSamples(4),
     {"FluidCastDepthSamples": 4}, "base"),
    ("sampling_scale", ["--sampling-scale", "0.25"], lambda m: m.SetSamplingScale(0.25),
     {"FluidCastSamplingScale": 0.25}, "base"),
    # Unlit, one pass of either noise is near the converged field; lit, the noise shows.
    ("rbf_white_noise", ["--field", "rbf", "--shadows", "--light", "0,1,0", "--noise", "white"],
     lambda m: (rbf_vtk(m, shadows=True), m.SetRBFNoise("white")),
     {**rbf_pv(shadows=True), "FluidCastRBFNoise": "White"}, "shadows"),
    ("rbf_seed", ["--field", "rbf", "--shadows", "--light", "0,1,0", "--seed", "7"],
     lambda m: (rbf_vtk(m, shadows=True), m.SetRBFSeed(7)),
     {**rbf_pv(shadows=True), "FluidCastRBFSeed": 7}, "shadows"),
    ("rbf_step", ["--field", "rbf", "--rbf-step", "0.05"],
     lambda m: (rbf_vtk(m), m.SetRBFStep(0.05)), {**rbf_pv(), "FluidCastRBFStep": 0.05},
     "rbf_post"),
    ("shadow_samples", ["--field", "rbf", "--shadows", "--light", "0,1,0",
                        "--shadow-samples", "4"],
     lambda m: (rbf_vtk(m, shadows=True), m.SetShadowSamples(4)),
     {**rbf_pv(shadows=True), "FluidCastShadowSamples": 4}, "shadows"),
    ("backend_gpu", [], lambda m: m.SetBackend(2), {"FluidCastBackend": "GPU"}, "device"),
    # The GPU backend with the RBF field, shadows and iso-surfaces: each front-end's image on
    # the GPU (lavapipe in CI) within 2/255 of the CPU's image of the same option.
    ("gpu_rbf_post", ["--field", "rbf", "--backend", "gpu"],
     lambda m: (rbf_vtk(m), m.SetBackend(2)), {**rbf_pv(), "FluidCastBackend": "GPU"},
     "gpu:rbf_post"),
    ("gpu_shadows", ["--field", "rbf", "--shadows", "--light", "0,1,0", "--backend", "gpu"],
     lambda m: (rbf_vtk(m, shadows=True), m.SetBackend(2)),
     {**rbf_pv(shadows=True), "FluidCastBackend": "GPU"}, "gpu:shadows"),
    ("gpu_iso", ["--iso", "0.5", "--backend", "gpu"], lambda m: (iso_vtk(m), m.SetBackend(2)),
     {"FluidCastIsosurfaceValues": [0.5], "FluidCastBackend": "GPU"}, "gpu:iso"),
    ("tiles", ["--tiles", "4"], lambda m: m.SetTiles(4), {"FluidCastTiles": 4}, "tiles"),
]


def reset():
    """Every front-end back to the base frame."""
    m = mapper
    m.SetMode("auto")
    m.SetGridCell(1)
    m.SetField("csph")
    m.SetErrorTolerance(TOLERANCE)
    m.SetProbe(0)
    m.SetLODTolerance(0.0)
    m.SetBlendModeToComposite()
    prop.GetIsoSurfaceValues().SetNumberOfContours(0)
    rbf_vtk(m)
    m.SetField("csph")
    m.SetBackend(1)
    m.SetTiles(0)
    m.SetRelax(1.0)
    m.SetStrict(0)
    m.SetBundleSize(8)
    m.SetDepthSamples(16)
    m.SetSamplingScale(1.0)
    m.SetRBFNoise("blue")
    m.SetRBFSeed(0)
    m.SetRBFStep(0.0)
    m.SetShadowSamples(1)
    display.FluidCastMode = "Auto"
    display.FluidCastGridCell = 1
    display.FluidCastField = "CSPH"
    display.FluidCastErrorTolerance = TOLERANCE
    display.FluidCastProbe = 0
    display.FluidCastLODTolerance = 0.0
    display.FluidCastIsosurfaceValues = []
    for k, v in rbf_pv().items():
        setattr(display, k, v)
    display.FluidCastField = "CSPH"
    display.FluidCastBackend = "CPU"
    display.FluidCastTiles = 0
    display.FluidCastRelax = 1.0
    display.FluidCastStrict = 0
    display.FluidCastBundleSize = 8
    display.FluidCastDepthSamples = 16
    display.FluidCastSamplingScale = 1.0
    display.FluidCastRBFNoise = "Blue"
    display.FluidCastRBFSeed = 0
    display.FluidCastRBFStep = 0.0
    display.FluidCastShadowSamples = 1


def worst(a, b):
    return int(abs(a - b).max())


reset()
images = {"base": (cli_image("base", []), vtk_image("base"), paraview_image("base"))}
status = 0
c, v, p = images["base"]
print(f"base: CLI vs VTK {worst(c, v)}/255, CLI vs ParaView {worst(c, p)}/255, "
      f"{int((c != 255).any(axis=1).sum())} pixels drawn")
if max(worst(c, v), worst(c, p)) > AGREE or int((c != 255).any(axis=1).sum()) < W * H // 20:
    print("FAIL: the base frame differs between the front-ends, or is (almost) empty")
    status = 1
for name, cli_opts, set_vtk, pv_props, against in OPTIONS:
    reset()
    set_vtk(mapper)
    for k, val in pv_props.items():
        setattr(display, k, val)
    c = cli_image(name, cli_opts)
    v = vtk_image(name)
    p = paraview_image(name)
    images[name] = (c, v, p)
    agree = max(worst(c, v), worst(c, p), worst(v, p))
    line = f"{name}: CLI vs VTK {worst(c, v)}, vs ParaView {worst(c, p)}, VTK vs ParaView " \
           f"{worst(v, p)} (/255, allowed {AGREE})"
    ok = agree <= AGREE
    if against == "device":
        devices = (mapper.GetLastDevice(), pv_last("Device"))
        line += f"; devices {devices}"
        ok = ok and all(d.startswith("GPU") for d in devices)
    elif against.startswith("gpu:"):
        cpu = images[against[4:]]
        devices = (mapper.GetLastDevice(), pv_last("Device"))
        vs_cpu = max(worst(x, y) for x, y in zip(images[name], cpu))
        line += f"; devices {devices}; vs the CPU's {against[4:]} {vs_cpu}/255"
        ok = ok and vs_cpu <= AGREE and all(d.startswith("GPU") for d in devices)
    elif against == "tiles":
        tiles = (mapper.GetLastTiles(), pv_last("Tiles"))
        line += f"; tiles {tiles}; vs base {worst(p, images['base'][2])}"
        ok = ok and all(t >= 2 for t in tiles)
    else:
        moved = min(worst(x, y) for x, y in zip(images[name], images[against]))
        line += f"; moved from {against} by at least {moved}/255"
        ok = ok and moved > AGREE
    print(line)
    if not ok:
        print(f"FAIL: {name}")
        status = 1


def rbf_on_the_gpu(path):
    """The RBF field with Backend GPU in a VTK window: rendered on the GPU, and the image of
    the CLI's `--field rbf --backend gpu` within 2/255."""
    r = vtkXMLUnstructuredGridReader()
    r.SetFileName(path)
    mapper.SetInputConnection(r.GetOutputPort())
    reset()
    rbf_vtk(mapper)
    mapper.SetBackend(2)
    ren.ResetCamera()
    write_camera(ren.GetActiveCamera(), os.path.join(out, "camera_small.json"))
    r.Update()
    lo_s, hi_s = r.GetOutput().GetPointData().GetArray(array).GetRange(-1)
    ctf.RemoveAllPoints()
    otf.RemoveAllPoints()
    for k in range(0, len(rgb), 4):
        x = lo_s + (hi_s - lo_s) * (rgb[k] - lo) / (hi - lo)
        ctf.AddRGBPoint(x, *rgb[k + 1:k + 4])
    for k in range(0, len(pts), 4):
        otf.AddPoint(lo_s + (hi_s - lo_s) * (pts[k] - lo) / (hi - lo), *pts[k + 1:k + 4])
    v = vtk_image("rbf_gpu_small")
    png = os.path.join(out, "cli_rbf_gpu_small.png")
    subprocess.run([cli, "render", path, "--array", f"{array}:mag", "--tf",
                    os.path.join(out, "tf.json"), "--range", f"{lo_s!r},{hi_s!r}",
                    "--camera", os.path.join(out, "camera_small.json"), "--size", f"{W}x{H}",
                    "--opacity-unit-distance", "0.1", "--background", "1,1,1",
                    "--field", "rbf", "--backend", "gpu", "-o", png],
                   check=True, stderr=subprocess.DEVNULL)
    c = read_png(png)
    device = mapper.GetLastDevice()
    drawn = int((v != 255).any(axis=1).sum())
    print(f"rbf_gpu ({os.path.basename(path)}): mapper on {device!r}, CLI vs VTK "
          f"{worst(c, v)}/255 (allowed {AGREE}), {drawn} pixels drawn")
    return device.startswith("GPU") and worst(c, v) <= AGREE and drawn > 0


if small is not None and not rbf_on_the_gpu(small):
    print("FAIL: rbf_gpu")
    status = 1
sys.stdout.flush()
os._exit(status)
