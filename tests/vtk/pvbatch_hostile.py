"""pvbatch test: hostile data never crashes ParaView through the fluidcast representation.

    pvbatch pvbatch_hostile.py PLUGIN.so OUTDIR

Shows each case with the "fluidcast" representation and renders it: damaged files (truncated,
garbage after the end, no points, a forged compression header) read by ParaView's own reader
and by the plugin's "fluidcast particle reader" (vtkFluidCastReader, which must report each
as a VTK error; ParaView 5.11's own vtkXMLDataParser aborts with std::bad_alloc on the forged
header, so that file goes through fluidcast's reader only), and a good file, which
fluidcast's reader must read exactly as ParaView's does and data that ParaView reads but that
challenges fluidcast (a far outlier, coordinates near the float limit, all-NaN points, a
zero or NaN radius array, values beyond single precision, two points 1e30 apart, no points).
Every case must come back from Render() and SaveScreenshot(): a Rust panic or an abort kills
the process, so reaching the end is the test. Cases that fluidcast refuses must report a VTK
error (vtkFluidCastVolumeMapper's message), counted through VTK's output window.
Exit code 0 pass, 1 fail.
"""
import base64
import faulthandler
import os
import struct
import sys
import zlib

faulthandler.enable(file=sys.__stderr__)

import numpy as np
from paraview.simple import (
    ColorBy,
    CreateView,
    Delete,
    GetOpacityTransferFunction,
    Hide,
    LoadPlugin,
    OpenDataFile,
    PVTrivialProducer,
    Render,
    SaveScreenshot,
    Show,
    servermanager,
)
from vtkmodules.util.numpy_support import numpy_to_vtk
from vtkmodules.vtkCommonCore import vtkOutputWindow, vtkPoints, vtkStringOutputWindow
from vtkmodules.vtkCommonDataModel import vtkPolyData

plugin, out = sys.argv[1:3]
os.makedirs(out, exist_ok=True)
LoadPlugin(plugin, remote=False, ns=globals())

# Count VTK's error messages; ParaView's own output window is put back before exiting
# (destroying a Python-owned instance at shutdown would crash pvbatch).
original_window = vtkOutputWindow.GetInstance()
messages = vtkStringOutputWindow()
vtkOutputWindow.SetInstance(messages)


def polydata(pts, arrays):
    pd = vtkPolyData()
    p = vtkPoints()
    p.SetData(numpy_to_vtk(np.ascontiguousarray(pts, dtype=np.float64), deep=True))
    pd.SetPoints(p)
    for name, values in arrays.items():
        a = numpy_to_vtk(np.ascontiguousarray(values, dtype=np.float64), deep=True)
        a.SetName(name)
        pd.GetPointData().AddArray(a)
    return pd


lattice = np.stack(np.meshgrid(*[np.arange(4) * 0.1] * 3, indexing="ij"), -1).reshape(-1, 3)
ones = np.ones(len(lattice))


def with_point(p):
    return np.vstack([lattice, [p]])


# (name, data, expect a VTK error, extra representation settings)
in_memory = [
    ("far_outlier", polydata(with_point([0, -1e14, 0]), {"q": np.ones(65)}), False, {}),
    ("near_float_max", polydata(with_point([3e38, 0, 0]), {"q": np.ones(65)}), False, {}),
    # One infinite point among good ones: left out of the bounds, so the camera stays finite.
    ("one_inf_point", polydata(with_point([np.inf, 0, 0]), {"q": np.ones(65)}), False, {}),
    # ParaView draws nothing for data without finite bounds: no mapper call, no error.
    ("all_nan", polydata(np.full((8, 3), np.nan), {"q": np.ones(8)}), False, {}),
    ("zero_radius", polydata(lattice, {"q": ones, "h": np.zeros(64)}), True,
     {"FluidCastRadiusArray": "h"}),
    ("nan_radius", polydata(lattice, {"q": ones, "h": np.full(64, np.nan)}), True,
     {"FluidCastRadiusArray": "h"}),
    ("value_beyond_f32", polydata(lattice, {"q": np.full(64, 1e39)}), True, {}),
    ("two_points_1e30_apart", polydata([[0, 0, 0], [1e30, 0, 0]], {"q": [1.0, 2.0]}), True, {}),
]


