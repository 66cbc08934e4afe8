"""pvbatch test: a .pvd time series through the plugin's "fluidcast particle reader", which
reads the next time step while the current one renders (Prefetch), animated with the
"fluidcast" representation.

    pvbatch pvbatch_series.py PLUGIN.so SERIES.pvd ARRAY OUTDIR [--bench]

Checks, stepping ParaView's animation forward through every time step:
- the reader offers the series' times to the animation (TimestepValues), as ParaView's own
  .pvd reader does;
- at every time step its particles give the same screenshot as ParaView's .pvd reader
  (within 2/255; the same particles, so they should be equal) and the same number of points;
- with Prefetch on, every step after the first came ready from the prefetch thread
  (PrefetchedSteps = steps - 1); with it off, none did;
- a series whose third step is a truncated file reports a VTK error naming the .pvd, the
  step and the file at that step, draws nothing there, and renders the steps after it.
Then it reports the animation's frame throughput (frames/s, read and render together) with
Prefetch on and off and with ParaView's own .pvd reader, each over a fresh reader, best of
two; the ratios are printed, not asserted (timings belong to benchmarks). With --bench only
the throughput is measured (for a user's own, larger series). Exit code 0 pass, 1 fail,
77 skipped (data not present and FLUIDCAST_REQUIRE_DATA unset).
"""
import faulthandler
import os
import shutil
import sys
import time
import xml.etree.ElementTree as ET

faulthandler.enable(file=sys.__stderr__)

from mpi_views import read_png, white_view  # tests/vtk, the script's folder
from paraview.simple import (
    ColorBy,
    Delete,
    GetAnimationScene,
    GetColorTransferFunction,
    GetOpacityTransferFunction,
    Hide,
    LoadPlugin,
    PVDReader,
    Render,
    SaveScreenshot,
    Show,
    servermanager,
)
from pvbatch_mpi import missing_data
from vtkmodules.vtkCommonCore import vtkOutputWindow, vtkStringOutputWindow

bench = "--bench" in sys.argv
plugin, series, array, out = [a for a in sys.argv[1:] if a != "--bench"][:4]
if (missing := missing_data(series)) is not None:
    sys.exit(missing)
os.makedirs(out, exist_ok=True)
W, H = 240, 180
LoadPlugin(plugin, remote=False, ns=globals())

# VTK's error messages, counted; ParaView's own output window is put back before exiting.
original_window = vtkOutputWindow.GetInstance()
messages = vtkStringOutputWindow()
vtkOutputWindow.SetInstance(messages)

view = white_view(W, H)
scene = GetAnimationScene()
failures = []
colours = []  # the fixed colour range every shown source gets (set_colours)


def say(*args):
    """Progress on the real stderr: pvbatch's captured stdout goes to VTK's output window."""
    sys.__stderr__.write(" ".join(str(a) for a in args) + "\n")
    sys.__stderr__.flush()


def show(source):
    """`source` in the view with the fluidcast representation, coloured by ARRAY."""
    d = Show(source, view)
    d.SetRepresentationType("fluidcast")
    ColorBy(d, ("POINTS", array, "Magnitude"))
    d.ScalarOpacityFunction = GetOpacityTransferFunction(array)
    d.ScalarOpacityUnitDistance = 0.1
    d.FluidCastBackend = "CPU"
    if colours:  # ColorBy rescaled the map to the current step's range: the fixed one again
        lut, pwf = GetColorTransferFunction(array), GetOpacityTransferFunction(array)
        lut.RescaleTransferFunction(*colours)
        lo, hi = colours
        pwf.Points = [lo, 0.05, 0.5, 0.0, hi, 0.8, 0.5, 0.0]
    return d


def screenshot(name):
    Render(view)
    path = os.path.join(out, f"{name}.png")
    SaveScreenshot(path, view, ImageResolution=[W, H], TransparentBackground=0)
    return read_png(path)


def points(source):
    return servermanager.Fetch(source).GetNumberOfPoints()


def prefetched(reader):
    reader.UpdatePropertyInformation()
    return int(reader.GetProperty("PrefetchedSteps").GetData())


def set_colours(source):
    """A fixed colour map and opacity over the last step's range, for every source and time
    (a first step at rest has a range of one value)."""
    source.UpdatePipeline(times[-1])  # (setting the scene's time alone leaves its ranges)
    lo, hi = source.PointData[array].GetRange(-1)
    hi = max(hi, lo + 1e-6)
    lut, pwf = GetColorTransferFunction(array), GetOpacityTransferFunction(array)
    lut.AutomaticRescaleRangeMode = "Never"
    lut.ColorSpace = "RGB"
    lut.RescaleTransferFunction(lo, hi)
    pwf.Points = [lo, 0.05, 0.5, 0.0, hi, 0.8, 0.5, 0.0]
    colours.extend([lo, hi])


