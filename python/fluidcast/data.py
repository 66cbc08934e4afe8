"""Particle data through VTK's own readers and writers: files, point arrays, the volume and
support-radius conventions fluidcast follows."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import vtk
from vtkmodules.util import numpy_support as ns

from .cli import run_fluidcast


def read_points(path: Path) -> vtk.vtkPointSet:
    """Reads a .vtu/.vtp/.vtk particle file with VTK's own readers."""
    path = Path(path)
    readers = {".vtu": vtk.vtkXMLUnstructuredGridReader, ".vtp": vtk.vtkXMLPolyDataReader,
               ".vtk": vtk.vtkDataSetReader}
    cls = readers.get(path.suffix.lower())
    if cls is None:
        raise ValueError(f"{path}: not a .vtu, .vtp or .vtk file")
    r = cls()
    r.SetFileName(str(path))
    r.Update()
    ds = r.GetOutput()
    if ds is None or ds.GetNumberOfPoints() == 0:
        raise ValueError(f"{path}: VTK's reader found no points (empty, truncated or not a "
                         f"{path.suffix} file)")
    return ds


def vertex_cells(count: int) -> vtk.vtkCellArray:
    """One vertex cell per point, 32-bit ids where they fit (half the size on disk)."""
    cells = vtk.vtkCellArray()
    if count < 2**31 - 1:
        cells.ConvertTo32BitStorage()
        kind = np.int32
    else:
        kind = np.int64
    ids = np.arange(count + 1, dtype=kind)
    cells.SetData(ns.numpy_to_vtk(ids, deep=True), ns.numpy_to_vtk(ids[:-1], deep=True))
    return cells


def write_particles(path: Path, points: np.ndarray, **arrays: np.ndarray) -> Path:
    """Writes particles (N, 3) with named point arrays as a VTK XML PolyData file (.vtp),
    one vertex cell per particle, as SPH codes write them."""
    pts = vtk.vtkPoints()
    pts.SetData(ns.numpy_to_vtk(np.ascontiguousarray(points, dtype=np.float64), deep=True))
    poly = vtk.vtkPolyData()
    poly.SetPoints(pts)
    poly.SetVerts(vertex_cells(len(points)))
    for name, a in arrays.items():
        arr = ns.numpy_to_vtk(np.ascontiguousarray(a), deep=True)
        arr.SetName(name)
        poly.GetPointData().AddArray(arr)
    w = vtk.vtkXMLPolyDataWriter()
    w.SetFileName(str(path))
    w.SetInputData(poly)
    if not w.Write():
        raise OSError(f"{path}: VTK could not write it")
    return Path(path)


def point_array(ds: vtk.vtkPointSet, spec: str) -> np.ndarray:
    """The per-particle scalar fluidcast renders for ``--array spec``: ``NAME`` (a vector
    gives its magnitude, ParaView's default), ``NAME:mag`` or ``NAME:K`` (component K)."""
    name, _, sel = spec.partition(":")
    arr = ds.GetPointData().GetArray(name)
    if arr is None:
        raise KeyError(f"no point array '{name}'")
    a = ns.vtk_to_numpy(arr).astype(np.float64)
    if a.ndim == 1:
        if sel not in ("", "mag", "0"):
            raise KeyError(f"'{name}' has one component")
        return np.abs(a) if sel == "mag" else a
    if sel in ("", "mag"):
        return np.linalg.norm(a, axis=1)
    return a[:, int(sel)]


def volume_arrays(ds: vtk.vtkPointSet) -> tuple[str | None, str | None]:
    """The mass and density arrays fluidcast picks by default (``mass``/``m``,
    ``density``/``rho``), or (None, None) for uniform volumes."""
    pd = ds.GetPointData()
    mass = next((n for n in ("mass", "m") if pd.GetArray(n) is not None), None)
    dens = next((n for n in ("density", "rho") if pd.GetArray(n) is not None), None)
    return (mass, dens) if mass and dens else (None, None)


def support_radius(ds: vtk.vtkPointSet, path: Path, binary: Path | None = None) -> float:
    """The file's ``support_radius`` field data (SPlisHSPlasH writes it) or fluidcast's
    suggestion (``fluidcast info --json``, run with ``binary`` or the one
    ``fluidcast.cli.fluidcast_binary`` finds)."""
    fd = ds.GetFieldData().GetArray("support_radius")
    if fd is not None:
        return float(fd.GetTuple1(0))
    info = json.loads(run_fluidcast("info", path, "--json", binary=binary).stdout)
    return float(info["suggested_support_radius"])
