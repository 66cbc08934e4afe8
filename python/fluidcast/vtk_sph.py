"""VTK's own SPH pipeline, the baseline fluidcast is compared with: ``vtkSPHInterpolator``
onto a ``vtkImageData`` grid rendered with ``vtkSmartVolumeMapper``, and Point Gaussian
splats through pyvista. Images are numpy arrays ``(height, width, 3)`` of uint8, top row
first, as fluidcast's PNG output."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import vtk
from vtkmodules.util import numpy_support as ns

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


def colour_field(ds: vtk.vtkPointSet, kernel: str, support: float, resolution: int,
                 mass: str | None = None, density: str | None = None) -> SphVolume:
    """The SPH colour field ``Σ V W`` (V = m/ρ from ``mass`` and ``density``) resampled by
    ``vtkSPHInterpolator`` onto a grid as ``sph_volume`` lays it out: the plain sum of the
    value 1 (no Shepard normalisation), 0 where no particle reaches."""
    ones = np.ones(ds.GetNumberOfPoints())
    return sph_volume(ds, ones, kernel, support, resolution, null_value=0.0, mass=mass,
                      density=density, shepard=False)


def render_iso_surface(vol: SphVolume, iso: float, cam: vtk.vtkCamera, color=(1.0, 1.0, 1.0),
                       ambient=0.1, diffuse=0.7, specular=0.2, specular_power=10.0,
                       size=(800, 600), background=(1.0, 1.0, 1.0)) -> np.ndarray:
    """VTK's own iso-surface of the grid: ``vtkFlyingEdges3D`` at ``iso`` with its gradient
    normals, drawn with ``vtkPolyDataMapper`` in one solid colour, lit by the renderer's
    default headlight with these ``vtkProperty`` coefficients."""
    ren, win = _offscreen(size, background, cam)
    fe = vtk.vtkFlyingEdges3D()
    fe.SetInputData(vol.image)
    fe.SetValue(0, iso)
    fe.ComputeNormalsOn()
    fe.ComputeScalarsOff()
    mapper = vtk.vtkPolyDataMapper()
    mapper.SetInputConnection(fe.GetOutputPort())
    mapper.ScalarVisibilityOff()
    actor = vtk.vtkActor()
    actor.SetMapper(mapper)
    p = actor.GetProperty()
    p.SetColor(*color)
    p.SetAmbient(ambient)
    p.SetDiffuse(diffuse)
    p.SetSpecular(specular)
    p.SetSpecularPower(specular_power)
    p.SetSpecularColor(1.0, 1.0, 1.0)
    ren.AddActor(actor)
    ren.ResetCameraClippingRange()
    win.Render()
    return _grab(win)


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
