"""fluidcast beside VTK: cameras, transfer functions and VTK's own SPH pipeline.

Shared by ``compare_vtk.py``, ``report.py`` and the pytest suite (``tests/python``):

* cameras: a ``vtkCamera`` (pyvista's ``plotter.camera``) to fluidcast's camera JSON and back,
  and VTK's own projection of world points into fluidcast's pixel convention (x from the
  left edge, y from the *top* edge, pixel centres at +0.5);
* transfer functions: a ``vtkColorTransferFunction`` + ``vtkPiecewiseFunction`` to a ParaView
  colour-map preset (the JSON fluidcast's ``--tf`` reads) and back;
* VTK's pipeline: ``vtkSPHInterpolator`` onto a ``vtkImageData`` grid, rendered with
  ``vtkSmartVolumeMapper``; Point Gaussian splats through pyvista;
* running the ``fluidcast`` CLI.

Images are numpy arrays ``(height, width, 3)`` of uint8, top row first, as fluidcast's PNG
output (colour composited over the background and written as it is, like a VTK screenshot).
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

try:
    import vtk
    from vtk.util import numpy_support as ns
except ImportError as e:  # pragma: no cover - explained to the user
    raise SystemExit(
        "this script needs VTK: run `bash scripts/setup_python.sh` and use .venv/bin/python "
        f"({e})"
    )

ROOT = Path(__file__).resolve().parents[1]


# --------------------------------------------------------------------------- the fluidcast CLI

def fluidcast_binary(build: bool = True) -> Path:
    """The ``fluidcast`` executable: ``$FLUIDCAST_BIN``, else ``target/release``, else
    ``target/debug``; with ``build``, ``cargo build --release`` when neither exists."""
    env = os.environ.get("FLUIDCAST_BIN")
    if env:
        return Path(env)
    for profile in ("release", "debug"):
        p = ROOT / "target" / profile / "fluidcast"
        if p.exists():
            return p
    if not build:
        raise FileNotFoundError("no fluidcast binary under target/ (run `cargo build --release`)")
    if shutil.which("cargo") is None:
        raise SystemExit("fluidcast is not built and cargo is not on PATH")
    subprocess.run(["cargo", "build", "--release", "--bin", "fluidcast"], cwd=ROOT, check=True)
    return ROOT / "target" / "release" / "fluidcast"


def run_fluidcast(*args, binary: Path | None = None) -> subprocess.CompletedProcess:
    """Runs the CLI; raises ``RuntimeError`` carrying its stderr when it fails."""
    cmd = [str(binary or fluidcast_binary()), *map(str, args)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({r.returncode}):\n{r.stderr}")
    return r


# --------------------------------------------------------------------------------- cameras

def camera_to_dict(cam: vtk.vtkCamera) -> dict:
    """vtkCamera → fluidcast's camera JSON (vtkCamera's own fields, snake_case)."""
    return {
        "position": list(cam.GetPosition()),
        "focal_point": list(cam.GetFocalPoint()),
        "view_up": list(cam.GetViewUp()),
        "view_angle": cam.GetViewAngle(),
        "parallel_projection": bool(cam.GetParallelProjection()),
        "parallel_scale": cam.GetParallelScale(),
    }


def camera_from_dict(d: dict) -> vtk.vtkCamera:
    """fluidcast's camera JSON (snake_case or VTK's CamelCase keys) → a new vtkCamera."""
    def get(snake, camel, default=None):
        for k in (snake, camel):
            if k in d:
                return d[k]
        if default is None:
            raise KeyError(f"camera JSON lacks '{snake}'")
        return default

    cam = vtk.vtkCamera()
    cam.SetPosition(*get("position", "Position"))
    cam.SetFocalPoint(*get("focal_point", "FocalPoint"))
    cam.SetViewUp(*get("view_up", "ViewUp"))
    cam.SetViewAngle(get("view_angle", "ViewAngle", 30.0))
    cam.SetParallelProjection(bool(get("parallel_projection", "ParallelProjection", False)))
    cam.SetParallelScale(get("parallel_scale", "ParallelScale", 1.0))
    return cam


def save_camera(cam: vtk.vtkCamera, path: Path) -> Path:
    Path(path).write_text(json.dumps(camera_to_dict(cam), indent=2))
    return Path(path)


def load_camera(path: Path) -> vtk.vtkCamera:
    return camera_from_dict(json.loads(Path(path).read_text()))


def vtk_project(cam: vtk.vtkCamera, points: np.ndarray, width: int, height: int) -> np.ndarray:
    """World points (N, 3) → pixel coordinates (N, 2) through VTK's own projection matrix
    (``GetCompositeProjectionTransformMatrix``), in fluidcast's convention: x from the left
    edge, y from the top edge, so pixel (i, j)'s centre is (i + 0.5, j + 0.5)."""
    m = cam.GetCompositeProjectionTransformMatrix(width / height, -1, 1)
    mat = np.array([[m.GetElement(r, c) for c in range(4)] for r in range(4)])
    p = np.c_[np.asarray(points, float), np.ones(len(points))] @ mat.T
    ndc = p[:, :2] / p[:, 3:4]
    return np.c_[(ndc[:, 0] + 1) * 0.5 * width, (1 - ndc[:, 1]) * 0.5 * height]