def lut_range(lut):
    """The first and last of a colour map's control points."""
    xs = list(lut.RGBPoints)[0::4]
    return [xs[0], xs[-1]]


def colour_range_over_time(theirs):
    """ParaView's colour map set at a first step where ARRAY is constant holds one value: the
    representation warns, at a later step, that the values saturate and how to fix it; after
    ParaView's "Rescale to data range over all timesteps" over our reader the map's range is
    the union of every step's range as ParaView's own .pvd reader reports them, and nothing is
    warned."""
    reader = fluidcastparticlereader(FileName=series)
    scene.AnimationTime = times[0]
    d = show(reader)
    lut = GetColorTransferFunction(array)
    lut.AutomaticRescaleRangeMode = "Grow and update on 'Apply'"
    d.RescaleTransferFunctionToDataRange(False, True)
    first = lut_range(lut)
    single = first[1] - first[0] <= 0.01 * max(abs(first[0]), abs(first[1]))
    before = len(messages.GetOutput())
    screenshot("range_first_step")
    scene.AnimationTime = times[len(times) // 2]
    screenshot("range_later_step")
    text = messages.GetOutput()[before:]
    warned = "is a single value" in text and "over all timesteps" in text
    say(f"colour map from the first step: range {first}; a later step "
        f"{'warned of' if warned else 'said nothing of'} the saturation")
    if not single or not warned:
        failures.append(f"a single-value first-step range {first} (single: {single}) was "
                        f"{'' if warned else 'not '}warned of at a later step")
    d.RescaleTransferFunctionToDataRangeOverTime()
    over = lut_range(lut)
    want = [float("inf"), float("-inf")]
    for t in times:
        theirs.UpdatePipeline(t)
        lo, hi = theirs.PointData[array].GetRange(-1)
        want = [min(want[0], lo), max(want[1], hi)]
    before = len(messages.GetOutput())
    scene.AnimationTime = times[len(times) // 2]
    screenshot("range_over_time")
    quiet = "single value" not in messages.GetOutput()[before:]
    say(f"rescaled over all time steps: {over}, ParaView's .pvd reader's steps unite to {want}; "
        f"{'no warning' if quiet else 'still a warning'}")
    if max(abs(a - b) for a, b in zip(over, want)) > 1e-6 * max(map(abs, want)) or not quiet:
        failures.append(f"range over time {over} vs {want}, quiet: {quiet}")
    lut.AutomaticRescaleRangeMode = "Never"
    Hide(reader, view)
    Delete(d)
    Delete(reader)


def throughput(make_reader, times):
    """Frames per second of the animation over a fresh reader: each step set as the scene's
    time, which updates the pipeline and renders the view once, as ParaView's Play does."""
    reader = make_reader()
    scene.AnimationTime = times[0]
    d = show(reader)
    Render(view)
    start = time.perf_counter()
    for t in times[1:]:
        scene.AnimationTime = t
    seconds = time.perf_counter() - start
    hits = prefetched(reader) if reader.GetProperty("PrefetchedSteps") else 0
    Hide(reader, view)
    Delete(d)
    Delete(reader)
    return (len(times) - 1) / seconds, hits


ours = fluidcastparticlereader(FileName=series)
times = list(ours.TimestepValues)
scene.UpdateAnimationUsingDataTimeSteps()
say(f"{series}: {len(times)} time steps, t = {times[0]} .. {times[-1]}")
if len(times) < 3:
    say("FAIL: a series of at least 3 time steps is needed")
    os._exit(1)
set_colours(ours)
show(ours)
view.ResetCamera()
view.CameraPosition = [a + 2 * (a - b) for a, b in zip(view.CameraPosition, view.CameraFocalPoint)]
view.ResetCamera()

if not bench:
    theirs = PVDReader(FileName=series)
    if list(theirs.TimestepValues) != times:
        failures.append(f"TimestepValues {times} vs ParaView's {list(theirs.TimestepValues)}")
    others = show(theirs)
    for i, t in enumerate(times):
        scene.AnimationTime = t
        Hide(theirs, view)
        Show(ours, view)
        a = screenshot(f"ours_{i:03d}")
        Hide(ours, view)
        Show(theirs, view)
        b = screenshot(f"paraview_{i:03d}")
        n_ours, n_theirs = points(ours), points(theirs)
        drawn = int((a != 255).any(axis=1).sum())
        diff = int(abs(a - b).max())
        say(f"t = {t}: {n_ours} vs {n_theirs} points; screenshots max diff {diff}/255; "
              f"{drawn} pixels drawn")
        if n_ours != n_theirs or diff > 2 or drawn < W * H // 50:
            failures.append(f"t = {t}: the fluidcast reader's step differs from ParaView's")
    Hide(theirs, view)
    Show(ours, view)
    hits = prefetched(ours)
    say(f"Prefetch on: {hits} of {len(times)} steps came from the prefetch thread")
    if hits != len(times) - 1:
        failures.append(f"PrefetchedSteps {hits}, expected {len(times) - 1}")

    # A truncated third step: an error naming it when shown, the steps after it still read.
    damaged_dir = os.path.join(out, "damaged")
    shutil.rmtree(damaged_dir, ignore_errors=True)
    os.makedirs(damaged_dir)
    root = ET.parse(series).getroot()
    entries = sorted(root.iter("DataSet"), key=lambda e: float(e.get("timestep", "0")))
    base = os.path.dirname(os.path.abspath(series))
    for e in entries[:4]:
        src = os.path.join(base, e.get("file"))
        dst = os.path.join(damaged_dir, os.path.basename(src))
        e.set("file", os.path.basename(src))
        if e is entries[2]:
            with open(src, "rb") as f:
                data = f.read()
            with open(dst, "wb") as f:
                f.write(data[: len(data) // 2])
            damaged_name = os.path.basename(src)
        else:
            os.symlink(src, dst)
    collection = root.find("Collection")
    for e in list(collection):
        if e not in entries[:4]:
            collection.remove(e)
    damaged_pvd = os.path.join(damaged_dir, "damaged.pvd")
    ET.ElementTree(root).write(damaged_pvd)
    Hide(ours, view)
    hurt = fluidcastparticlereader(FileName=damaged_pvd)
    scene.UpdateAnimationUsingDataTimeSteps()
    show(hurt)
    for i, t in enumerate(times[:4]):
        before = len(messages.GetOutput())
        scene.AnimationTime = t
        drawn = int((screenshot(f"damaged_{i}") != 255).any(axis=1).sum())
        text = messages.GetOutput()[before:]
        named = "damaged.pvd" in text and f"time step {i}" in text and damaged_name in text
        say(f"damaged series, step {i}: {drawn} pixels drawn, "
              f"{'an error naming the step and file' if named else 'no error'}")
        if (i == 2) != named or (i == 2) != (drawn == 0):
            failures.append(f"damaged series, step {i}: expected "
                            f"{'an error and nothing drawn' if i == 2 else 'a render'}")
    Hide(hurt, view)
    Delete(hurt)
    colour_range_over_time(theirs)
    Delete(others)
    Delete(theirs)

Hide(ours, view)
scene.UpdateAnimationUsingDataTimeSteps()
readers = {
    "Prefetch 0": lambda: fluidcastparticlereader(FileName=series, Prefetch=0),
    "Prefetch 1": lambda: fluidcastparticlereader(FileName=series, Prefetch=1),
    "ParaView's .pvd reader": lambda: PVDReader(FileName=series),
}
rates = {}
for name in list(readers) * 2:
    fps, hits = throughput(readers[name], times)
    rates.setdefault(name, []).append(fps)
    say(f"{name}: {fps:.2f} frames/s over {len(times) - 1} frames ({hits} prefetched)")
    if (hits > 0) != (name == "Prefetch 1"):
        failures.append(f"{name}: {hits} steps prefetched")
off, on, theirs = (max(rates[n]) for n in readers)
say(f"frame throughput, best of 2: {on:.2f} frames/s prefetched, {off:.2f} frames/s read in "
    f"turn ({on / off:.2f}x), {theirs:.2f} frames/s with ParaView's .pvd reader "
    f"({on / theirs:.2f}x); {os.cpu_count()} cores")

# Representations are deleted, some later than Delete() (ParaView holds them a while): none
# may say anything then (the mapper once refused its own destructor's clearing of the
# kernel's name, with an error for every representation deleted).
if " stays '" in messages.GetOutput():
    failures.append("a deleted fluidcast representation reported an error")
vtkOutputWindow.SetInstance(original_window)
for f in failures:
    say("FAIL:", f)
say("FAIL" if failures else "PASS")
# Leave without ParaView's teardown: under Xvfb, Debian's pvbatch dies with "GLXBadContext"
# while destroying its window after sys.exit (as pvbatch_fluidcast.py notes).
os._exit(1 if failures else 0)
