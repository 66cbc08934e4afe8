"""pvbatch test: loading the plugin leaves ParaView's own readers in charge of users' files.

    pvbatch pvbatch_readers.py PLUGIN.so SHARED_DATA OUTDIR

1. Writes meshes with VTK: a tetrahedral .vtu (vtkDelaunay3D of 200 points, with point and
   cell data), a polygonal .vtp (vtkSphereSource), a legacy structured grid .vtk, a .pvd of
   two tetrahedral meshes, a .pvd whose parts are particles and a mesh, and a .pvtu of two
   tetrahedral pieces.
2. Opens each, and the particle files (shared SPlisHSPlasH and PySPH data, the shipped
   sample, VTK-written .vtp and legacy fixtures), with OpenDataFile before the plugin is
   loaded, and records what ParaView reads: the reader, the data type, the points, the cells
   (and of a .pvd, at each time) and the point and cell arrays.
3. Loads the plugin, checks that ParaView's reader factory now knows the fluidcast reader
   (else the rest would pass without it), and opens every file again: each must give the
   same record. ParaView's readers stay the default, for meshes and particles alike.
4. The fluidcast reader itself (the factory asked for that reader by name) declines every
   mesh and takes every particle file, and the readers the GUI's File > Open weighs are
   ParaView's alone for a mesh (no question asked) and ParaView's, then the fluidcast
   reader, for a particle file (the GUI asks which).
5. Chosen by name for a mesh, it reads nothing and says why, naming the file and its cells.
6. The particle files render with the fluidcast representation, through ParaView's reader
   (OpenDataFile) and through the fluidcast reader chosen by name, to the same image.
7. The fluidcast reader, chosen by name, steps through a .pvd series reading ahead.

Exit code 0 pass, 1 fail.
"""
import faulthandler
import json
import os
import sys

faulthandler.enable(file=sys.__stderr__)

import numpy as np
from paraview.simple import (
    ColorBy,
    CreateView,
    Delete,
    GetAnimationScene,
    GetOpacityTransferFunction,
    Hide,
    LoadPlugin,
    OpenDataFile,
    Render,
    SaveScreenshot,
    Show,
    servermanager,
)
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkOutputWindow, vtkPoints, vtkStringOutputWindow
from vtkmodules.vtkCommonDataModel import vtkPolyData, vtkStructuredGrid
from vtkmodules.vtkFiltersCore import vtkDelaunay3D
from vtkmodules.vtkFiltersSources import vtkSphereSource
from vtkmodules.vtkIOImage import vtkPNGReader
from vtkmodules.vtkIOLegacy import vtkStructuredGridWriter
from vtkmodules.vtkIOParallelXML import vtkXMLPUnstructuredGridWriter
from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter, vtkXMLUnstructuredGridWriter

plugin, shared, out = sys.argv[1:4]
os.makedirs(out, exist_ok=True)
root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
# The fluidcast reader's proxy (paraview/Representation/fluidcast_reader.xml).
READER = ("sources", "fluidcastParticleReader")


def say(text):
    """Progress on the real stderr: pvbatch's captured stdout is lost if the process dies."""
    sys.__stderr__.write(text + "\n")
    sys.__stderr__.flush()


def array(values, name):
    a = numpy_to_vtk(np.ascontiguousarray(values), deep=True)
    a.SetName(name)
    return a


def tetra_mesh(path, seed):
    rng = np.random.default_rng(seed)
    cloud = vtkPolyData()
    pts = vtkPoints()
    pts.SetData(numpy_to_vtk(rng.random((200, 3)), deep=True))
    cloud.SetPoints(pts)
    cloud.GetPointData().AddArray(array(rng.random(200), "temperature"))
    d = vtkDelaunay3D()
    d.SetInputData(cloud)
    d.Update()
    mesh = d.GetOutput()
    mesh.GetCellData().AddArray(array(np.arange(mesh.GetNumberOfCells(), dtype=np.int32),
                                      "element_id"))
    write(vtkXMLUnstructuredGridWriter(), mesh, path)
    return mesh


def write(writer, data, path):
    writer.SetInputData(data)
    writer.SetFileName(path)
    assert writer.Write() == 1, path


def structured_grid(path):
    g = vtkStructuredGrid()
    g.SetDimensions(5, 4, 3)
    xyz = np.stack(np.meshgrid(np.arange(5), np.arange(4), np.arange(3), indexing="ij"), -1)
    pts = vtkPoints()
    pts.SetData(numpy_to_vtk(xyz.transpose(2, 1, 0, 3).reshape(-1, 3).astype(float), deep=True))
    g.SetPoints(pts)
    g.GetPointData().AddArray(array(np.arange(60, dtype=float), "height"))
    write(vtkStructuredGridWriter(), g, path)


def pvd(path, entries):
    rows = "".join(f'<DataSet timestep="{t}" part="{p}" file="{f}"/>\n' for t, p, f in entries)
    with open(path, "w") as f:
        f.write('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
                f"<Collection>\n{rows}</Collection>\n</VTKFile>\n")