def reset_camera(bounds, azimuth=0.0, elevation=0.0, zoom=1.0, size=(800, 600)) -> vtk.vtkCamera:
    """VTK's ResetCamera on ``bounds`` (looking down −z, y up), then Azimuth/Elevation/Zoom —
    what ``fluidcast render --camera auto --azimuth A --elevation E`` does."""
    ren = vtk.vtkRenderer()
    win = vtk.vtkRenderWindow()  # for the aspect ratio only; never rendered
    win.SetOffScreenRendering(1)
    win.SetSize(*size)
    win.AddRenderer(ren)
    ren.ResetCamera(bounds)
    cam = ren.GetActiveCamera()
    cam.Azimuth(azimuth)
    cam.Elevation(elevation)
    cam.OrthogonalizeViewUp()
    cam.Zoom(zoom)
    out = vtk.vtkCamera()
    out.DeepCopy(cam)
    return out


# ---------------------------------------------------------------------- transfer functions

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
        rgb = [c for x in xs for c in (x, *ctf.GetColor(x))]
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


# ------------------------------------------------------------------------- particle data

def read_points(path: Path) -> vtk.vtkPointSet:
    """Reads a .vtu/.vtp/.vtk particle file with VTK's own readers."""
    path = Path(path)
    readers = {".vtu": vtk.vtkXMLUnstructuredGridReader, ".vtp": vtk.vtkXMLPolyDataReader,
               ".vtk": vtk.vtkDataSetReader}
    cls = readers.get(path.suffix.lower())
    if cls is None:
        raise ValueError(f"{path}: not a .vtu, .vtp or .vtk file")
    r = cls()
    r.SetFileName(str(path))
    r.Update()
    ds = r.GetOutput()
    if ds is None or ds.GetNumberOfPoints() == 0:
        raise ValueError(f"{path}: VTK's reader found no points (empty, truncated or not a "
                         f"{path.suffix} file)")
    return ds


def write_particles(path: Path, points: np.ndarray, **arrays: np.ndarray) -> Path:
    """Writes particles (N, 3) with named point arrays as a VTK XML PolyData file (.vtp),
    one vertex cell per particle, as SPH codes write them."""
    pts = vtk.vtkPoints()
    pts.SetData(ns.numpy_to_vtk(np.ascontiguousarray(points, dtype=np.float64), deep=True))
    poly = vtk.vtkPolyData()
    poly.SetPoints(pts)
    verts = vtk.vtkCellArray()
    for i in range(len(points)):
        verts.InsertNextCell(1)
        verts.InsertCellPoint(i)
    poly.SetVerts(verts)
    for name, a in arrays.items():
        arr = ns.numpy_to_vtk(np.ascontiguousarray(a), deep=True)
        arr.SetName(name)
        poly.GetPointData().AddArray(arr)
    w = vtk.vtkXMLPolyDataWriter()
    w.SetFileName(str(path))
    w.SetInputData(poly)
    if not w.Write():
        raise OSError(f"{path}: VTK could not write it")
    return Path(path)


