"""pvbatch property fuzzer: random values for the fluidcast representation's properties (in a
ParaView view) and the wrapped mapper's setters (in a VTK window) never leave the view unable
to render good data.

    PYTHONPATH=BUILD/python pvbatch pvbatch_property_fuzz.py PLUGIN.so DATA.vtu ARRAY OUTDIR \
        [CASES] [SEED] [WxH]

First, the case of issue 45: FluidCastSupportRadius = inf, then -1, then a good value; the
view's camera stays finite and the good data render again as before.

Then CASES (default 200) random assignments on each of the two surfaces: a property chosen at
random gets a hostile or ordinary value (inf, -inf, NaN, -1, 0, 1e30, a whole number out of an
enumeration's range, an unknown name, ...), set through the server-manager layer (as a
Python script or a state file would, without the GUI's domain checks) or the mapper's Set
method, and the view renders. Every 10 assignments and at the end every property goes back
to its default: the image must be the one rendered before the fuzzing (within 1/255), and
the camera after ResetCamera finite. A crash or an abort ends the process (the test fails);
a refusal is a VTK error, which is what a hostile value should give.

Exit code 0 pass, 1 fail. Prints the cases run and how many assignments were refused.
"""
import math
import os
import random
import sys

from fluidcast import vtkFluidCastVolumeMapper
from mpi_views import read_png, white_view  # tests/vtk, the script's folder
from paraview.simple import (
    ColorBy,
    GetOpacityTransferFunction,
    LoadPlugin,
    OpenDataFile,
    Render,
    SaveScreenshot,
    Show,
)
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkOutputWindow, vtkStringOutputWindow
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

plugin, data, array, out = sys.argv[1:5]
cases = int(sys.argv[5]) if len(sys.argv) > 5 else 200
seed = int(sys.argv[6]) if len(sys.argv) > 6 else 1
os.makedirs(out, exist_ok=True)
W, H = map(int, (sys.argv[7] if len(sys.argv) > 7 else "64x48").split("x"))
RESTORE_EVERY = 10
AGREE = 1  # /255 per channel

LoadPlugin(plugin, remote=False, ns=globals())
# VTK's errors are counted in a string window; pvbatch sends Python's own errors there too, so
# an exception in this script is printed to the real stderr (sys.excepthook) before exiting.
original_window = vtkOutputWindow.GetInstance()
messages = vtkStringOutputWindow()
vtkOutputWindow.SetInstance(messages)
rng = random.Random(seed)
failures = []


def excepthook(kind, value, tb):
    import traceback
    traceback.print_exception(kind, value, tb, file=sys.__stderr__)
    vtkOutputWindow.SetInstance(original_window)
    os._exit(1)


sys.excepthook = excepthook

HOSTILE = [math.inf, -math.inf, math.nan, -1.0, 0.0, 1e30, -1e30, 1e-30, 0.5, 1.0, 2.0, 3.0,
           7.0, 64.0, 65537.0, 2.0 ** 31, -(2.0 ** 31)]
NAMES = ["", "nonsense", array, "colour", "density", "gpu", "cubic", "wendland-c2", "rbf",
         "x" * 1000]


def say(text):
    sys.__stderr__.write(text + "\n")
    sys.__stderr__.flush()


def finite_camera(cam):
    return all(math.isfinite(v) for v in (*cam.GetPosition(), *cam.GetFocalPoint(),
                                           *cam.GetViewUp(), cam.GetViewAngle()))


def worst(a, b):
    return int(abs(a - b).max()) if a.shape == b.shape else 255


seen = [0]


def refusals():
    """VTK errors reported since the last call."""
    text = messages.GetOutput()
    new, seen[0] = text[seen[0]:], len(text)
    return new.count("ERROR")


# --- the ParaView representation ---
view = white_view(W, H)
reader = OpenDataFile(data)
display = Show(reader, view)
display.SetRepresentationType("fluidcast")
ColorBy(display, ("POINTS", array, "Magnitude"))
display.ScalarOpacityFunction = GetOpacityTransferFunction(array)
display.FluidCastBackend = "CPU"
view.ResetCamera()
Render(view)
# The bounds grow by the support radius once the particles are prepared: reset again.
view.ResetCamera()
rep = display.SMProxy
fuzzed = sorted(n for n in display.ListProperties()
                if n.startswith("FluidCast") or n == "ScalarOpacityUnitDistance")


