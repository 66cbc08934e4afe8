#!/usr/bin/env python3
"""Writes small VTK files in every encoding VTK and ParaView produce, with VTK itself.

Used two ways:
  * `python tests/make_fixtures.py OUTDIR` writes the whole matrix (the pytest oracle test
    writes into a temp dir and compares fluidcast's reader with VTK's on each file);
  * the committed fixtures under tests/fixtures/ were written by this script
    (`python tests/make_fixtures.py tests/fixtures --committed`), so Rust tests can run
    without Python.

Every file holds the same particles: a 8 x 8 x 4 lattice (256 points) with a Float32 vector
`velocity`, Float64 `density`, Int32 `id`, UInt8 `flag`, Int64 `big`, UInt64 `ubig`, and
field data `TIME` and `support_radius`.
"""
import os
import sys

import numpy as np
import vtk
from vtk.util import numpy_support as ns


def lattice(nx, ny, nz, spacing=0.01):
    g = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"), -1)
    return (g.reshape(-1, 3) * spacing).astype(np.float32)


def add_array(data, name, values, vtk_type=None):
    arr = ns.numpy_to_vtk(np.ascontiguousarray(values), deep=True, array_type=vtk_type)
    arr.SetName(name)
    data.AddArray(arr)


def make_polydata(pts, with_verts=True, arrays=True):
    poly = vtk.vtkPolyData()
    p = vtk.vtkPoints()
    p.SetData(ns.numpy_to_vtk(pts, deep=True))
    poly.SetPoints(p)
    if with_verts:
        verts = vtk.vtkCellArray()
        for i in range(len(pts)):
            verts.InsertNextCell(1)
            verts.InsertCellPoint(i)
        poly.SetVerts(verts)
    if arrays:
        n = len(pts)
        rng = np.random.default_rng(2)
        add_array(poly.GetPointData(), "velocity", rng.normal(size=(n, 3)).astype(np.float32))
        add_array(poly.GetPointData(), "density", 1000.0 + rng.normal(size=n))
        add_array(poly.GetPointData(), "id", np.arange(n, dtype=np.int32))
        add_array(poly.GetPointData(), "flag", (np.arange(n) % 2).astype(np.uint8))
        add_array(poly.GetPointData(), "big", np.arange(n, dtype=np.int64) - 100)
        add_array(poly.GetPointData(), "ubig", np.arange(n, dtype=np.uint64) * 3)
        add_array(poly.GetFieldData(), "TIME", np.array([0.25]))
        add_array(poly.GetFieldData(), "support_radius", np.array([0.03]))
    return poly


def to_ugrid(poly):
    f = vtk.vtkAppendFilter()
    f.AddInputData(poly)
    f.Update()
    ug = f.GetOutput()
    ug.GetFieldData().ShallowCopy(poly.GetFieldData())
    return ug


COMPRESSORS = {
    "none": None,
    "zlib": vtk.vtkZLibDataCompressor,
    "lz4": vtk.vtkLZ4DataCompressor,
    "lzma": vtk.vtkLZMADataCompressor,
}


def write_xml(data, path, mode, compressor="none", header=64, block_size=None):
    w = vtk.vtkXMLPolyDataWriter() if path.endswith(".vtp") else vtk.vtkXMLUnstructuredGridWriter()
    w.SetFileName(path)
    w.SetInputData(data)
    if mode == "ascii":
        w.SetDataModeToAscii()
    elif mode == "binary":
        w.SetDataModeToBinary()
    else:
        w.SetDataModeToAppended()
        w.SetEncodeAppendedData(mode == "appended-base64")
    if header == 64:
        w.SetHeaderTypeToUInt64()
    else:
        w.SetHeaderTypeToUInt32()
    if COMPRESSORS[compressor] is None:
        w.SetCompressorTypeToNone()
    else:
        w.SetCompressor(COMPRESSORS[compressor]())
    if block_size:
        w.SetBlockSize(block_size)
    assert w.Write() == 1, path


def write_legacy(data, path, binary, version):
    poly = isinstance(data, vtk.vtkPolyData)
    w = vtk.vtkPolyDataWriter() if poly else vtk.vtkUnstructuredGridWriter()
    w.SetFileName(path)
    w.SetInputData(data)
    if binary:
        w.SetFileTypeToBinary()
    else:
        w.SetFileTypeToASCII()
    w.SetFileVersion(42 if version == "4.2" else 51)
    assert w.Write() == 1, path