def write_meshes():
    """The meshes of the issue (and two more), written by VTK; returns {name: path}."""
    m = {name: os.path.join(out, name) for name in (
        "tetra.vtu", "tetra_later.vtu", "sphere.vtp", "structured.vtk", "meshes.pvd",
        "particles_and_mesh.pvd", "tetra.pvtu")}
    mesh = tetra_mesh(m["tetra.vtu"], 1)
    tetra_mesh(m["tetra_later.vtu"], 2)
    sphere = vtkSphereSource()
    sphere.Update()
    write(vtkXMLPolyDataWriter(), sphere.GetOutput(), m["sphere.vtp"])
    structured_grid(m["structured.vtk"])
    pvd(m["meshes.pvd"], [(0, 0, "tetra.vtu"), (1, 0, "tetra_later.vtu")])
    # A particle file beside a mesh (fluid and a wall), as one time of a .pvd.
    ddb = os.path.join(shared, "splash_doubledambreak", "DoubleDamBreak_r0.0125_0011.vtu")
    pvd(m["particles_and_mesh.pvd"], [(0, 0, os.path.abspath(ddb)), (0, 1, "sphere.vtp")])
    w = vtkXMLPUnstructuredGridWriter()
    w.SetNumberOfPieces(2)
    w.SetStartPiece(0)
    w.SetEndPiece(1)
    write(w, mesh, m["tetra.pvtu"])
    return m


meshes = write_meshes()
particles = {
    "ddb.vtu": os.path.join(shared, "splash_doubledambreak", "DoubleDamBreak_r0.0125_0011.vtu"),
    "ddb.vtp": os.path.join(shared, "splash_doubledambreak", "DoubleDamBreak_r0.0125_0011.vtp"),
    "ddb.pvd": os.path.join(shared, "splash_doubledambreak", "DoubleDamBreak_r0.0125.pvd"),
    "pysph.vtu": os.path.join(shared, "pysph_dambreak3d", "dam_break_3d_fluid_01180.vtu"),
    "pysph.pvd": os.path.join(shared, "pysph_dambreak3d", "dam_break_3d_fluid.pvd"),
    "sample.vtu": os.path.join(root, "examples", "data", "sample_column.vtu"),
    "lattice.vtp": os.path.join(root, "tests", "fixtures", "lattice_appended-raw_zlib_h64.vtp"),
    "lattice_legacy.vtk": os.path.join(root, "tests", "fixtures", "lattice_legacy51_binary.vtk"),
}
for name, path in particles.items():
    if not os.path.isfile(path):
        say(f"FAIL: {name}: {path} is missing (../shared/data laid beside the clone?)")
        sys.exit(1)
files = {**meshes, **particles}


def record(source):
    """What ParaView read: reader, data type, points, cells and arrays (at each time)."""
    times = list(getattr(source, "TimestepValues", None) or [None])
    at = []
    for t in times:
        source.UpdatePipeline(t)
        info = source.GetDataInformation()
        at.append({"time": t, "type": info.GetDataClassName(),
                   "points": info.GetNumberOfPoints(), "cells": info.GetNumberOfCells(),
                   "point_arrays": sorted(source.PointData.keys()),
                   "cell_arrays": sorted(source.CellData.keys())})
    return {"reader": source.GetXMLName(), "steps": at}


def open_all():
    got = {}
    for name, path in files.items():
        source = OpenDataFile(path)
        got[name] = record(source)
        Delete(source)
    return got


factory = servermanager.vtkSMProxyManager.GetProxyManager().GetReaderFactory()
session = servermanager.ActiveConnection.Session
before = open_all()
for name in meshes:
    say(f"without the plugin: {name}: {json.dumps(before[name])}")

LoadPlugin(plugin, remote=False, ns=globals())
failures = []
known = factory.GetPossibleReaders("", session)
listed = [known.GetString(i) for i in range(1, known.GetLength(), 3)]
if READER[1] not in listed:
    failures.append(f"the reader factory does not know {READER[1]} after LoadPlugin: this "
                    "test would pass without it")

# 3. The same data, reader and all, with the plugin loaded.
after = open_all()
for name in files:
    if after[name] != before[name]:
        failures.append(f"{name}: OpenDataFile gives {json.dumps(after[name])} with the plugin, "
                        f"{json.dumps(before[name])} without")
    else:
        say(f"with the plugin: {name}: as without ({after[name]['reader']}, "
            f"{after[name]['steps'][0]['type']}, {after[name]['steps'][0]['cells']} cells)")

