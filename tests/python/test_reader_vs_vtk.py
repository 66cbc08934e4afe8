"""fluidcast's reader gives the same points and arrays as VTK's own readers.

Bounds and array ranges (read in double precision) must be identical to VTK's.

fluidcast has no Python binding yet, so values come through the CLI: `probe` with a tiny
support radius and an array evaluates the CSPH field *at the particles themselves*, which
returns each particle's own value exactly (only it contributes). Counts, ranges and array
lists come from `info --json`.
"""

import make_fixtures  # tests/make_fixtures.py (pyproject.toml puts tests/ on pytest's path)
import numpy as np
import pytest
import vtk
from conftest import SHARED, fluidcast, info_json, render_png, shared
from vtk.util import numpy_support as ns
from vtk.util.vtkAlgorithm import VTKPythonAlgorithmBase


def vtk_read(path):
    path = str(path)
    ext = path.rsplit(".", 1)[-1]
    r = {"vtu": vtk.vtkXMLUnstructuredGridReader, "vtp": vtk.vtkXMLPolyDataReader,
         "pvtu": vtk.vtkXMLPUnstructuredGridReader, "pvtp": vtk.vtkXMLPPolyDataReader}.get(ext)
    if r is None:
        r = vtk.vtkDataSetReader
    reader = r()
    reader.SetFileName(path)
    if ext == "vtk":
        reader.ReadAllScalarsOn()
        reader.ReadAllVectorsOn()
        reader.ReadAllFieldsOn()
    reader.Update()
    return reader.GetOutput()


def files_to_check():
    out = sorted(SHARED.glob("*/*.vtu")) + sorted(SHARED.glob("*/*.vtp"))
    return out


def compare_file(path, tmp_path):
    ds = vtk_read(path)
    pts = ns.vtk_to_numpy(ds.GetPoints().GetData()).astype(np.float64)
    info = info_json(path)
    assert info["points"] == len(pts)
    np.testing.assert_allclose(info["bounds"]["min"], pts.min(0), rtol=0, atol=0)
    np.testing.assert_allclose(info["bounds"]["max"], pts.max(0), rtol=0, atol=0)
    pd = ds.GetPointData()
    vtk_arrays = {pd.GetArrayName(i): ns.vtk_to_numpy(pd.GetArray(i))
                  for i in range(pd.GetNumberOfArrays())}
    ours = {a["name"]: a for a in info["point_data"]}
    assert set(ours) == set(vtk_arrays), (set(ours), set(vtk_arrays))
    for name, arr in vtk_arrays.items():
        a = arr.astype(np.float64)
        lo, hi = ours[name]["range"]
        assert (lo, hi) == (a.min(), a.max()), name
        assert ours[name]["components"] == (1 if a.ndim == 1 else a.shape[1]), name
    # Per-particle values: probe at the particles with a support far below the spacing.
    pick = np.linspace(0, len(pts) - 1, min(len(pts), 400)).astype(int)
    csv = tmp_path / "pts.csv"
    np.savetxt(csv, pts[pick], delimiter=",", fmt="%.17g")
    for name, arr in vtk_arrays.items():
        a = arr.astype(np.float64).reshape(len(pts), -1)
        for k in range(a.shape[1]):
            sel = f"{name}:{k}" if a.shape[1] > 1 else name
            out = tmp_path / "v.csv"
            fluidcast("probe", path, "--points", csv, "-o", out, "--array", sel,
                      "--support-radius", "1e-6", "--uniform-volume")
            got = np.genfromtxt(out, delimiter=",", skip_header=1)[:, 3]
            # Particles hold single precision (the renderer's layout): exact for Float32 and
            # integer arrays below 2^24, within f32 rounding for Float64.
            np.testing.assert_allclose(got, a[pick, k], rtol=1e-6, atol=0,
                                       err_msg=f"{path.name}: {sel}")


@pytest.mark.parametrize("path", files_to_check(), ids=lambda p: p.name)
def test_shared_files_match_vtk(path, tmp_path):
    compare_file(path, tmp_path)


def test_every_encoding_matches_vtk(tmp_path):
    """The whole matrix of encodings VTK writes (incl. lz4/lzma with UInt32 headers)."""
    d = tmp_path / "fx"
    names = make_fixtures.write_all(str(d), committed=False)
    n = 0
    for name in names:
        if name.endswith((".vtu", ".vtp")) and not name.startswith("pyvisfile"):
            compare_file(d / name, tmp_path)
            n += 1
    assert n >= 50


def legacy_with_attributes(pts):
    """PolyData whose point data are *active attributes*, which VTK's legacy writer stores
    as SCALARS (with LOOKUP_TABLE), VECTORS, NORMALS, TENSORS, TEXTURE_COORDINATES and
    GLOBAL_IDS sections rather than FIELD arrays (how many SPH codes write legacy files)."""
    poly = make_fixtures.make_polydata(pts, arrays=False)
    n = len(pts)
    rng = np.random.default_rng(5)
    pd = poly.GetPointData()

    def arr(name, values, vtk_type=None):
        a = ns.numpy_to_vtk(np.ascontiguousarray(values), deep=True, array_type=vtk_type)
        a.SetName(name)
        return a

    pd.SetScalars(arr("pressure", rng.normal(size=n)))
    pd.SetVectors(arr("velocity", rng.normal(size=(n, 3)).astype(np.float32)))
    nrm = rng.normal(size=(n, 3))
    pd.SetNormals(arr("normal", (nrm / np.linalg.norm(nrm, axis=1)[:, None]).astype(np.float32)))
    pd.SetTensors(arr("stress", rng.normal(size=(n, 9))))
    pd.SetTCoords(arr("uv", rng.random(size=(n, 2)).astype(np.float32)))
    pd.SetGlobalIds(arr("gid", np.arange(n, dtype=np.int64) + 7))
    pd.AddArray(arr("phase", (np.arange(n) % 3).astype(np.int32)))
    return poly


