"""fluidcast in a pyvista Plotter (issue 18): the mapper from `import fluidcast`, placed with
`fluidcast.add_particles`, renders what the CLI renders for the plotter's camera and
transfer function, composited with the plotter's other actors, and reports bad input.

The oracle is the `fluidcast render` CLI (a separate program: the Rust renderer without VTK)
given the camera and transfer function exported from the plotter, and VTK's own rendering of
the meshes for the composition (depth buffer of the outline and of the particles' box).
"""
import json

import fluidcast
import fluidcast.plotting
import numpy as np
import pytest
import pyvista as pv
from fluidcast.camera import save_camera
from fluidcast.cli import run_fluidcast
from fluidcast.images import read_png
from fluidcast.transfer import tf_to_preset
from shared_data import DDB, shared

SIZE = (320, 240)
WHITE = (255, 255, 255)
# Full rate: both renderers take the same samples; what is left is 8-bit rounding and VTK's
# 1024-entry table of the same transfer function nodes (as the C++ window test allows).
ALLOWED = 2


def plotter(off_screen=True):
    p = pv.Plotter(off_screen=off_screen, window_size=list(SIZE))
    p.set_background("white")
    return p


def add(p, mesh, **kw):
    kw = {"cmap": "viridis", "opacity": "linear", "error_tolerance": 0.0,
          "show_scalar_bar": False, **kw}
    return fluidcast.add_particles(p, mesh, "velocity", **kw)


def cli_image(p, volume, data, tmp_path, tag, *extra, size=SIZE):
    """`fluidcast render` of ``data`` with the plotter's camera and the volume's transfer
    function, opacity unit distance and tolerance, over a white background, and ``extra``
    options, at ``size`` (default: the plotter's)."""
    prop, mapper = volume.prop, volume.mapper
    camera = save_camera(p.camera, tmp_path / f"{tag}_camera.json")
    tf = tmp_path / f"{tag}_tf.json"
    ctf, otf = prop.GetRGBTransferFunction(0), prop.GetScalarOpacity(0)
    tf.write_text(json.dumps([tf_to_preset(ctf, otf)]))
    lo, hi = ctf.GetRange()
    out = tmp_path / f"{tag}_cli.png"
    run_fluidcast("render", data, "--array", "velocity:mag", "--tf", tf,
                  "--range", f"{lo!r},{hi!r}", "--camera", camera,
                  "--size", f"{size[0]}x{size[1]}",
                  "--opacity-unit-distance", repr(prop.GetScalarOpacityUnitDistance()),
                  "--background", "1,1,1", "--error-tolerance", "off"
                  if mapper.GetErrorTolerance() == 0 else repr(mapper.GetErrorTolerance()),
                  *extra, "-o", out)
    return read_png(out)


def drawn(img):
    return (img != WHITE).any(axis=2)


def grown(mask):
    """``mask`` grown by one pixel in x and y (the outline's anti-aliased fringe)."""
    m = np.pad(mask, 1)
    return m[1:-1, 1:-1] | m[:-2, 1:-1] | m[2:, 1:-1] | m[1:-1, :-2] | m[1:-1, 2:]


def max_diff(a, b, where=None):
    d = np.abs(a.astype(int) - b.astype(int)).max(axis=2)
    return int(d[where].max() if where is not None else d.max())


@pytest.fixture(scope="module")
def ddb():
    path = shared(DDB)
    return path, fluidcast.plotting.read(path)  # pyvista.PolyData