def point_array(ds: vtk.vtkPointSet, spec: str) -> np.ndarray:
    """The per-particle scalar fluidcast renders for ``--array spec``: ``NAME`` (a vector
    gives its magnitude, ParaView's default), ``NAME:mag`` or ``NAME:K`` (component K)."""
    name, _, sel = spec.partition(":")
    arr = ds.GetPointData().GetArray(name)
    if arr is None:
        raise KeyError(f"no point array '{name}'")
    a = ns.vtk_to_numpy(arr).astype(np.float64)
    if a.ndim == 1:
        if sel not in ("", "mag", "0"):
            raise KeyError(f"'{name}' has one component")
        return np.abs(a) if sel == "mag" else a
    if sel in ("", "mag"):
        return np.linalg.norm(a, axis=1)
    return a[:, int(sel)]


def volume_arrays(ds: vtk.vtkPointSet) -> tuple[str | None, str | None]:
    """The mass and density arrays fluidcast picks by default (``mass``/``m``,
    ``density``/``rho``), or (None, None) for uniform volumes."""
    pd = ds.GetPointData()
    mass = next((n for n in ("mass", "m") if pd.GetArray(n) is not None), None)
    dens = next((n for n in ("density", "rho") if pd.GetArray(n) is not None), None)
    return (mass, dens) if mass and dens else (None, None)


def support_radius(ds: vtk.vtkPointSet, path: Path) -> float:
    """The file's ``support_radius`` field data (SPlisHSPlasH writes it) or fluidcast's
    suggestion (``fluidcast info --json``)."""
    fd = ds.GetFieldData().GetArray("support_radius")
    if fd is not None:
        return float(fd.GetTuple1(0))
    info = json.loads(run_fluidcast("info", path, "--json").stdout)
    return float(info["suggested_support_radius"])


# ----------------------------------------------------------------------- VTK's SPH volume

# fluidcast kernel name → VTK kernel class and support radius / spatial step h.
VTK_KERNELS = {
    "cubic": (vtk.vtkSPHCubicKernel, 2.0),
    "quintic": (vtk.vtkSPHQuinticKernel, 3.0),
    "wendland-c2": (vtk.vtkWendlandQuinticKernel, 2.0),
}


@dataclass
class SphVolume:
    """VTK's resampled field: the grid, the time ``vtkSPHInterpolator`` took (s) and the
    grid's memory (bytes, ``GetActualMemorySize``)."""
    image: vtk.vtkImageData
    seconds: float
    bytes: int
    null_value: float