def damaged_files():
    """Writes damaged .vtu files; returns [(name, path)]."""
    head = ('<?xml version="1.0"?><VTKFile type="UnstructuredGrid" version="1.0" '
            'byte_order="LittleEndian" header_type="UInt64"{c}><UnstructuredGrid>'
            '<Piece NumberOfPoints="{n}" NumberOfCells="0"><PointData Scalars="q">'
            '<DataArray type="Float64" Name="q" format="ascii">{q}</DataArray></PointData>'
            '<Points><DataArray type="Float32" NumberOfComponents="3" format="{f}">{p}'
            '</DataArray></Points><Cells><DataArray type="Int64" Name="connectivity"/>'
            '<DataArray type="Int64" Name="offsets"/><DataArray type="UInt8" Name="types"/>'
            '</Cells></Piece></UnstructuredGrid></VTKFile>\n')
    pts = " ".join(f"{x:g}" for x in lattice.ravel())
    q = " ".join("1" for _ in range(64))
    good = head.format(c="", n=64, q=q, f="ascii", p=pts)
    forged = struct.pack("<QQQQ", 1, 1 << 40, 1 << 40, 12) + zlib.compress(b"\0" * 12)
    cases = {
        "truncated": good[: len(good) * 2 // 3],
        "garbage_after_end": good + "garbage",
        "no_points": head.format(c="", n=0, q="", f="ascii", p=""),
        "forged_block_header": head.format(c=' compressor="vtkZLibDataCompressor"', n=64, q=q,
                                           f="binary", p=base64.b64encode(forged).decode()),
    }
    paths = []
    for name, text in cases.items():
        path = os.path.join(out, name + ".vtu")
        with open(path, "w") as f:
            f.write(text)
        paths.append((name, path))
    return paths


failures = []
view = CreateView("RenderView")
view.ViewSize = [64, 48]
view.OrientationAxesVisibility = 0


def fetch(source):
    source.UpdatePipeline()
    return servermanager.Fetch(source)


def say(text):
    """Progress on the real stderr: pvbatch's captured stdout is lost if the process dies."""
    sys.__stderr__.write(text + "\n")
    sys.__stderr__.flush()


def show(source, name, settings):
    say(f"case {name}")
    display = Show(source, view)
    display.SetRepresentationType("fluidcast")
    if source.PointData.keys():
        ColorBy(display, ("POINTS", "q"))
        display.ScalarOpacityFunction = GetOpacityTransferFunction("q")
    for k, v in settings.items():
        setattr(display, k, v)
    view.ResetCamera()
    cam = view.GetActiveCamera()
    if not all(np.isfinite([*cam.GetPosition(), *cam.GetFocalPoint()])):
        failures.append(f"{name}: the camera is not finite after ResetCamera")
    Render(view)
    SaveScreenshot(os.path.join(out, name + ".png"), view, ImageResolution=[64, 48])
    Hide(source, view)
    Delete(source)


for name, data, expect_error, settings in in_memory:
    before = len(messages.GetOutput())
    src = PVTrivialProducer()
    src.GetClientSideObject().SetOutput(data)
    show(src, name, settings)
    text = messages.GetOutput()[before:]
    got_error = "vtkFluidCastVolumeMapper" in text and "ERROR" in text
    say(f"{name}: {'VTK error' if got_error else 'rendered'}")
    if expect_error and not got_error:
        failures.append(f"{name}: expected a VTK error from the fluidcast mapper")

damaged = damaged_files()
for name, path in damaged:
    if name == "forged_block_header":
        continue  # ParaView's own XML reader aborts on it (std::bad_alloc): fluidcast's only
    show(OpenDataFile(path), name, {})
    say(f"{name}: survived ParaView's reader")

# fluidcast's checked reader (the plugin's "fluidcast particle reader"): every damaged file
# is a VTK error naming the problem, the forged header included.
for name, path in damaged:
    before = len(messages.GetOutput())
    show(fluidcastparticlereader(FileName=path), name + "_fluidcast_reader", {})
    text = messages.GetOutput()[before:]
    refused = "vtkFluidCastReader" in text and name + ".vtu" in text
    say(f"{name} through the fluidcast reader: {'VTK error' if refused else 'read'}")
    if name != "no_points" and not refused:
        failures.append(f"{name}: the fluidcast reader reported no error")

# And it reads a good file as ParaView's own reader does.
sample = os.path.join(os.path.dirname(__file__), "..", "..", "examples", "data",
                      "sample_column.vtu")
ours = fetch(fluidcastparticlereader(FileName=sample))
theirs = fetch(OpenDataFile(sample))
if ours.GetNumberOfPoints() != theirs.GetNumberOfPoints():
    failures.append(f"sample: {ours.GetNumberOfPoints()} points vs ParaView's "
                    f"{theirs.GetNumberOfPoints()}")
for i in range(theirs.GetPointData().GetNumberOfArrays()):
    a = theirs.GetPointData().GetArray(i)
    b = ours.GetPointData().GetArray(a.GetName())
    if b is None or b.GetNumberOfComponents() != a.GetNumberOfComponents():
        failures.append(f"sample: array {a.GetName()} missing or of another shape")
        continue
    diff = max(abs(a.GetComponent(t, c) - b.GetComponent(t, c))
               for t in range(a.GetNumberOfTuples()) for c in range(a.GetNumberOfComponents()))
    if diff != 0:
        failures.append(f"sample: array {a.GetName()} differs by {diff}")
say(f"sample through the fluidcast reader: {ours.GetNumberOfPoints()} points, "
    f"{ours.GetPointData().GetNumberOfArrays()} arrays, as ParaView's reader")

say(f"survived {len(in_memory)} in-memory cases and {len(damaged)} damaged files")
vtkOutputWindow.SetInstance(original_window)
if failures:
    say("FAIL:\n  " + "\n  ".join(failures))
    sys.exit(1)
say("PASS")