def test_plotter_with_outline_matches_cli(ddb, tmp_path):
    """Particles and an outline of their field's box in one Plotter: away from the outline
    the image is the CLI's within 2/255; where the outline is in front it shows unchanged."""
    path, mesh = ddb
    p = plotter()
    volume = add(p, mesh)
    box = pv.Box(bounds=volume.bounds)  # the field's extent: points grown by H
    outline = p.add_mesh(box.outline(), color="red", line_width=3)
    p.view_isometric()
    p.camera.zoom(1.3)
    both = p.screenshot(return_img=True)
    assert volume.mapper.GetLastError() == ""
    assert volume.mapper.GetLastParticleCount() == mesh.n_points

    # VTK alone, same plotter and camera: the outline's pixels and depth without the
    # particles, then the depth of the box's faces.
    volume.SetVisibility(False)
    p.render()
    line_img = p.screenshot(return_img=True)
    line_depth = p.get_image_depth(fill_value=np.nan)
    outline.SetVisibility(False)
    p.add_mesh(box, color="blue")
    p.render()
    face_depth = p.get_image_depth(fill_value=np.nan)
    on_line = drawn(line_img)
    near, far = p.camera.clipping_range
    tolerance = 1e-3 * (far - near)
    # On a face turned to the camera (or off the box): nothing of the field lies in front.
    in_front = on_line & (np.isnan(face_depth) | (line_depth >= face_depth - tolerance))
    behind = on_line & ~in_front

    cli = cli_image(p, volume, path, tmp_path, "outline")
    field = drawn(cli)
    assert field.sum() > SIZE[0] * SIZE[1] // 10, "the CLI drew almost nothing"
    away = ~grown(on_line)
    assert max_diff(both, cli, away) <= ALLOWED
    assert in_front.sum() > 100 and behind.sum() > 100
    assert max_diff(both, line_img, in_front) == 0, "the outline in front was covered"
    # Behind the particles the outline is covered (where the field is not nearly clear).
    dense = behind & ((255 - cli.astype(int)).max(axis=2) > 60)
    assert dense.sum() > 20
    covered = (both[dense] != line_img[dense]).any(axis=1).mean()
    assert covered > 0.9, f"only {covered:.0%} of the outline behind the particles is covered"


def test_isosurface_matches_cli(ddb, tmp_path):
    """``isosurfaces=[0.5]`` draws the free surface the CLI's ``--iso 0.5`` draws (same
    lighting coefficients, here away from their defaults), within 2/255; it is not the
    volume."""
    path, mesh = ddb
    p = plotter()
    volume = add(p, mesh, isosurfaces=[0.5], specular=0.4, specular_power=20)
    p.view_isometric()
    img = p.screenshot(return_img=True)
    assert volume.mapper.GetLastError() == ""
    cli = cli_image(p, volume, path, tmp_path, "iso", "--iso", "0.5", "--specular", "0.4",
                    "--specular-power", "20")
    assert drawn(cli).sum() > SIZE[0] * SIZE[1] // 20, "the CLI drew almost nothing"
    assert max_diff(img, cli) <= ALLOWED
    plain = cli_image(p, volume, path, tmp_path, "volume")
    assert max_diff(img, plain) > 50, "the plotter drew the volume, not the surface"


@pytest.mark.parametrize("off_screen", [True, False], ids=["offscreen", "window"])
def test_rotating_the_camera_renders_the_new_view(ddb, tmp_path, off_screen):
    """After the plotter's camera moves, the next render is the CLI's image for the new
    camera, offscreen and in a window; the scalar bar is pyvista's."""
    path, mesh = ddb
    p = plotter(off_screen)
    volume = add(p, mesh, show_scalar_bar=True, scalar_bar_args={"title": "speed (m/s)"})
    assert "speed (m/s)" in p.scalar_bars
    bar = p.scalar_bars["speed (m/s)"]
    bar.SetVisibility(False)  # off the comparison; its presence is what was checked
    p.show(auto_close=False, interactive=False)
    first = p.screenshot(return_img=True)
    assert max_diff(first, cli_image(p, volume, path, tmp_path, "first")) <= ALLOWED

    p.camera.azimuth += 60
    p.camera.elevation += 25
    p.render()
    second = p.screenshot(return_img=True)
    cli = cli_image(p, volume, path, tmp_path, "second")
    assert max_diff(second, cli) <= ALLOWED
    assert (np.abs(second.astype(int) - first.astype(int)).max(axis=2) > 20).sum() > 1000, \
        "the view did not change"