def sph_volume(ds: vtk.vtkPointSet, values: np.ndarray, kernel: str, support: float,
               resolution: int, null_value: float, mass: str | None = None,
               density: str | None = None, shepard: bool = True) -> SphVolume:
    """Resamples ``values`` (one per particle) onto a ``vtkImageData`` with ``resolution``
    points along the longest side of the particles' bounds grown by the support radius
    (isotropic spacing), with ``vtkSPHInterpolator``. Points no particle reaches get
    ``null_value`` (choose it outside the transfer function's range, with zero opacity)."""
    if kernel not in VTK_KERNELS:
        raise ValueError(f"VTK has no '{kernel}' SPH kernel (use {', '.join(VTK_KERNELS)})")
    cls, factor = VTK_KERNELS[kernel]
    src = vtk.vtkPolyData()
    src.SetPoints(ds.GetPoints())
    arr = ns.numpy_to_vtk(np.ascontiguousarray(values, dtype=np.float64), deep=True)
    arr.SetName("value")
    src.GetPointData().AddArray(arr)
    for n in (mass, density):
        if n:
            src.GetPointData().AddArray(ds.GetPointData().GetArray(n))
    b = np.array(ds.GetBounds()).reshape(3, 2)
    lo, hi = b[:, 0] - support, b[:, 1] + support
    spacing = (hi - lo).max() / (resolution - 1)
    dims = np.maximum(np.ceil((hi - lo) / spacing).astype(int) + 1, 2)
    img = vtk.vtkImageData()
    img.SetDimensions(*map(int, dims))
    img.SetOrigin(*lo)
    img.SetSpacing(spacing, spacing, spacing)

    k = cls()
    k.SetSpatialStep(support / factor)
    k.SetDimension(3)
    interp = vtk.vtkSPHInterpolator()
    interp.SetInputData(img)
    interp.SetSourceData(src)
    interp.SetKernel(k)
    if mass and density:
        interp.SetMassArrayName(mass)
        interp.SetDensityArrayName(density)
    interp.SetShepardNormalization(shepard)
    interp.ComputeShepardSumOn()
    interp.PassPointArraysOff()
    for n in (mass, density):
        if n:
            interp.AddExcludedArray(n)
    t = time.perf_counter()
    interp.Update()
    seconds = time.perf_counter() - t
    out = vtk.vtkImageData()
    out.ShallowCopy(interp.GetOutput())
    # VTK writes 0 where no particle reaches (its null-point strategy does not apply to SPH
    # sums); the Shepard sum Σ V W is 0 exactly there.
    value = ns.vtk_to_numpy(out.GetPointData().GetArray("value"))
    shepard_sum = ns.vtk_to_numpy(out.GetPointData().GetArray(interp.GetShepardSumArrayName()))
    value[shepard_sum <= 0] = null_value
    out.GetPointData().RemoveArray(interp.GetShepardSumArrayName())
    out.GetPointData().SetActiveScalars("value")
    return SphVolume(out, seconds, out.GetActualMemorySize() * 1024, null_value)


def with_null(ctf, otf, null_value: float):
    """Copies of ``ctf`` and ``otf`` extended down to ``null_value`` (below their range),
    transparent there and unchanged from the range's low end on: VTK then sees no medium
    where no particle reaches. (VTK's GPU mapper builds its tables over the colour
    function's range, so the colour function needs the extra node too.)"""
    lo = ctf.GetRange()[0]
    c = vtk.vtkColorTransferFunction()
    c.DeepCopy(ctf)
    c.AddRGBPoint(null_value, *ctf.GetColor(lo))
    o = vtk.vtkPiecewiseFunction()
    o.DeepCopy(otf)
    o.AddPoint(null_value, 0.0)
    o.AddPoint(lo, otf.GetValue(lo))
    return c, o


def _offscreen(size, background, cam):
    ren = vtk.vtkRenderer()
    ren.SetBackground(*background)
    win = vtk.vtkRenderWindow()
    win.SetOffScreenRendering(1)
    win.SetSize(*size)
    win.AddRenderer(ren)
    c = ren.GetActiveCamera()
    c.DeepCopy(cam)
    return ren, win


def _grab(win) -> np.ndarray:
    w2i = vtk.vtkWindowToImageFilter()
    w2i.SetInput(win)
    w2i.SetInputBufferTypeToRGB()
    w2i.ReadFrontBufferOff()
    w2i.Update()
    im = w2i.GetOutput()
    w, h, _ = im.GetDimensions()
    a = ns.vtk_to_numpy(im.GetPointData().GetScalars()).reshape(h, w, 3)
    return np.ascontiguousarray(a[::-1])  # VTK's rows start at the bottom