def elements(name):
    prop = rep.GetProperty(name)
    return [prop.GetElement(i) for i in range(prop.GetNumberOfElements())]


defaults = {n: elements(n) for n in fuzzed}


def pv_image(name="paraview"):
    Render(view)
    path = os.path.join(out, name + ".png")
    SaveScreenshot(path, view, ImageResolution=[W, H])
    return read_png(path)


def pv_restore():
    for n in fuzzed:
        prop = rep.GetProperty(n)
        prop.SetNumberOfElements(len(defaults[n]))
        for i, v in enumerate(defaults[n]):
            prop.SetElement(i, v)
    rep.UpdateVTKObjects()
    view.ResetCamera()
    if not finite_camera(view.GetActiveCamera()):
        failures.append("ParaView: the camera is not finite after ResetCamera")


reference = pv_image("reference")
if int(reference.min()) == 255:
    failures.append("ParaView: the reference image is blank")

# Issue 45's case: inf, then -1, then a good value.
for bad in (math.inf, -1.0):
    display.FluidCastSupportRadius = bad
    view.ResetCamera()
    pv_image()
    if not finite_camera(view.GetActiveCamera()):
        failures.append(f"ParaView: FluidCastSupportRadius = {bad} left the camera not finite")
    if refusals() == 0:
        failures.append(f"ParaView: FluidCastSupportRadius = {bad} was not refused")
display.FluidCastSupportRadius = 0.0
pv_restore()
if (d := worst(pv_image("restored"), reference)) > AGREE:
    failures.append(f"ParaView: after inf and -1 the good radius renders {d}/255 off")
say(f"ParaView: {len(fuzzed)} properties; SupportRadius inf, -1, then good: "
    f"{'ok' if not failures else failures}")


def random_value(prop):
    cls = prop.GetClassName()
    if cls == "vtkSMStringVectorProperty":
        return rng.choice(NAMES)
    v = rng.choice(HOSTILE)
    if cls in ("vtkSMIntVectorProperty", "vtkSMIdTypeVectorProperty"):
        if math.isfinite(v) and abs(v) < 2 ** 31:
            return int(v)
        return rng.choice([-1, 0, 1, 2, 3, 99, 2 ** 31 - 1, -(2 ** 31)])
    return v


def pv_case(k):
    name = rng.choice(fuzzed)
    prop = rep.GetProperty(name)
    n = max(prop.GetNumberOfElements(), 1 if prop.GetRepeatCommand() == 0 else 0)
    if prop.GetRepeatCommand():
        n = rng.choice([0, 1, 2])
        prop.SetNumberOfElements(n)
    values = [random_value(prop) for _ in range(n)]
    for i, v in enumerate(values):
        prop.SetElement(i, v)
    rep.UpdateVTKObjects()
    view.ResetCamera()
    Render(view)
    if not finite_camera(view.GetActiveCamera()):
        failures.append(f"ParaView case {k}: {name} = {values} left the camera not finite")


def fuzz(surface, case, restore, image):
    refused = 0
    for k in range(cases):
        case(k)
        refused += refusals() > 0
        if (k + 1) % RESTORE_EVERY == 0 or k + 1 == cases:
            restore()
            if (d := worst(image(), reference_of[surface])) > AGREE:
                failures.append(f"{surface}: after case {k} and defaults restored the image "
                                f"is {d}/255 off")
                break
            refusals()
        if (k + 1) % 1000 == 0:
            say(f"{surface}: {k + 1} cases, {refused} refused, {len(failures)} failures")
    say(f"{surface}: {cases} cases, {refused} refused a value")


reference_of = {"ParaView": reference}
fuzz("ParaView", pv_case, pv_restore, pv_image)

