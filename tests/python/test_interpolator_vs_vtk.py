"""fluidcast's field reconstruction equals VTK's vtkSPHInterpolator.

Same kernel (VTK's cubic = our cubic with H = 2h, quintic H = 3h, Wendland quintic =
our wendland-c2 with H = 2h), same radius, mass and density arrays, Shepard normalisation
on (our csph) and off (our sph), at >= 1000 points inside a real frame.
"""
import numpy as np
import pytest
import vtk
from conftest import shared
from fluidcast import api
from fluidcast.data import read_points
from fluidcast.vtk_sph import VTK_KERNELS
from vtk.util import numpy_support as ns

KERNELS = VTK_KERNELS  # fluidcast kernel name -> (VTK kernel class, H / h)


def vtk_interpolate(ds, probe_pts, kernel, support, shepard, array):
    cls, factor = KERNELS[kernel]
    k = cls()
    k.SetSpatialStep(support / factor)  # h; VTK's cutoff radius is factor * h
    k.SetDimension(3)
    interp = vtk.vtkSPHInterpolator()
    poly = vtk.vtkPolyData()
    p = vtk.vtkPoints()
    p.SetData(ns.numpy_to_vtk(probe_pts, deep=True))
    poly.SetPoints(p)
    interp.SetInputData(poly)
    interp.SetSourceData(ds)
    interp.SetKernel(k)
    interp.SetDensityArrayName("density")
    interp.SetMassArrayName("mass")
    interp.SetShepardNormalization(shepard)
    interp.SetNullPointsStrategyToMaskPoints()
    interp.PassPointArraysOff()
    interp.Update()
    out = interp.GetOutput().GetPointData()
    vals = ns.vtk_to_numpy(out.GetArray(array)).astype(np.float64)
    mask = ns.vtk_to_numpy(out.GetArray(interp.GetValidPointsMaskArrayName())).astype(bool)
    return vals, mask


@pytest.mark.parametrize("kernel", list(KERNELS))
@pytest.mark.parametrize("shepard", [True, False])
def test_field_matches_vtk_sph_interpolator(kernel, shepard, tmp_path):
    path = shared("splash_doubledambreak/DoubleDamBreak_r0.0125_0011.vtu")
    ds = read_points(path)
    pts = ns.vtk_to_numpy(ds.GetPoints().GetData()).astype(np.float64)
    rng = np.random.default_rng(3)
    # Probe near particles (inside the fluid), offset by up to one spacing.
    probe = pts[rng.choice(len(pts), 1200, replace=False)] + rng.uniform(-0.02, 0.02, (1200, 3))
    support = 0.05
    ref, mask = vtk_interpolate(ds, probe, kernel, support, shepard, "density")
    # The Python module (volumes = mass / density, the arrays it finds by name).
    got = api.interpolate(path, probe, "density", kernel=kernel, support_radius=support,
                          field="csph" if shepard else "sph")
    ok = mask & np.isfinite(got)
    assert ok.sum() >= 1000
    rel = np.abs(got[ok] - ref[ok]) / np.maximum(np.abs(ref[ok]), 1e-12)
    assert rel.max() < 1e-4, f"max relative difference {rel.max():.3g}"
