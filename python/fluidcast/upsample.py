"""Large test scenes from a real SPH frame: each particle becomes k³ smaller ones.

``python -m fluidcast.upsample IN OUT --factor K`` replaces every particle of ``IN`` by K³
children on a jittered K×K×K sub-lattice of the particle's own spacing, so a 42k-particle
frame becomes 9.1M particles at K = 6 and 14.5M at K = 7. The children keep the flow's
structure (free surface, splashes, phases) at K times the resolution, which is what a finer
simulation of the same flow would look like at a glance; they are not a simulation.

Conserved: every point array is copied to the children except

* extensive arrays (``--extensive``, default those named mass, m, volume, V), divided by K³,
  so the total mass and volume stay those of the frame;
* length arrays (``--length``, default h, radius, smoothing_length), divided by K;
* field data ``particle_radius`` and ``support_radius`` (SPlisHSPlasH's), divided by K.

The parent's spacing is V^(1/3) from its volume array when it has one, else twice the
field data's ``particle_radius``, else ``--spacing``. The output is VTK XML (``.vtu`` or
``.vtp``) written by VTK itself, appended raw binary, zlib compressed unless ``--raw``, with
one vertex cell per particle, so ParaView and pyvista read it as they read the codes' files.
Nothing here is specific to one code: give ``--extensive``/``--length`` for other names.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import vtk
from vtkmodules.util import numpy_support as ns

from .data import read_points, vertex_cells

EXTENSIVE = ("mass", "m", "volume", "V")
LENGTH = ("h", "radius", "smoothing_length")
FIELD_LENGTHS = ("particle_radius", "support_radius")


def parent_spacing(ds, extensive: tuple[str, ...], spacing: float | None) -> np.ndarray:
    """Per-parent spacing in world units: V^(1/3), 2 × particle_radius, or ``spacing``."""
    n = ds.GetNumberOfPoints()
    pd = ds.GetPointData()
    for name in ("volume", "V"):
        if name in extensive and pd.GetArray(name) is not None:
            v = ns.vtk_to_numpy(pd.GetArray(name)).astype(np.float64)
            if v.ndim == 1 and np.all(np.isfinite(v)) and np.all(v > 0):
                return np.cbrt(v)
    fd = ds.GetFieldData().GetArray("particle_radius")
    if fd is not None and fd.GetNumberOfTuples() > 0 and fd.GetTuple1(0) > 0:
        return np.full(n, 2.0 * fd.GetTuple1(0))
    if spacing is not None:
        return np.full(n, spacing)
    raise ValueError("the particles' spacing is unknown: the file has no positive volume "
                     "array and no particle_radius field data; give --spacing")


def child_offsets(k: int) -> np.ndarray:
    """(k³, 3) offsets of a K×K×K sub-lattice centred on the parent, in units of its spacing."""
    c = (np.arange(k) + 0.5) / k - 0.5
    g = np.stack(np.meshgrid(c, c, c, indexing="ij"), axis=-1)
    return g.reshape(-1, 3)


def upsample(ds, k: int, jitter: float, seed: int, extensive: tuple[str, ...],
             length: tuple[str, ...], spacing: float | None) -> vtk.vtkPolyData:
    """The upsampled particles as vtkPolyData with one vertex per particle."""
    if k < 1:
        raise ValueError(f"--factor must be at least 1, not {k}")
    if not 0.0 <= jitter < 0.5:
        raise ValueError(f"--jitter must lie in [0, 0.5), not {jitter}")
    n = ds.GetNumberOfPoints()
    k3 = k ** 3
    s = parent_spacing(ds, extensive, spacing)
    parents = ns.vtk_to_numpy(ds.GetPoints().GetData()).astype(np.float64)
    rng = np.random.default_rng(seed)
    off = child_offsets(k)
    pts = np.empty((n * k3, 3), dtype=np.float32)
    chunk = max(1, 2_000_000 // k3)
    for a in range(0, n, chunk):
        b = min(n, a + chunk)
        o = off[None, :, :] + rng.uniform(-jitter, jitter, (b - a, k3, 3)) / k
        pts[a * k3:b * k3] = (parents[a:b, None, :] + o * s[a:b, None, None]).reshape(-1, 3)
    poly = vtk.vtkPolyData()
    points = vtk.vtkPoints()
    points.SetData(ns.numpy_to_vtk(pts, deep=True))
    del pts
    poly.SetPoints(points)
    pd = ds.GetPointData()
    for i in range(pd.GetNumberOfArrays()):
        src = pd.GetAbstractArray(i)
        if not isinstance(src, vtk.vtkDataArray) or src.GetName() is None:
            continue
        a = np.repeat(ns.vtk_to_numpy(src), k3, axis=0)
        if src.GetName() in extensive:
            a = (a / k3).astype(a.dtype, copy=False)
        elif src.GetName() in length:
            a = (a / k).astype(a.dtype, copy=False)
        out = ns.numpy_to_vtk(np.ascontiguousarray(a), deep=True, array_type=src.GetDataType())
        out.SetName(src.GetName())
        poly.GetPointData().AddArray(out)
    poly.SetVerts(vertex_cells(n * k3))
    poly.SetFieldData(scaled_field_data(ds.GetFieldData(), k))
    return poly


def scaled_field_data(fd: vtk.vtkFieldData, k: int) -> vtk.vtkFieldData:
    """The frame's field data with SPlisHSPlasH's particle and support radius divided by K."""
    out = vtk.vtkFieldData()
    out.DeepCopy(fd)
    for name in FIELD_LENGTHS:
        a = out.GetArray(name)
        if a is not None:
            for t in range(a.GetNumberOfTuples()):
                a.SetTuple1(t, a.GetTuple1(t) / k)
    return out


def write(poly: vtk.vtkPolyData, path: Path, compress: bool) -> None:
    """Writes .vtp as it is or .vtu as an unstructured grid of vertex cells."""
    if path.suffix == ".vtp":
        w = vtk.vtkXMLPolyDataWriter()
        data = poly
    elif path.suffix == ".vtu":
        w = vtk.vtkXMLUnstructuredGridWriter()
        data = vtk.vtkUnstructuredGrid()
        data.SetPoints(poly.GetPoints())
        data.GetPointData().ShallowCopy(poly.GetPointData())
        data.SetFieldData(poly.GetFieldData())
        data.SetCells(vtk.VTK_VERTEX, poly.GetVerts())
    else:
        raise ValueError(f"{path}: write a .vtu or .vtp file")
    w.SetFileName(str(path))
    w.SetInputData(data)
    w.SetDataModeToAppended()
    w.EncodeAppendedDataOff()
    w.SetHeaderTypeToUInt64()
    if compress:
        w.SetCompressorTypeToZLib()
    else:
        w.SetCompressorTypeToNone()
    if w.Write() != 1:
        raise OSError(f"{path}: VTK could not write the file")


def names(text: str) -> tuple[str, ...]:
    return tuple(t for t in text.split(",") if t)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m fluidcast.upsample", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("input", type=Path, help="a .vtu/.vtp/.vtk frame")
    p.add_argument("output", type=Path, help="the .vtu or .vtp to write")
    p.add_argument("--factor", type=int, required=True,
                   help="K: children per parent along each axis (K³ in all)")
    p.add_argument("--jitter", type=float, default=0.25,
                   help="random shift of each child, in child spacings (default 0.25)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--extensive", type=names, default=EXTENSIVE,
                   help="comma-separated arrays divided by K³ (default mass,m,volume,V)")
    p.add_argument("--length", type=names, default=LENGTH,
                   help="comma-separated arrays divided by K (default h,radius,smoothing_length)")
    p.add_argument("--spacing", type=float, help="parent spacing (m) when the file has none")
    p.add_argument("--raw", action="store_true", help="write uncompressed appended data")
    a = p.parse_args(argv)
    t0 = time.perf_counter()
    try:
        ds = read_points(a.input)
        print(f"{a.input}: {ds.GetNumberOfPoints():,} particles; writing "
              f"{ds.GetNumberOfPoints() * a.factor ** 3:,}", file=sys.stderr)
        poly = upsample(ds, a.factor, a.jitter, a.seed, a.extensive, a.length, a.spacing)
        del ds
        write(poly, a.output, not a.raw)
    except (ValueError, OSError) as e:
        print(f"fluidcast.upsample: {e}", file=sys.stderr)
        return 2
    mib = a.output.stat().st_size / 2**20
    print(f"{a.output}: {poly.GetNumberOfPoints():,} particles, {mib:,.0f} MiB, "
          f"{time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
