"""Transfer functions: a ``vtkColorTransferFunction`` + ``vtkPiecewiseFunction`` to a ParaView
colour-map preset (the JSON ``fluidcast render --tf`` reads) and back, rescaling, and
matplotlib colour maps."""
from __future__ import annotations

import numpy as np
import vtk


def color_at(ctf: vtk.vtkColorTransferFunction, x: float) -> list[float]:
    """RGB at ``x`` through the two-argument ``GetColor``, which every subclass wraps alike
    (ParaView's ``vtkPVDiscretizableColorTransferFunction`` has no one-argument form)."""
    rgb = [0.0, 0.0, 0.0]
    ctf.GetColor(x, rgb)
    return rgb


def tf_to_preset(ctf: vtk.vtkColorTransferFunction, otf: vtk.vtkPiecewiseFunction,
                 name: str = "from VTK", samples: int = 256) -> dict:
    """A VTK colour + opacity transfer function → one ParaView colour-map preset (the JSON
    object ParaView's preset editor exports and ``fluidcast --tf FILE`` reads).

    Nodes are copied exactly when both functions interpolate linearly in RGB (colour space
    RGB, every midpoint 0.5 and sharpness 0 — fluidcast's own model). Otherwise (Lab,
    Diverging, midpoints, sharpness) each function is sampled at its nodes plus ``samples``
    evenly spaced values, which follows the curve to well under 1/255 for 256 samples.
    """
    def nodes(f, width):
        out = []
        for i in range(f.GetSize()):
            v = [0.0] * width
            f.GetNodeValue(i, v)
            out.append(v)
        return out

    cn = nodes(ctf, 6)  # x, r, g, b, midpoint, sharpness
    on = nodes(otf, 4)  # x, y, midpoint, sharpness
    if not cn:
        raise ValueError("colour transfer function has no nodes")
    linear = (ctf.GetColorSpace() == vtk.VTK_CTF_RGB
              and all(abs(n[4] - 0.5) < 1e-12 and n[5] == 0 for n in cn)
              and all(abs(n[2] - 0.5) < 1e-12 and n[3] == 0 for n in on))
    if linear:
        rgb = [c for n in cn for c in n[:4]]
        pts = [c for n in on for c in (n[0], n[1], 0.5, 0.0)]
    else:
        lo, hi = ctf.GetRange()
        if on:
            lo, hi = min(lo, on[0][0]), max(hi, on[-1][0])
        xs = np.unique(np.r_[np.linspace(lo, hi, samples), [n[0] for n in cn],
                             [n[0] for n in on]])
        rgb = [c for x in xs for c in (x, *color_at(ctf, x))]
        pts = [c for x in xs for c in (x, otf.GetValue(x), 0.5, 0.0)]
    preset = {"Name": name, "ColorSpace": "RGB", "RGBPoints": [float(v) for v in rgb]}
    if on:
        preset["Points"] = [float(v) for v in pts]
    return preset


def preset_to_vtk(preset) -> tuple[vtk.vtkColorTransferFunction, vtk.vtkPiecewiseFunction]:
    """A ParaView preset (dict, or a list holding one) → VTK colour and opacity functions,
    interpolated in RGB as fluidcast does. Without ``Points`` the opacity is 1."""
    if isinstance(preset, list):
        preset = next(p for p in preset if "RGBPoints" in p)
    ctf = vtk.vtkColorTransferFunction()
    ctf.SetColorSpaceToRGB()
    rgb = preset["RGBPoints"]
    for i in range(0, len(rgb), 4):
        ctf.AddRGBPoint(*rgb[i:i + 4])
    otf = vtk.vtkPiecewiseFunction()
    pts = preset.get("Points")
    if pts:
        for i in range(0, len(pts), 4):
            otf.AddPoint(pts[i], pts[i + 1], pts[i + 2], pts[i + 3])
    else:
        otf.AddPoint(rgb[0], 1.0)
        otf.AddPoint(rgb[-4], 1.0)
    return ctf, otf


def rescaled(ctf, otf, lo: float, hi: float):
    """Copies of ``ctf`` and ``otf`` with their nodes moved linearly from the colour
    function's range onto [lo, hi] (ParaView's "Rescale to data range")."""
    a, b = ctf.GetRange()
    s = (hi - lo) / (b - a) if b > a else 1.0

    def x(v):
        return lo + (v - a) * s

    c = vtk.vtkColorTransferFunction()
    c.SetColorSpace(ctf.GetColorSpace())
    for i in range(ctf.GetSize()):
        n = [0.0] * 6
        ctf.GetNodeValue(i, n)
        c.AddRGBPoint(x(n[0]), *n[1:])
    o = vtk.vtkPiecewiseFunction()
    for i in range(otf.GetSize()):
        n = [0.0] * 4
        otf.GetNodeValue(i, n)
        o.AddPoint(x(n[0]), *n[1:])
    return c, o


def matplotlib_tf(cmap: str, lo: float, hi: float, opacity: list[float],
                  n: int = 32) -> tuple[vtk.vtkColorTransferFunction, vtk.vtkPiecewiseFunction]:
    """A colour map by matplotlib name (as pyvista's ``cmap=``) sampled at ``n`` nodes over
    [lo, hi], and a piecewise-linear opacity through the values ``opacity`` spread evenly
    over the same range (pyvista's ``opacity=[...]``)."""
    import matplotlib

    cm = matplotlib.colormaps[cmap]
    ctf = vtk.vtkColorTransferFunction()
    ctf.SetColorSpaceToRGB()
    for t in np.linspace(0, 1, n):
        ctf.AddRGBPoint(lo + t * (hi - lo), *cm(t)[:3])
    otf = vtk.vtkPiecewiseFunction()
    for t, a in zip(np.linspace(0, 1, len(opacity)), opacity):
        otf.AddPoint(lo + t * (hi - lo), a)
    return ctf, otf
