#!/usr/bin/env python3
"""Writes examples/data/sample_column.vtu, the small sample the README renders.

A synthetic SPH-like particle set (not a simulation): a column of 6,000 particles on a
jittered lattice (spacing 0.02 m) with a swirling `velocity` (m/s), `density` (kg/m^3),
`mass` (kg) and field data `support_radius` = 0.04 m, saved as ParaView saves by default
(appended raw, zlib). Re-run to regenerate: .venv/bin/python examples/make_sample.py
"""
import os

import numpy as np
import vtk
from vtk.util import numpy_support as ns

rng = np.random.default_rng(42)
dx = 0.02
g = np.stack(np.meshgrid(np.arange(15), np.arange(20), np.arange(20), indexing="ij"), -1)
g = g.reshape(-1, 3)
pts = (g * dx + rng.normal(scale=0.002, size=g.shape)).astype(np.float32)
pts[:, 1] *= 1.5  # taller column
c = pts.mean(axis=0)
r = pts - c
vel = np.stack([-r[:, 2], 0.3 * r[:, 1], r[:, 0]], -1) * 6.0
vel[:, 1] -= 2.0 * (pts[:, 1] / pts[:, 1].max()) ** 2
rho = 1000.0 + 20.0 * (1.0 - pts[:, 1] / pts[:, 1].max())
mass = np.full(len(pts), 1000.0 * dx**3, dtype=np.float32)

poly = vtk.vtkPolyData()
p = vtk.vtkPoints()
p.SetData(ns.numpy_to_vtk(pts, deep=True))
poly.SetPoints(p)
for name, arr in (("velocity", vel.astype(np.float32)), ("density", rho.astype(np.float32)),
                  ("mass", mass)):
    a = ns.numpy_to_vtk(arr, deep=True)
    a.SetName(name)
    poly.GetPointData().AddArray(a)
h = ns.numpy_to_vtk(np.array([2 * dx]), deep=True)
h.SetName("support_radius")
poly.GetFieldData().AddArray(h)
verts = vtk.vtkCellArray()
for i in range(len(pts)):
    verts.InsertNextCell(1)
    verts.InsertCellPoint(i)
poly.SetVerts(verts)
app = vtk.vtkAppendFilter()
app.AddInputData(poly)
app.Update()
ug = app.GetOutput()
ug.GetFieldData().ShallowCopy(poly.GetFieldData())
out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "sample_column.vtu")
w = vtk.vtkXMLUnstructuredGridWriter()
w.SetFileName(out)
w.SetInputData(ug)
w.SetDataModeToAppended()
w.SetEncodeAppendedData(False)
w.SetCompressorTypeToZLib()
w.Write()
print("wrote", out, os.path.getsize(out), "bytes")
