"""The large-scene generator (python -m fluidcast.upsample): K³ children per particle that
keep the frame's mass, volume and flow, in a file VTK and fluidcast both read."""
import json

import numpy as np
import pytest
from conftest import fluidcast, shared
from fluidcast.data import read_points, write_particles
from fluidcast.images import difference, read_png
from fluidcast.upsample import main as upsample
from shared_data import DDB
from vtkmodules.util import numpy_support as ns

CAMERA = {"position": [1.6, 1.5, 5.5], "focal_point": [0.0, 0.5, 0.0], "view_up": [0, 1, 0],
          "view_angle": 30}


def arrays(ds):
    pd = ds.GetPointData()
    return {pd.GetArrayName(i): ns.vtk_to_numpy(pd.GetArray(i))
            for i in range(pd.GetNumberOfArrays())}


@pytest.mark.parametrize("ext", ["vtu", "vtp"])
def test_children_keep_mass_volume_and_their_parents_cells(tmp_path, ext):
    src = shared(DDB)
    out = tmp_path / f"k3.{ext}"
    assert upsample([str(src), str(out), "--factor", "3"]) == 0
    a, b = read_points(src), read_points(out)
    n = a.GetNumberOfPoints()
    assert b.GetNumberOfPoints() == 27 * n
    pa, pb = arrays(a), arrays(b)
    assert set(pa) == set(pb)
    for name in ("mass", "volume"):
        assert np.isclose(pb[name].astype(np.float64).sum(), pa[name].astype(np.float64).sum(),
                          rtol=1e-5)
    for name in ("velocity", "object_id", "density"):
        assert np.array_equal(pb[name], np.repeat(pa[name], 27, axis=0))
    # Each child lies in its parent's cell (spacing V^(1/3)), the 27 spread over it.
    xa = ns.vtk_to_numpy(a.GetPoints().GetData()).astype(np.float64)
    xb = ns.vtk_to_numpy(b.GetPoints().GetData()).astype(np.float64).reshape(n, 27, 3)
    s = np.cbrt(pa["volume"].astype(np.float64))[:, None, None]
    off = (xb - xa[:, None, :]) / s
    assert np.abs(off).max() <= 0.5 + 1e-5
    assert off.std(axis=1).min() > 0.2
    # SPlisHSPlasH's field data follow the children's size; fluidcast reads it.
    info = json.loads(fluidcast("info", out, "--json").stdout)
    assert info["points"] == 27 * n
    field = {a["name"]: a["values"][0] for a in info["field_data"]}
    assert field["support_radius"] == pytest.approx(0.05 / 3)
    assert field["particle_radius"] == pytest.approx(0.0125 / 3)
    assert b.GetNumberOfCells() == 27 * n


def test_the_upsampled_flow_looks_like_the_frame(tmp_path):
    """Rendered from one camera, the 8x finer frame is much closer to the frame than the same
    flow 0.45 s earlier is."""
    cam = tmp_path / "cam.json"
    cam.write_text(json.dumps(CAMERA))
    frame, early = shared(DDB), shared(DDB.replace("_0011", "_0002"))
    fine = tmp_path / "k2.vtu"
    assert upsample([str(frame), str(fine), "--factor", "2"]) == 0
    images = {}
    for name, f in [("frame", frame), ("fine", fine), ("early", early)]:
        png = tmp_path / f"{name}.png"
        fluidcast("render", f, "-o", png, "--array", "velocity", "--size", "256x192",
                  "--camera", cam, "--range", "0,4", "--opacity-unit-distance", "0.1")
        images[name] = read_png(png)
    near = difference(images["frame"], images["fine"])["rmse"]
    far = difference(images["frame"], images["early"])["rmse"]
    assert near < 0.1 and far > 2.5 * near, (near, far)


def test_bad_input_is_a_clear_error(tmp_path, capsys):
    src = shared(DDB)
    assert upsample([str(src), str(tmp_path / "x.vtu"), "--factor", "0"]) == 2
    assert "--factor must be at least 1" in capsys.readouterr().err
    assert upsample([str(src), str(tmp_path / "x.csv"), "--factor", "2"]) == 2
    assert "write a .vtu or .vtp" in capsys.readouterr().err
    lattice = tmp_path / "bare.vtp"
    write_particles(lattice, np.random.default_rng(1).random((50, 3)))
    assert upsample([str(lattice), str(tmp_path / "y.vtu"), "--factor", "2"]) == 2
    assert "give --spacing" in capsys.readouterr().err
    assert upsample([str(lattice), str(tmp_path / "y.vtu"), "--factor", "2",
                     "--spacing", "0.1"]) == 0