def test_mapper_properties_reach_the_image(ddb, tmp_path):
    """The mapper's properties set from Python (kernel, support radius, tolerance) are the
    ones rendered: the CLI with the same settings agrees, and the image is not the default's."""
    path, mesh = ddb
    p = plotter()
    volume = add(p, mesh)
    p.view_isometric()
    default = p.screenshot(return_img=True)
    m = volume.mapper
    h = 2.5 * m.GetLastMaxRadius()
    m.SetKernel("wendland-c2")
    m.SetSupportRadius(h)
    m.SetBackendToCPU()
    p.render()
    changed = p.screenshot(return_img=True)
    assert m.GetKernel() == "wendland-c2" and m.GetLastMaxRadius() == pytest.approx(h)
    assert m.GetLastDevice().startswith("CPU")
    assert max_diff(changed, default) > 20
    cli = cli_image(p, volume, path, tmp_path, "properties", "--kernel", "wendland-c2",
                    "--support-radius", repr(h))
    assert max_diff(changed, cli) <= ALLOWED


def with_nan_radius(mesh):
    bad = mesh.copy()
    bad["h"] = np.full(bad.n_points, 0.03)
    bad["h"][17] = np.nan
    return bad


@pytest.mark.parametrize("case, message", [
    ("missing array", "no point array 'pressure'"),
    ("NaN radius", "support radius of particle 17 is NaN"),
    ("empty mesh", "no points"),
    ("file with no such array", "no point array 'pressure'"),
])
def test_bad_input_raises_with_the_message(ddb, case, message):
    path, mesh = ddb
    p = plotter()
    with pytest.raises(ValueError, match=message):
        if case == "missing array":
            fluidcast.add_particles(p, mesh, "pressure")
        elif case == "NaN radius":
            fluidcast.add_particles(p, with_nan_radius(mesh), "velocity", radius_array="h")
        elif case == "empty mesh":
            fluidcast.add_particles(p, pv.PolyData(), "velocity")
        else:
            fluidcast.add_particles(p, path, "pressure")
    assert p.renderer.GetVolumes().GetNumberOfItems() == 0, "a failed call left a volume"