# 4. Which files the fluidcast reader claims, and the readers the GUI's File > Open weighs
# (vtkSMReaderFactory::GetReaders: with more than one it asks "Open Data With...").
for name, path in files.items():
    claims = factory.CanReadFile(path, READER[0], READER[1], session)
    expected = name in particles
    readers = factory.GetReaders(path, session)
    offered = [readers.GetString(i) for i in range(1, readers.GetLength(), 3)]
    say(f"fluidcast reader {'takes' if claims else 'declines'} {name}; File > Open weighs "
        f"{offered}")
    if bool(claims) != expected:
        failures.append(f"{name}: the fluidcast reader {'takes' if claims else 'declines'} it")
    if name.endswith(".pvtu"):
        continue  # the fluidcast reader takes no .pvtu by extension
    paraview_first = offered[:1] == [before[name]["reader"]]
    if not paraview_first or (READER[1] in offered) != expected:
        failures.append(f"{name}: File > Open weighs {offered} (expected ParaView's reader "
                        f"first{', then ' + READER[1] if expected else ' alone'})")

# 5. Chosen by name for a mesh: nothing read, an error naming the file and its cells.
original_window = vtkOutputWindow.GetInstance()
messages = vtkStringOutputWindow()
vtkOutputWindow.SetInstance(messages)
for name in ("tetra.vtu", "sphere.vtp", "structured.vtk", "meshes.pvd"):
    start = len(messages.GetOutput())
    source = fluidcastparticlereader(FileName=meshes[name])
    source.UpdatePipeline()
    cells = source.GetDataInformation().GetNumberOfCells()
    text = messages.GetOutput()[start:]
    file = "structured.vtk" if name == "structured.vtk" else name.replace("meshes.pvd", "tetra.vtu")
    why = "not particle data" if name == "structured.vtk" else "not vertices"
    say(f"fluidcast reader chosen for {name}: {cells} cells; says: "
        f"{text.strip().splitlines()[-1] if text.strip() else '(nothing)'}")
    if cells != 0 or file not in text or why not in text:
        failures.append(f"{name}: the fluidcast reader chosen by name read {cells} cells and "
                        f"said {text!r} (expected no cells and an error naming {file}: {why})")
    Delete(source)
vtkOutputWindow.SetInstance(original_window)

# 6. Particle files render with the fluidcast representation, through either reader.
view = CreateView("RenderView")
view.ViewSize = [160, 120]
view.OrientationAxesVisibility = 0
view.Background = [0, 0, 0]
try:
    view.UseColorPaletteForBackground = 0
except AttributeError:
    pass


def screenshot(source, name):
    display = Show(source, view)
    display.SetRepresentationType("fluidcast")
    array_name = "velocity" if "velocity" in source.PointData.keys() else source.PointData.keys()[0]
    ColorBy(display, ("POINTS", array_name, "Magnitude"))
    display.ScalarOpacityFunction = GetOpacityTransferFunction(array_name)
    display.RescaleTransferFunctionToDataRange(False, True)
    view.ResetCamera()
    Render(view)
    path = os.path.join(out, name + ".png")
    SaveScreenshot(path, view, ImageResolution=[160, 120])
    Hide(source, view)
    r = vtkPNGReader()
    r.SetFileName(path)
    r.Update()
    img = vtk_to_numpy(r.GetOutput().GetPointData().GetScalars()).astype(int)
    return img


for name in ("ddb.vtu", "ddb.vtp", "pysph.vtu", "lattice_legacy.vtk"):
    theirs = OpenDataFile(particles[name])
    ours = fluidcastparticlereader(FileName=particles[name])
    a, b = screenshot(theirs, name + "_paraview_reader"), screenshot(ours, name + "_fluidcast")
    lit = int((a[:, :3].max(axis=1) > 8).sum())
    diff = int(np.abs(a - b).max())
    say(f"{name}: fluidcast representation, {lit} of {len(a)} pixels lit through "
        f"{theirs.GetXMLName()}; largest difference to the fluidcast reader's {diff}/255")
    if lit < len(a) // 50:
        failures.append(f"{name}: the fluidcast representation drew {lit} pixels")
    if diff > 2:
        failures.append(f"{name}: the image through ParaView's reader and the fluidcast "
                        f"reader's differ by {diff}/255")
    Delete(theirs)
    Delete(ours)

# 7. The fluidcast reader chosen by name reads a series ahead.
series = fluidcastparticlereader(FileName=particles["ddb.pvd"], Prefetch=1)
display = Show(series, view)
display.SetRepresentationType("fluidcast")
ColorBy(display, ("POINTS", "velocity", "Magnitude"))
scene = GetAnimationScene()
scene.UpdateAnimationUsingDataTimeSteps()
steps = list(series.TimestepValues)
for t in steps[:4]:
    scene.AnimationTime = t
    Render(view)
series.UpdatePropertyInformation()
prefetched = series.GetProperty("PrefetchedSteps").GetData()
say(f"ddb.pvd through the fluidcast reader: {len(steps)} steps, {prefetched} of the first 4 "
    "shown came read ahead")
if len(steps) < 4 or prefetched < 2:
    failures.append(f"ddb.pvd: {prefetched} steps read ahead of {min(4, len(steps))} shown")

if failures:
    say("FAIL:\n  " + "\n  ".join(failures))
    sys.exit(1)
say("PASS")