def render_volume(vol: SphVolume, cam: vtk.vtkCamera, ctf, otf, unit_distance: float,
                  size=(800, 600), background=(1.0, 1.0, 1.0),
                  sample_distance: float | None = None) -> tuple[np.ndarray, float]:
    """Renders the resampled grid with ``vtkSmartVolumeMapper`` (trilinear interpolation,
    no shading, fixed sample distance: half the grid spacing unless given) and returns the
    image and the seconds the first render took (shader set-up and upload included)."""
    ren, win = _offscreen(size, background, cam)
    mapper = vtk.vtkSmartVolumeMapper()
    mapper.SetInputData(vol.image)
    mapper.SetAutoAdjustSampleDistances(0)
    mapper.SetInteractiveAdjustSampleDistances(0)
    mapper.SetSampleDistance(sample_distance or vol.image.GetSpacing()[0] * 0.5)
    prop = vtk.vtkVolumeProperty()
    c, o = with_null(ctf, otf, vol.null_value)
    prop.SetColor(c)
    prop.SetScalarOpacity(o)
    prop.SetScalarOpacityUnitDistance(unit_distance)
    prop.SetInterpolationTypeToLinear()
    prop.ShadeOff()
    volume = vtk.vtkVolume()
    volume.SetMapper(mapper)
    volume.SetProperty(prop)
    ren.AddVolume(volume)
    ren.ResetCameraClippingRange()
    t = time.perf_counter()
    win.Render()
    seconds = time.perf_counter() - t
    return _grab(win), seconds


def render_splats(ds: vtk.vtkPointSet, values: np.ndarray, cam: vtk.vtkCamera, cmap: str,
                  clim, radius: float, opacity: float = 1.0, size=(800, 600),
                  background=(1.0, 1.0, 1.0)) -> tuple[np.ndarray, float]:
    """Point Gaussian splats through pyvista (``style='points_gaussian'``), each a Gaussian of
    world radius ``radius`` coloured by ``values``; returns the image and the seconds from
    building the plotter to the image."""
    import pyvista as pv

    t = time.perf_counter()
    pts = pv.PolyData(ns.vtk_to_numpy(ds.GetPoints().GetData()).astype(np.float64))
    pts["value"] = values
    pl = pv.Plotter(off_screen=True, window_size=list(size))
    pl.set_background(background)
    pl.add_mesh(pts, scalars="value", cmap=cmap, clim=clim, style="points_gaussian",
                point_size=radius, opacity=opacity, emissive=False,
                render_points_as_spheres=False, show_scalar_bar=False)
    # pyvista's point_size for Gaussian points is a screen size; set the world radius.
    pl.mapper.SetScaleFactor(radius)
    pl.camera.DeepCopy(cam)
    pl.renderer.ResetCameraClippingRange()
    img = pl.screenshot(return_img=True)
    seconds = time.perf_counter() - t
    pl.close()
    return np.ascontiguousarray(img[:, :, :3]), seconds


# ----------------------------------------------------------------------------- comparison

def read_png(path: Path) -> np.ndarray:
    """An 8-bit RGB(A) PNG → (h, w, 3) uint8, top row first."""
    r = vtk.vtkPNGReader()
    r.SetFileName(str(path))
    r.Update()
    im = r.GetOutput()
    w, h, _ = im.GetDimensions()
    nc = im.GetPointData().GetScalars().GetNumberOfComponents()
    a = ns.vtk_to_numpy(im.GetPointData().GetScalars()).reshape(h, w, nc)
    return np.ascontiguousarray(a[::-1, :, :3])


def write_png(path: Path, img: np.ndarray) -> None:
    h, w, nc = img.shape
    im = vtk.vtkImageData()
    im.SetDimensions(w, h, 1)
    im.GetPointData().SetScalars(
        ns.numpy_to_vtk(np.ascontiguousarray(img[::-1]).reshape(-1, nc), deep=True))
    wr = vtk.vtkPNGWriter()
    wr.SetFileName(str(path))
    wr.SetInputData(im)
    wr.Write()


def difference(a: np.ndarray, b: np.ndarray) -> dict:
    """Max abs, RMSE and the 99th percentile of the per-pixel largest channel difference,
    in 0..1 (8-bit levels / 255)."""
    d = np.abs(a.astype(np.float64) - b.astype(np.float64)) / 255.0
    px = d.max(axis=2)
    return {"max_abs": float(d.max()), "rmse": float(np.sqrt((d ** 2).mean())),
            "p99": float(np.percentile(px, 99))}
