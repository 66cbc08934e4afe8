"""The Python module on the Rust library (issue 48): ``fluidcast.read``, ``fluidcast.render``
and ``fluidcast.interpolate`` without VTK, held against the ``fluidcast`` CLI (a separate
program) on shared frames: the same image within 1/255, the same field values within 1e-6.
"""
import csv
import json
import shutil
import subprocess
import sys
from pathlib import Path

import fluidcast
import numpy as np
import pytest
from fluidcast import api
from fluidcast.images import read_png
from shared_data import DDB, shared

PYSPH = "pysph_dambreak3d/dam_break_3d_fluid_01180.vtu"


def cli(*args):
    exe = shutil.which("fluidcast", path=str(Path(sys.executable).parent))
    assert exe, "the fluidcast CLI is not installed beside this Python"
    r = subprocess.run([exe, *map(str, args)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return r


def test_read_gives_the_files_points_and_arrays():
    p = fluidcast.read(shared(DDB))
    assert p.points.shape == (p.n_points, 3) and p.n_points > 1000
    assert p["velocity"].shape == (p.n_points, 3)
    assert np.isfinite(p.points).all()


def test_a_series_step_is_its_file():
    pvd = shared("splash_doubledambreak/DoubleDamBreak_r0.0125.pvd")
    series = fluidcast.read(pvd, step=3)
    assert len(series.times) == 10 and series.time == series.times[3]
    (time, files), = [s for s in api._core.series(str(pvd)) if s[0] == series.time]
    alone = fluidcast.read(files[0])
    np.testing.assert_array_equal(series.points, alone.points)
    with pytest.raises(ValueError, match="time step 10, but it has 10"):
        fluidcast.read(pvd, step=10)


@pytest.mark.parametrize("tolerance", ["0.004", "off"])
def test_render_equals_the_cli(tmp_path, tolerance):
    """The default camera, colour map and range are the CLI's: the same PNG within 1/255."""
    data = shared(DDB)
    err = 0.0 if tolerance == "off" else float(tolerance)
    img = fluidcast.render(data, "velocity", size=(240, 180), error_tolerance=err,
                           backend="cpu")
    img.save(tmp_path / "module.png")
    cli("render", data, "--array", "velocity", "--size", "240x180", "--backend", "cpu",
        "--error-tolerance", tolerance, "-o", tmp_path / "cli.png")
    a, b = read_png(tmp_path / "module.png"), read_png(tmp_path / "cli.png")
    assert (a != 255).any(axis=2).mean() > 0.03, "the frame must cover part of the image"
    assert np.abs(a.astype(int) - b.astype(int)).max() <= 1
    assert img.rgba.shape == (180, 240, 4) and img.rgba.dtype == np.float32
    assert np.isfinite(img.depth).any() and np.isinf(img.depth).any()


def test_numpy_arrays_render_as_their_file(tmp_path):
    """Arrays straight from a simulation (no file) render as the file they came from, with
    an explicit camera and a matplotlib colour map."""
    p = fluidcast.read(shared(DDB))
    cam = dict(position=(2.0, 1.0, 4.0), focal_point=(0.8, 0.3, 0.3), view_up=(0, 1, 0),
               view_angle=30.0)
    a = fluidcast.render(p.points.astype(np.float32), np.linalg.norm(p["velocity"], axis=1),
                         camera=cam, size=(160, 120), cmap="plasma", opacity="sigmoid",
                         support_radius=float(p.field_data["support_radius"][0]),
                         settings={}, backend="cpu")
    b = fluidcast.render(p, "velocity", camera=cam, size=(160, 120), cmap="plasma",
                         opacity="sigmoid", backend="cpu")
    assert a.stats["particles"] == b.stats["particles"] == p.n_points
    # Without mass/density arrays the volumes differ (uniform), so the images differ a little;
    # the colours come from the same map and the coverage is the same.
    assert np.abs(a.rgba[..., 3] - b.rgba[..., 3]).max() < 0.5
    assert ((a.rgba[..., 3] > 0.01) == (b.rgba[..., 3] > 0.01)).mean() > 0.95


def test_interpolate_equals_probe(tmp_path):
    data = shared(DDB)
    p = fluidcast.read(data)
    rng = np.random.default_rng(7)
    lo, hi = p.points.min(0), p.points.max(0)
    # Near particles (most in the fluid) and anywhere in the box (some outside it).
    near = p.points[rng.choice(p.n_points, 200)] + rng.normal(scale=0.01, size=(200, 3))
    pts = np.concatenate([near, lo + rng.random((100, 3)) * (hi - lo)])
    csv_in = tmp_path / "points.csv"
    csv_in.write_text("x,y,z\n" + "\n".join(",".join(repr(float(v)) for v in q) for q in pts))
    cli("probe", data, "--points", csv_in, "--array", "velocity:0", "-o", tmp_path / "out.csv")
    rows = list(csv.DictReader((tmp_path / "out.csv").open()))
    want = np.array([float(r["value"]) if r["value"] else np.nan for r in rows])
    shepard = np.array([float(r["shepard"]) for r in rows])
    got = fluidcast.interpolate(p, pts, "velocity", component=0)
    assert 150 < np.isfinite(want).sum() < 300, "points in the fluid and outside it"
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=0)
    np.testing.assert_allclose(fluidcast.interpolate(p, pts, field="colour"), shepard,
                               rtol=1e-6, atol=0)


def test_depth_limit_stops_the_rays():
    p = fluidcast.read(shared(DDB))
    full = fluidcast.render(p, "velocity", size=(80, 60), backend="cpu")
    near = np.nanmin(np.where(np.isfinite(full.depth), full.depth, np.nan))
    cut = fluidcast.render(p, "velocity", size=(80, 60), backend="cpu",
                           depth_limit=np.full((60, 80), near * 0.5, np.float32))
    assert full.rgba[..., 3].max() > 0.5 and cut.rgba[..., 3].max() == 0.0


def test_float32_points_are_passed_as_they_are():
    pts = np.zeros((10, 3), np.float32)
    assert api._floats(pts, "points") is pts
    assert api._floats(pts.astype(np.float64), "points").dtype == np.float64
    assert api._floats(np.zeros((10, 3), np.int32), "points").dtype == np.float64


def _cube(n=8):
    g = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3)
    return g.astype(np.float32) * 0.1


