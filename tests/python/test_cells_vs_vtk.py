"""fluidcast counts a file's cells and cell data as VTK's own readers do.

fluidcast keeps the points of a file; what else it holds (cells other than vertices, cell
data) is what the VTK/ParaView particle reader would drop, so it refuses such files. These
tests write meshes and particle files with VTK in every encoding VTK writes and hold
`fluidcast info --json`'s `cells` against VTK's reader: the number of cells, the cells that
are not vertices by kind, and the cell-data arrays.
"""

import make_fixtures  # tests/make_fixtures.py (pyproject.toml puts tests/ on pytest's path)
import numpy as np
import pytest
import vtk
from conftest import info_json
from test_reader_vs_vtk import vtk_read
from vtk.util import numpy_support as ns

# The VTK cell types these meshes hold, by the names fluidcast reports.
TYPE_NAMES = {vtk.VTK_TETRA: "tetra", vtk.VTK_TRIANGLE: "triangle", vtk.VTK_LINE: "line",
              vtk.VTK_QUAD: "quad", vtk.VTK_POLYGON: "polygon"}
VERTICES = (vtk.VTK_VERTEX, vtk.VTK_POLY_VERTEX)


def named(values, name):
    a = ns.numpy_to_vtk(np.ascontiguousarray(values), deep=True)
    a.SetName(name)
    return a


def tetra_mesh():
    """An unstructured grid of tetrahedra, triangles and vertices, with cell data."""
    rng = np.random.default_rng(3)
    cloud = make_fixtures.make_polydata(rng.random((60, 3)).astype(np.float32))
    d = vtk.vtkDelaunay3D()
    d.SetInputData(cloud)
    sphere = vtk.vtkSphereSource()
    append = vtk.vtkAppendFilter()
    append.AddInputConnection(d.GetOutputPort())
    append.AddInputConnection(sphere.GetOutputPort())
    append.AddInputData(cloud)  # its vertices
    append.Update()
    mesh = append.GetOutput()
    n = mesh.GetNumberOfCells()
    mesh.GetCellData().AddArray(named(np.arange(n, dtype=np.int32), "element_id"))
    mesh.GetCellData().AddArray(named(rng.random((n, 3)), "flux"))
    return mesh


def poly_mesh():
    """Poly data with polygons, lines, a strip and vertices, with cell data."""
    sphere = vtk.vtkSphereSource()
    sphere.Update()
    poly = vtk.vtkPolyData()
    poly.DeepCopy(sphere.GetOutput())
    lines = vtk.vtkCellArray()
    for i in range(5):
        lines.InsertNextCell(2, [i, i + 1])
    poly.SetLines(lines)
    strips = vtk.vtkCellArray()
    strips.InsertNextCell(4, [0, 1, 2, 3])
    poly.SetStrips(strips)
    verts = vtk.vtkCellArray()
    for i in range(7):
        verts.InsertNextCell(1, [i])
    poly.SetVerts(verts)
    n = poly.GetNumberOfCells()
    poly.GetCellData().AddArray(named(np.arange(n, dtype=np.float64), "area"))
    return poly


def vtk_cells(path):
    """(count, {kind: n} of the cells that are not vertices, cell-data names) by VTK."""
    ds = vtk_read(path)
    cd = ds.GetCellData()
    arrays = sorted(cd.GetArrayName(i) for i in range(cd.GetNumberOfArrays()))
    other = {}
    if isinstance(ds, vtk.vtkPolyData):
        for kind, n in (("lines", ds.GetNumberOfLines()), ("polygons", ds.GetNumberOfPolys()),
                        ("triangle strips", ds.GetNumberOfStrips())):
            if n:
                other[kind] = n
    else:
        for i in range(ds.GetNumberOfCells()):
            t = ds.GetCellType(i)
            if t not in VERTICES:
                other[TYPE_NAMES[t]] = other.get(TYPE_NAMES[t], 0) + 1
    return ds.GetNumberOfCells(), other, arrays


def ours(path):
    c = info_json(path)["cells"]
    return c["count"], c["not_vertices"], sorted(c["cell_data"])


def xml_cases():
    for mode in ("ascii", "binary", "appended-base64", "appended-raw"):
        for comp in (["none"] if mode == "ascii" else ["none", "zlib", "lz4"]):
            yield mode, comp


@pytest.mark.parametrize("mode,comp", list(xml_cases()))
def test_mesh_cells_match_vtk(mode, comp, tmp_path):
    for name, data in (("tetra.vtu", tetra_mesh()), ("mesh.vtp", poly_mesh())):
        path = tmp_path / name
        make_fixtures.write_xml(data, str(path), mode, comp)
        expected = vtk_cells(path)
        assert expected[1], "the mesh must hold cells that are not vertices"
        assert ours(path) == expected, (name, mode, comp)


def test_legacy_mesh_cells_match_vtk(tmp_path):
    n = 0
    for name, data in (("tetra", tetra_mesh()), ("mesh", poly_mesh())):
        for version in ("4.2", "5.1"):
            for binary in (False, True):
                path = tmp_path / f"{name}_{version}_{'bin' if binary else 'ascii'}.vtk"
                make_fixtures.write_legacy(data, str(path), binary, version)
                assert ours(path) == vtk_cells(path), path.name
                n += 1
    assert n == 8


def test_particle_files_have_vertices_only(tmp_path):
    """Vertex cells (or none) and no cell data: nothing a particle read drops."""
    names = make_fixtures.write_all(str(tmp_path), committed=True)
    checked = 0
    for name in names:
        if name.endswith((".vtu", ".vtp", ".vtk")):
            count, other, arrays = ours(tmp_path / name)
            assert (other, arrays) == ({}, []), name
            assert count == vtk_read(tmp_path / name).GetNumberOfCells(), name
            checked += 1
    assert checked >= 30
