"""VTK transfer functions carry over to fluidcast.

A vtkColorTransferFunction + vtkPiecewiseFunction is exported to a ParaView preset
(``fluidcast_vtk.tf_to_preset``) and fluidcast renders with it. The oracle is VTK's own
evaluation of the functions (``GetColor``/``GetValue``): a block of particles that all
carry the value v, rendered fully opaque, shows exactly the colour at v (CSPH reproduces a
constant; the first sample is opaque), and a half-transparent block of known thickness
shows the opacity at v through the closed-form slab transmittance.
"""
import json

import numpy as np
import pytest
import vtk
from conftest import fluidcast
from fluidcast.camera import save_camera, vtk_project
from fluidcast.data import write_particles
from fluidcast.images import read_png
from fluidcast.transfer import preset_to_vtk, tf_to_preset

VTK = vtk
VALUES = [0.0, 0.13, 0.5, 0.77, 1.0]
H = 0.2  # support radius; blocks are 1 apart (> 2H), so supports never overlap


def blocks(values, spacing=0.25, n=5, gap=1.0):
    """One cubic lattice block of n^3 particles per value, side by side along x."""
    g = np.arange(n) * spacing
    cube = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    pts, vals, centres = [], [], []
    width = (n - 1) * spacing
    for k, v in enumerate(values):
        x0 = k * (width + gap)
        pts.append(cube + [x0, 0, 0])
        vals.append(np.full(len(cube), v))
        centres.append([x0 + width / 2, width / 2, width / 2])
    return np.concatenate(pts), np.concatenate(vals), np.array(centres)


def diverging():
    ctf = VTK.vtkColorTransferFunction()
    ctf.SetColorSpaceToDiverging()
    ctf.AddRGBPoint(0.0, 0.230, 0.299, 0.754)
    ctf.AddRGBPoint(1.0, 0.706, 0.016, 0.150)
    return ctf


def rgb_with_midpoints():
    ctf = VTK.vtkColorTransferFunction()
    ctf.SetColorSpaceToRGB()
    ctf.AddRGBPoint(0.0, 0.1, 0.2, 0.9, 0.3, 0.0)
    ctf.AddRGBPoint(0.6, 0.9, 0.9, 0.2, 0.5, 0.0)
    ctf.AddRGBPoint(1.0, 0.8, 0.1, 0.1)
    return ctf


def plain_rgb():
    ctf = VTK.vtkColorTransferFunction()
    ctf.SetColorSpaceToRGB()
    for x, c in [(0, (0, 0, 0.5)), (0.3, (0, 0.8, 1)), (0.7, (1, 0.9, 0)), (1, (0.6, 0, 0))]:
        ctf.AddRGBPoint(x, *c)
    return ctf


def constant_opacity(a):
    otf = VTK.vtkPiecewiseFunction()
    otf.AddPoint(0.0, a)
    otf.AddPoint(1.0, a)
    return otf


def render(tmp_path, preset, values, unit, size=(500, 100)):
    pts, vals, centres = blocks(values)
    data = write_particles(tmp_path / "blocks.vtp", pts, value=vals)
    tf = tmp_path / "tf.json"
    tf.write_text(json.dumps([preset]))
    cam = VTK.vtkCamera()
    lo, hi = pts.min(0) - H, pts.max(0) + H
    mid = (lo + hi) / 2
    cam.SetFocalPoint(*mid)
    cam.SetPosition(mid[0], mid[1], mid[2] + 10)
    cam.SetViewUp(0, 1, 0)
    cam.ParallelProjectionOn()
    cam.SetParallelScale((hi[0] - lo[0]) / 2 * size[1] / size[0] * 1.05)
    camfile = save_camera(cam, tmp_path / "cam.json")
    out = tmp_path / "blocks.png"
    fluidcast("render", data, "--array", "value", "--range", "0,1", "--tf", tf,
              "--support-radius", H, "--uniform-volume", "--opacity-unit-distance", unit,
              "--camera", camfile, "--size", f"{size[0]}x{size[1]}", "--background", "0,0,0",
              "--sampling-scale", 4, "--mode", "reference", "-o", out)
    img = read_png(out).astype(np.float64) / 255
    px = vtk_project(cam, centres, *size)
    return [img[int(y), int(x)] for x, y in px]


@pytest.mark.parametrize("make_ctf", [plain_rgb, rgb_with_midpoints, diverging],
                         ids=["rgb", "rgb-midpoints", "diverging"])
def test_colour_matches_vtk(make_ctf, tmp_path):
    ctf = make_ctf()
    preset = tf_to_preset(ctf, constant_opacity(1.0))
    got = render(tmp_path, preset, VALUES, unit=1.0)
    for v, c in zip(VALUES, got):
        want = np.array(ctf.GetColor(v))
        # One 8-bit level for quantisation plus 1/255 for the sampled Diverging/midpoint
        # curves (256 samples).
        assert np.abs(c - want).max() <= 2 / 255, f"value {v}: {c} vs VTK {want}"


def test_opacity_matches_vtk_slab_transmittance(tmp_path):
    """The ray through a block's centre runs down a column of particles, so the medium it
    crosses spans the lattice plus H on each side; a constant field with opacity a per unit
    distance D gives alpha = 1 - (1 - a)^(L/D). Tolerance: the depth step (a quarter pixel
    footprint with --sampling-scale 4, 0.006 world units) at each end changes alpha by at most
    0.005, plus one 8-bit level."""
    otf = VTK.vtkPiecewiseFunction()
    otf.AddPoint(0.0, 0.05)
    otf.AddPoint(0.5, 0.3, 0.5, 0.0)
    otf.AddPoint(1.0, 0.6)
    white = VTK.vtkColorTransferFunction()
    white.AddRGBPoint(0, 1, 1, 1)
    white.AddRGBPoint(1, 1, 1, 1)
    preset = tf_to_preset(white, otf)
    unit = 1.0
    got = render(tmp_path, preset, VALUES, unit=unit)
    thickness = 4 * 0.25 + 2 * H
    for v, c in zip(VALUES, got):
        a = otf.GetValue(v)
        want = 1 - (1 - a) ** (thickness / unit)
        assert abs(c[0] - want) <= 0.01, f"value {v}: alpha {c[0]:.4f} vs {want:.4f}"


def test_preset_round_trip_exact_for_linear_rgb():
    ctf, otf = plain_rgb(), constant_opacity(0.4)
    otf.AddPoint(0.5, 0.9)
    c2, o2 = preset_to_vtk(tf_to_preset(ctf, otf))
    for x in np.linspace(-0.1, 1.1, 97):
        assert c2.GetColor(x) == pytest.approx(ctf.GetColor(x), abs=1e-12)
        assert o2.GetValue(x) == pytest.approx(otf.GetValue(x), abs=1e-12)