@pytest.mark.parametrize("bad, match", [
    (dict(radius_array="h", arrays={"h": np.full(512, np.nan)}), r"radius .*nan|NaN"),
    (dict(scalars=np.ones(7)), r"scalars: 7 values for 512 particles"),
    (dict(scalars="missing"), r"no point array 'missing'"),
    (dict(points=np.zeros((0, 3), np.float32)), r"the particles are empty"),
    (dict(arrays={"v": np.ones(5)}, scalars="v"), r"'v' has 5 values, expected 512 points"),
    (dict(support_radius=float("nan")), r"support_radius"),
])
def test_bad_input_raises_value_error_naming_it(bad, match):
    bad = dict(bad)
    points = bad.pop("points", _cube())
    arrays = bad.pop("arrays", {})
    p = api.Particles(points, arrays)
    if "support_radius" not in bad and "radius_array" not in bad:
        bad["support_radius"] = 0.2
    with pytest.raises(ValueError, match=match):
        fluidcast.render(p, bad.pop("scalars", None), size=(20, 15), **bad)


def test_a_pysph_frame_with_its_own_radii_renders(tmp_path):
    data = shared(PYSPH)
    img = fluidcast.render(data, "p", radius_array="h", radius_scale=2.0, size=(120, 90),
                           backend="cpu")
    img.save(tmp_path / "p.png")
    cli("render", data, "--array", "p", "--radius-array", "h", "--radius-scale", "2",
        "--size", "120x90", "--backend", "cpu", "-o", tmp_path / "c.png")
    a, b = read_png(tmp_path / "p.png"), read_png(tmp_path / "c.png")
    assert np.abs(a.astype(int) - b.astype(int)).max() <= 1
    json.dumps(img.stats)  # plain Python values


def test_the_numpy_example_draws_its_figure(tmp_path):
    """examples/numpy_arrays.py: arrays (no file) to a matplotlib figure with a colour bar."""
    import runpy

    example = Path(__file__).resolve().parents[2] / "examples" / "numpy_arrays.py"
    img = runpy.run_path(str(example))["main"](str(tmp_path / "figure.png"))
    assert (tmp_path / "figure.png").stat().st_size > 10_000
    assert img.stats["particles"] == 16000 and img.rgba[..., 3].max() > 0.9


@pytest.mark.parametrize("field", ["colour", "p"])
def test_iso_surfaces_equal_the_cli(tmp_path, field):
    """Iso-surfaces of the colour field and of another point array (its values handed to the
    renderer from the numpy arrays) are the CLI's --iso within 1/255."""
    data = shared(PYSPH)
    value = 0.5 if field == "colour" else 1000.0
    img = fluidcast.render(data, "velocity", radius_array="h", radius_scale=2.0,
                           size=(120, 90), isosurfaces=[value], isosurface_field=field,
                           backend="cpu")
    img.save(tmp_path / "m.png")
    cli("render", data, "--array", "velocity", "--radius-array", "h", "--radius-scale", "2",
        "--iso", value, "--iso-field", field, "--size", "120x90", "--backend", "cpu",
        "-o", tmp_path / "c.png")
    a, b = read_png(tmp_path / "m.png"), read_png(tmp_path / "c.png")
    assert (a != 255).any(axis=2).mean() > 0.05
    assert np.abs(a.astype(int) - b.astype(int)).max() <= 1


@pytest.mark.parametrize("extra, options", [
    (["--field", "rbf", "--spp", "2"], dict(field="rbf", spp=2)),
    (["--shadows", "--spp", "2"], dict(shadows=True, spp=2)),
])
def test_rbf_and_shadows_equal_the_cli(tmp_path, extra, options):
    """The stochastic march (the RBF field, an SPH field with shadows) is the CLI's: the same
    seed and passes give the same image within 1/255."""
    data = Path(__file__).resolve().parents[2] / "examples" / "data" / "sample_column.vtu"
    img = fluidcast.render(data, "velocity", size=(100, 75), backend="cpu", **options)
    img.save(tmp_path / "m.png")
    cli("render", data, "--array", "velocity", "--size", "100x75", "--backend", "cpu", *extra,
        "-o", tmp_path / "c.png")
    a, b = read_png(tmp_path / "m.png"), read_png(tmp_path / "c.png")
    assert (a != 255).any(axis=2).mean() > 0.05
    assert np.abs(a.astype(int) - b.astype(int)).max() <= 1