# --- the wrapped mapper in a VTK window ---
vtk_reader = vtkXMLUnstructuredGridReader()
vtk_reader.SetFileName(data)
mapper = vtkFluidCastVolumeMapper()
mapper.SetInputConnection(vtk_reader.GetOutputPort())
mapper.SelectScalarArray(array)
mapper.SetScalarModeToUsePointFieldData()
mapper.SetBackend(vtkFluidCastVolumeMapper.CPU)
lo, hi = reader.PointData[array].GetRange(-1)
ctf = vtkColorTransferFunction()
ctf.AddRGBPoint(lo, 0.2, 0.2, 0.8)
ctf.AddRGBPoint(hi, 0.9, 0.8, 0.1)
otf = vtkPiecewiseFunction()
otf.AddPoint(lo, 0.1)
otf.AddPoint(hi, 0.8)
prop = vtkVolumeProperty()
prop.SetColor(ctf)
prop.SetScalarOpacity(otf)
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
ren.ResetCamera()
mapper_camera = [ren.GetActiveCamera().GetPosition(), ren.GetActiveCamera().GetFocalPoint()]
# Every Set method that takes one number or one name, with its default (Get) to go back to.
SETTERS = [m[3:] for m in dir(mapper) if m.startswith("Set") and hasattr(mapper, "Get" + m[3:])
           and m[3:] not in ("InputData", "InputConnection", "InputArrayToProcess", "Debug",
                             "GlobalWarningDisplay", "ReferenceCount", "ObjectName",
                             "BlendMode", "CroppingRegionPlanes", "LightDirection",
                             "Cropping", "ScalarMode", "ArrayAccessMode", "Adapter",
                             "InputDataObject", "ExecutiveObject", "ProgressText",
                             "AbortExecute", "ReleaseDataFlag", "InformationObject",
                             "Progress", "NumberOfInputConnections", "AbortOutput",
                             "ContainerAlgorithm", "Executive", "Information",
                             "ProgressObserver")]
mapper_defaults = {}
for s in SETTERS:
    try:
        mapper_defaults[s] = getattr(mapper, "Get" + s)()
    except TypeError:
        pass
SETTERS = []
for s, v in sorted(mapper_defaults.items()):
    try:  # a property whose Set takes back what its Get gives (one number or one name)
        getattr(mapper, "Set" + s)(v)
        SETTERS.append(s)
    except TypeError:
        pass


def vtk_image():
    ren.GetActiveCamera().SetPosition(*mapper_camera[0])
    ren.GetActiveCamera().SetFocalPoint(*mapper_camera[1])
    ren.ResetCameraClippingRange()
    win.Render()
    grab = vtkWindowToImageFilter()
    grab.SetInput(win)
    grab.ReadFrontBufferOff()
    grab.Update()
    return vtk_to_numpy(grab.GetOutput().GetPointData().GetScalars())[:, :3].astype(int)


def vtk_restore():
    for s in SETTERS:
        getattr(mapper, "Set" + s)(mapper_defaults[s])
    ren.ResetCamera()
    if not finite_camera(ren.GetActiveCamera()):
        failures.append("mapper: the camera is not finite after ResetCamera")


def vtk_case(k):
    name = rng.choice(SETTERS)
    default = mapper_defaults[name]
    if isinstance(default, str) or default is None:
        v = rng.choice(NAMES)
    elif isinstance(default, int):
        v = rng.choice([-1, 0, 1, 2, 3, 7, 99, 65537, 2 ** 31 - 1])
    else:
        v = rng.choice(HOSTILE)
    try:
        getattr(mapper, "Set" + name)(v)
    except (TypeError, ValueError, OverflowError):
        return  # the wrapping refuses the value before it reaches the mapper
    ren.ResetCamera()
    win.Render()
    if not finite_camera(ren.GetActiveCamera()):
        failures.append(f"mapper case {k}: Set{name}({v}) left the camera not finite")


say(f"mapper: {len(SETTERS)} setters: {' '.join(SETTERS)}")
reference_of["mapper"] = vtk_image()
if int(reference_of["mapper"].min()) == 255:
    failures.append("mapper: the reference image is blank")
refusals()
fuzz("mapper", vtk_case, vtk_restore, vtk_image)

vtkOutputWindow.SetInstance(original_window)
for f in failures:
    say("FAIL " + f)
say("pvbatch_property_fuzz: " + ("FAIL" if failures else "ok"))
sys.stdout.flush()
# As pvbatch_parity.py: a VTK window and mapper of this script's own would be destroyed after
# ParaView's finalization at a normal exit.
os._exit(1 if failures else 0)