def test_damaged_file_raises_naming_it(tmp_path):
    damaged = tmp_path / "cut.vtu"
    good = shared(DDB).read_bytes()
    damaged.write_bytes(good[: len(good) // 2])
    with pytest.raises(ValueError, match="cut.vtu"):
        fluidcast.read(damaged)


def test_a_mesh_is_refused_not_stripped_to_its_points(tmp_path):
    """fluidcast.read keeps particles only: a mesh raises, naming the file and its cells,
    instead of coming back as points without its polygons."""
    mesh = tmp_path / "sphere.vtp"
    pv.Sphere().save(mesh)
    with pytest.raises(ValueError, match=r"sphere\.vtp: holds \d+ cells that are not vertices"):
        fluidcast.read(mesh)
    # The same points as particles (one vertex each) are read.
    points = pv.PolyData(pv.Sphere().points)
    points.save(tmp_path / "points.vtp")
    assert fluidcast.read(tmp_path / "points.vtp").n_points == points.n_points


def test_mapper_used_directly_reports_a_vtk_error(ddb):
    """Bad data given to the mapper itself (no helper in between) is a VTK error with the
    message at render time, nothing drawn, and the process goes on."""
    _, mesh = ddb
    p = plotter()
    volume = add(p, mesh)
    volume.mapper.SetInputData(with_nan_radius(mesh))
    volume.mapper.SetRadiusArray("h")
    messages = []
    volume.mapper.AddObserver("ErrorEvent", lambda *_: messages.append(True))
    p.render()
    img = p.screenshot(return_img=True)
    assert messages, "no VTK error"
    assert "support radius of particle 17 is NaN" in volume.mapper.GetLastError()
    assert not drawn(img).any()
    volume.mapper.SetRadiusArray(None)  # good input again renders again
    volume.mapper.SetInputData(mesh)
    p.render()
    assert drawn(p.screenshot(return_img=True)).sum() > 1000
    assert volume.mapper.GetLastError() == ""


@pytest.mark.parametrize("opacity", ["linear", "sigmoid", "geom_r", [0.0, 0.9, 0.2]])
def test_transfer_function_follows_pyvista(ddb, opacity):
    """cmap, clim and opacity mean what they mean in pyvista: the volume's functions, in data
    units, give pyvista's own lookup-table colours and opacity transfer function."""
    _, mesh = ddb
    p = plotter()
    volume = add(p, mesh, cmap="plasma", opacity=opacity, clim=[0.5, 2.5], n_colors=128)
    ctf, otf = volume.prop.GetRGBTransferFunction(0), volume.prop.GetScalarOpacity(0)
    assert ctf.GetRange() == pytest.approx((0.5, 2.5))
    want_opacity = pv.opacity_transfer_function(opacity, 128) / 255.0
    lut = pv.LookupTable(cmap="plasma", n_values=128, scalar_range=(0.5, 2.5))
    for i, x in enumerate(np.linspace(0.5, 2.5, 128)):
        assert ctf.GetColor(x) == pytest.approx(lut.map_value(x, opacity=False), abs=1 / 255)
        assert otf.GetValue(x) == pytest.approx(want_opacity[i], abs=1 / 255)
    speed = np.linalg.norm(mesh["velocity"], axis=1)
    default = add(p, mesh)
    lo, hi = default.prop.GetRGBTransferFunction(0).GetRange()
    assert (lo, hi) == pytest.approx((speed.min(), speed.max()))


def bilinear(img, w, h):
    """``img`` interpolated onto w × h pixels covering the same window (pixel centres map
    onto pixel centres, clamped at the edges): the oracle for a coarse interactive frame."""
    sh, sw = img.shape[:2]
    x = np.clip((np.arange(w) + 0.5) * sw / w - 0.5, 0, sw - 1)
    y = np.clip((np.arange(h) + 0.5) * sh / h - 0.5, 0, sh - 1)
    x0, y0 = x.astype(int), y.astype(int)
    x1, y1 = np.minimum(x0 + 1, sw - 1), np.minimum(y0 + 1, sh - 1)
    fx, fy = (x - x0)[None, :, None], (y - y0)[:, None, None]
    f = img.astype(float)
    top = f[y0][:, x0] + fx * (f[y0][:, x1] - f[y0][:, x0])
    bottom = f[y1][:, x0] + fx * (f[y1][:, x1] - f[y1][:, x0])
    return top + fy * (bottom - top)


def test_image_sample_distance_renders_the_coarse_image(ddb, tmp_path):
    """ImageSampleDistance 2 (auto adjust off): the image is the CLI's at half the size,
    interpolated bilinearly (the CLI's 8-bit rounding, interpolated, stays within 2/255)."""
    path, mesh = ddb
    p = plotter()
    volume = add(p, mesh)
    p.view_isometric()
    m = volume.mapper
    m.AutoAdjustSampleDistancesOff()
    m.SetImageSampleDistance(2)
    p.render()
    coarse = p.screenshot(return_img=True)
    assert m.GetLastImageSampleDistance() == 2
    half = cli_image(p, volume, path, tmp_path, "half", size=(SIZE[0] // 2, SIZE[1] // 2))
    want = bilinear(half, *SIZE)
    assert np.abs(coarse.astype(float) - want).max() <= ALLOWED + 0.5
    full = cli_image(p, volume, path, tmp_path, "full")
    assert max_diff(coarse, full) > 20, "a coarse image should differ from the full one"


def test_auto_adjust_fits_the_allocated_time(ddb):
    """AutoAdjustSampleDistances: a still render (VTK's default update rate) casts every
    pixel; an interactive one with a tiny time budget takes the coarsest distance allowed,
    and a budget of a few full frames takes the finest again."""
    _, mesh = ddb
    p = plotter()
    volume = add(p, mesh)
    m = volume.mapper
    m.SetMaximumImageSampleDistance(6)
    p.show(auto_close=False, interactive=False)  # the first frame: pyvista renders from here
    assert m.GetLastImageSampleDistance() == 1
    full_seconds = m.GetLastRenderMilliseconds() / 1e3
    window = p.render_window
    window.SetDesiredUpdateRate(1e6)  # a microsecond per frame: impossible
    p.render()
    assert m.GetLastImageSampleDistance() == 6
    assert drawn(p.screenshot(return_img=True)).sum() > 1000
    window.SetDesiredUpdateRate(1 / (20 * full_seconds))
    p.render()
    assert m.GetLastImageSampleDistance() == 1