def test_legacy_files_match_vtk(tmp_path):
    """Legacy .vtk 4.2 and 5.1, ASCII and BINARY, UNSTRUCTURED_GRID with FIELD arrays and
    POLYDATA with active attribute sections: fluidcast's own legacy parser against VTK's."""
    pts = make_fixtures.lattice(6, 5, 4)
    datasets = {
        "ugrid": make_fixtures.to_ugrid(make_fixtures.make_polydata(pts)),
        "attrs": legacy_with_attributes(pts),
    }
    n = 0
    for kind, data in datasets.items():
        for version in ("4.2", "5.1"):
            for binary in (False, True):
                path = tmp_path / f"{kind}_{version}_{'bin' if binary else 'ascii'}.vtk"
                make_fixtures.write_legacy(data, str(path), binary, version)
                compare_file(path, tmp_path)
                n += 1
    assert n == 8


class Slabs(VTKPythonAlgorithmBase):
    """Serves VTK's pipeline piece k of n as an MPI code's rank k would hold it: the points
    whose x lies in the k-th of n equal slabs, in their original order, with all arrays."""

    def __init__(self, data):
        super().__init__(nInputPorts=0, nOutputPorts=1, outputType=data.GetClassName())
        self.data = data

    def RequestInformation(self, request, in_info, out_info):
        out_info.GetInformationObject(0).Set(vtk.vtkAlgorithm.CAN_HANDLE_PIECE_REQUEST(), 1)
        return 1

    def RequestData(self, request, in_info, out_info):
        info = out_info.GetInformationObject(0)
        sddp = vtk.vtkStreamingDemandDrivenPipeline
        k, n = info.Get(sddp.UPDATE_PIECE_NUMBER()), info.Get(sddp.UPDATE_NUMBER_OF_PIECES())
        x = ns.vtk_to_numpy(self.data.GetPoints().GetData())[:, 0]
        edges = np.linspace(x.min(), x.max(), n + 1)
        edges[-1] = np.inf
        ids = vtk.vtkIdList()
        for i in np.nonzero((x >= edges[k]) & (x < edges[k + 1]))[0]:
            ids.InsertNextId(int(i))
        out = self.data.NewInstance()
        pts = vtk.vtkPoints()
        pts.SetDataType(self.data.GetPoints().GetDataType())
        self.data.GetPoints().GetPoints(ids, pts)
        out.SetPoints(pts)
        out.GetPointData().CopyAllocate(self.data.GetPointData(), ids.GetNumberOfIds())
        for j in range(ids.GetNumberOfIds()):
            out.GetPointData().CopyData(self.data.GetPointData(), ids.GetId(j), j)
        out.GetFieldData().ShallowCopy(self.data.GetFieldData())
        vtk.vtkDataObject.GetData(out_info).ShallowCopy(out)
        return 1


def write_parallel(path, pieces, out):
    """The particles of ``path`` as VTK's parallel writer stores ``pieces`` slabs of them."""
    data = vtk_read(path)
    poly = data.IsA("vtkPolyData")
    w = vtk.vtkXMLPPolyDataWriter() if poly else vtk.vtkXMLPUnstructuredGridWriter()
    src = Slabs(data)
    w.SetInputConnection(src.GetOutputPort())
    w.SetFileName(str(out.with_suffix(".pvtp" if poly else ".pvtu")))
    w.SetNumberOfPieces(pieces)
    w.SetStartPiece(0)
    w.SetEndPiece(pieces - 1)
    assert w.Write() == 1
    return out.with_suffix(".pvtp" if poly else ".pvtu")


@pytest.mark.parametrize("rel,pieces", [
    ("splash_doubledambreak/DoubleDamBreak_r0.0125_0011.vtu", 3),
    ("pysph_dambreak3d/dam_break_3d_fluid_01180_zlib.vtp", 4),
])
def test_parallel_files_match_vtk(rel, pieces, tmp_path):
    """A .pvtu / .pvtp that VTK's parallel writer made of a real file, in slabs as MPI ranks
    write them: fluidcast reads the same points and arrays as VTK's parallel reader, and
    renders the same image as from the original single file."""
    path = shared(rel)
    par = write_parallel(path, pieces, tmp_path / "slabs")
    assert len(list(tmp_path.glob("slabs_*.vt?"))) == pieces
    assert info_json(par)["points"] == vtk_read(path).GetNumberOfPoints()
    compare_file(par, tmp_path)
    images = []
    for src in (path, par):
        images.append(render_png(src, "velocity:mag", size=(160, 120)).astype(int))
    # The particles come in another order (slab by slab), so sums may round differently.
    diff = np.abs(images[0] - images[1]).max(axis=2)
    assert diff.max() <= 1 and (diff > 0).mean() < 0.01, (diff.max(), (diff > 0).mean())
    drawn = (images[0] != images[0][0, 0]).any(axis=2).mean()
    assert drawn > 0.02, f"the render drew only {drawn:.1%} of the image"
