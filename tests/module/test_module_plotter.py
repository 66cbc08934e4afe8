"""fluidcast.add_particles in a pyvista Plotter on any VTK (issue 48). In .venv-pip (PyPI's
VTK, no mapper) the particles are rendered by the Python module and composited into the
plotter; in .venv-paraview both routes run and must agree. The oracle is the `fluidcast
render` CLI given the plotter's camera and transfer function, and VTK's own rendering of an
opaque box for the depth composition.
"""
import json
import shutil
import subprocess
import sys
from pathlib import Path

import fluidcast
import numpy as np
import pytest
import pyvista as pv
from fluidcast.camera import save_camera
from fluidcast.images import read_png
from fluidcast.plotting import MAPPER_ERROR, transfer_functions
from fluidcast.transfer import tf_to_preset
from shared_data import DDB, shared

SIZE = (240, 180)
ROUTES = ["module"] + ([] if MAPPER_ERROR else ["mapper"])


def cli(*args):
    exe = shutil.which("fluidcast", path=str(Path(sys.executable).parent))
    r = subprocess.run([exe, *map(str, args)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def plotter():
    p = pv.Plotter(off_screen=True, window_size=list(SIZE))
    p.set_background("white")
    p.disable_anti_aliasing()
    return p


def add(p, mesh, route, **kw):
    return fluidcast.add_particles(p, mesh, "velocity", cmap="viridis", opacity="linear",
                                   error_tolerance=0.0, show_scalar_bar=False, route=route,
                                   clim=(0.0, 3.0), opacity_unit_distance=0.05, **kw)


def cli_image(p, data, tmp_path, tag):
    """`fluidcast render` with the plotter's camera and add()'s transfer function."""
    camera = save_camera(p.camera, tmp_path / f"{tag}_camera.json")
    lut = pv.LookupTable(cmap="viridis", n_values=256)
    lut.apply_opacity("linear")
    ctf, otf = transfer_functions(lut, (0.0, 3.0))
    tf = tmp_path / f"{tag}_tf.json"
    tf.write_text(json.dumps([tf_to_preset(ctf, otf)]))
    out = tmp_path / f"{tag}.png"
    cli("render", data, "--array", "velocity:mag", "--tf", tf, "--range", "0,3",
        "--camera", camera, "--size", f"{SIZE[0]}x{SIZE[1]}", "--opacity-unit-distance",
        "0.05", "--background", "1,1,1", "--error-tolerance", "off", "-o", out)
    return read_png(out)


def diff(a, b, where=None):
    d = np.abs(a.astype(int) - b.astype(int)).max(axis=2)
    return int(d[where].max() if where is not None else d.max())


@pytest.fixture(scope="module")
def ddb():
    path = shared(DDB)
    return path, fluidcast.read(path)


@pytest.mark.parametrize("route", ROUTES)
def test_views_equal_the_cli_after_a_camera_change(ddb, tmp_path, route):
    path, particles = ddb
    p = plotter()
    add(p, particles, route)
    p.view_isometric()
    first = p.screenshot(return_img=True)
    assert (first != 255).any(axis=2).mean() > 0.1, "the particles must be in view"
    assert diff(first, cli_image(p, path, tmp_path, "a")) <= 2
    p.camera.azimuth = 60.0
    p.camera.zoom(1.4)
    p.render()  # pyvista's screenshot does not render a camera change by itself
    second = p.screenshot(return_img=True)
    assert diff(second, first) > 20, "the new camera must show another image"
    assert diff(second, cli_image(p, path, tmp_path, "b")) <= 2


@pytest.mark.parametrize("route", ROUTES)
def test_an_opaque_box_hides_and_is_hidden_by_depth(ddb, tmp_path, route):
    """A box cutting through the particles: where it is in front it shows its own colour,
    unchanged; where it lies behind the particles they cover it (the pixels there differ
    from the box alone and equal the particles alone within 2/255 where the particles are
    opaque); everywhere the image is the CLI's over the box."""
    _, particles = ddb
    lo, hi = particles.points.min(0), particles.points.max(0)
    mid = (lo + hi) / 2
    box = pv.Box(bounds=(lo[0], hi[0], lo[1], hi[1], mid[2] - 0.02, mid[2] + 0.02))
    views = {}
    for what in ("box", "both", "particles"):
        p = plotter()
        if what != "particles":
            p.add_mesh(box, color="red", lighting=False)
        if what != "box":
            add(p, particles, route)
        p.camera_position = [(mid[0], mid[1], hi[2] + 3.0), tuple(mid), (0, 1, 0)]
        p.reset_camera_clipping_range()
        views[what] = p.screenshot(return_img=True).astype(int)
    red = np.all(views["box"] == (255, 0, 0), axis=2)
    empty = np.all(views["particles"] == 255, axis=2)
    # In front of the particles' back half: the box where no particle lies before it.
    assert red.mean() > 0.2 and (red & empty).any()
    assert diff(views["both"], views["box"], red & empty) == 0
    # The particles in front of the box cover it.
    covered = red & ~empty
    assert covered.mean() > 0.05
    assert (np.abs(views["both"] - views["box"]).max(axis=2)[covered] > 10).mean() > 0.5


def test_the_routes_agree(ddb):
    """Where the mapper is built both routes give the same image; elsewhere asking for the
    mapper says why there is none."""
    _, particles = ddb
    if MAPPER_ERROR:
        with pytest.raises(ValueError, match="route 'mapper': .*not available"):
            add(plotter(), particles, "mapper")
        return
    shots = []
    for route in ("mapper", "module"):
        p = plotter()
        add(p, particles, route)
        p.view_xy()
        shots.append(p.screenshot(return_img=True))
    assert diff(*shots) <= 2


def test_the_module_route_is_what_pips_vtk_gets():
    """Where the mapper is not built (pip's VTK), add_particles renders through the module."""
    import vtkmodules

    p = plotter()
    added = fluidcast.add_particles(p, pv.PolyData(np.random.default_rng(1).random((500, 3))),
                                    np.ones(500), support_radius=0.2, show_scalar_bar=False)
    kind = type(added).__name__
    assert kind == ("ParticlesOverlay" if MAPPER_ERROR else "Volume"), vtkmodules.__version__