def write_v01_separate_base64(pts, path):
    """VTK XML version 0.1 as pyvisfile writes it: appended base64, UInt32 headers,
    header and data base64-encoded (and padded) separately, Int64 cells, Float64 data."""
    import base64

    n = len(pts)
    pts = pts.astype(np.float64)
    rho = 1000.0 + np.arange(n, dtype=np.float64)
    chunks = []

    def enc(arr):
        raw = np.ascontiguousarray(arr).tobytes()
        return base64.b64encode(np.uint32(len(raw)).tobytes()) + base64.b64encode(raw)

    arrays = [("points", "Float64", 3, pts), ("rho", "Float64", 1, rho),
              ("connectivity", "Int64", 1, np.arange(n, dtype=np.int64)),
              ("offsets", "Int64", 1, np.arange(1, n + 1, dtype=np.int64)),
              ("types", "UInt8", 1, np.ones(n, dtype=np.uint8))]
    offsets = {}
    pos = 0
    for name, _, _, arr in arrays:
        offsets[name] = pos
        c = enc(arr)
        chunks.append(c)
        pos += len(c)
    def da(name, t, nc):
        return (f'<DataArray type="{t}" Name="{name}" NumberOfComponents="{nc}" '
                f'format="appended" offset="{offsets[name]}"/>')
    xml = f"""<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">
<UnstructuredGrid>
<Piece NumberOfPoints="{n}" NumberOfCells="{n}">
<Points>
{da("points", "Float64", 3)}
</Points>
<Cells>
{da("connectivity", "Int64", 1)}
{da("offsets", "Int64", 1)}
{da("types", "UInt8", 1)}
</Cells>
<PointData>
{da("rho", "Float64", 1)}
</PointData>
</Piece>
</UnstructuredGrid>
<AppendedData encoding="base64">
_""".encode() + b"".join(chunks) + b"\n</AppendedData>\n</VTKFile>\n"
    with open(path, "wb") as f:
        f.write(xml)


def write_all(out, committed):
    os.makedirs(out, exist_ok=True)
    pts = lattice(8, 8, 4)
    poly = make_polydata(pts)
    ug = to_ugrid(poly)
    written = []
    modes = ["ascii", "binary", "appended-base64", "appended-raw"]
    for ext, data in ((".vtu", ug), (".vtp", poly)):
        for mode in modes:
            for comp in (["none"] if mode == "ascii" else list(COMPRESSORS)):
                for header in (32, 64):
                    if committed and header == 32 and comp not in ("none", "zlib"):
                        continue
                    name = f"lattice_{mode}_{comp}_h{header}{ext}"
                    write_xml(data, os.path.join(out, name), mode, comp, header)
                    written.append(name)
    for version in ("4.2", "5.1"):
        for binary in (False, True):
            name = f"lattice_legacy{version.replace('.', '')}_{'binary' if binary else 'ascii'}.vtk"
            write_legacy(ug, os.path.join(out, name), binary, version)
            written.append(name)
    # vtkio fault: zlib array whose byte size is an exact multiple of the 32 KiB block size,
    # so VTK writes a last-block size of 0 (8192 Float32 xyz = 98304 bytes = 3 blocks).
    big = make_polydata(lattice(32, 16, 16), with_verts=False, arrays=False)
    add_array(big.GetPointData(), "z", lattice(32, 16, 16)[:, 2].copy())
    write_xml(to_ugrid(big), os.path.join(out, "fault_zlib_full_last_block.vtu"), "appended-raw",
              "zlib")
    # vtkio fault: multi-block lzma arrays above ~30 KB.
    write_xml(to_ugrid(big), os.path.join(out, "fault_lzma_multiblock.vtu"), "appended-raw", "lzma")
    # vtkio fault: compressed .vtp with empty Lines/Strips/Polys (zero compressed blocks).
    write_xml(poly, os.path.join(out, "fault_compressed_polydata.vtp"), "appended-raw", "zlib")
    # Old XML version 0.1 with separately padded base64 header and data (pyvisfile).
    write_v01_separate_base64(pts, os.path.join(out, "pyvisfile_v01_base64.vtu"))
    written += ["fault_zlib_full_last_block.vtu", "fault_lzma_multiblock.vtu",
                "fault_compressed_polydata.vtp", "pyvisfile_v01_base64.vtu"]
    # A .pvd collection over two of them.
    with open(os.path.join(out, "series.pvd"), "w") as f:
        f.write('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n<Collection>\n'
                '<DataSet timestep="0.5" group="" part="0" '
                'file="lattice_appended-raw_zlib_h64.vtu"/>\n'
                '<DataSet timestep="0" group="" part="0" file="lattice_ascii_none_h64.vtu"/>\n'
                '</Collection>\n</VTKFile>\n')
    written.append("series.pvd")
    # A parallel summary over two of them (as an MPI run writes one piece per rank).
    with open(os.path.join(out, "pieces.pvtu"), "w") as f:
        f.write('<?xml version="1.0"?>\n<VTKFile type="PUnstructuredGrid" version="0.1" '
                'byte_order="LittleEndian">\n<PUnstructuredGrid GhostLevel="0">\n'
                '<PPointData/>\n<PPoints><PDataArray type="Float32" NumberOfComponents="3"/>'
                '</PPoints>\n<Piece Source="lattice_ascii_none_h64.vtu"/>\n'
                '<Piece Source="lattice_binary_zlib_h64.vtu"/>\n'
                '</PUnstructuredGrid>\n</VTKFile>\n')
    written.append("pieces.pvtu")
    return written


if __name__ == "__main__":
    out = sys.argv[1]
    names = write_all(out, "--committed" in sys.argv)
    print(f"wrote {len(names)} files to {out}")
