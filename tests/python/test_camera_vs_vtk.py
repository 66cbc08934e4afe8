"""fluidcast's camera is VTK's camera.

* Round trip: a vtkCamera (pyvista's ``plotter.camera``) exported to fluidcast's camera JSON,
  used by ``fluidcast render --camera`` and written back with ``--save-camera``, loads into
  a vtkCamera with the same projection matrix.
* ``--camera auto --azimuth --elevation --zoom`` equals vtkRenderer::ResetCamera followed by
  vtkCamera::Azimuth/Elevation/Zoom.
* Projection: small isolated particles rendered by fluidcast land where VTK's own projection
  matrix puts them: the intensity centroid of each blob is within 0.5 px of VTK's projected
  centre (fluidcast's pixel convention: y from the top, centres at +0.5).
"""
import json

import numpy as np
import pytest
import pyvista as pv
import vtk
from conftest import fluidcast
from fluidcast.camera import load_camera, reset_camera, save_camera, vtk_project
from fluidcast.data import write_particles
from fluidcast.images import read_png

SIZE = (320, 200)  # not square, so an aspect-ratio mistake shows

CAMERAS = {
    "perspective": dict(azimuth=35, elevation=20, zoom=1.2, view_angle=30, parallel=False),
    "wide-angle": dict(azimuth=-60, elevation=-35, zoom=1.0, view_angle=60, parallel=False),
    "parallel": dict(azimuth=120, elevation=45, zoom=1.5, view_angle=30, parallel=True),
}


def pyvista_camera(points, azimuth, elevation, zoom, view_angle, parallel):
    """A camera set up the way a pyvista user does it."""
    pl = pv.Plotter(off_screen=True, window_size=list(SIZE))
    pl.add_points(pv.PolyData(points))
    pl.camera.view_angle = view_angle
    pl.enable_parallel_projection() if parallel else pl.disable_parallel_projection()
    pl.reset_camera()
    pl.camera.azimuth = azimuth
    pl.camera.elevation = elevation
    pl.camera.zoom(zoom)
    cam = vtk.vtkCamera()
    cam.DeepCopy(pl.camera)
    pl.close()
    return cam


def matrix(cam):
    """The rows of VTK's projection that decide where a point lands (x, y, w); the z row
    depends on the clipping range, which is not part of the camera JSON."""
    m = cam.GetCompositeProjectionTransformMatrix(SIZE[0] / SIZE[1], -1, 1)
    return np.array([[m.GetElement(r, c) for c in range(4)] for r in (0, 1, 3)])


def spaced(px, min_dist):
    """Indices of points whose projections are at least min_dist pixels from each other."""
    keep = []
    for i, p in enumerate(px):
        if all(np.hypot(*(p - px[j])) >= min_dist for j in keep):
            keep.append(i)
    return np.array(keep)


@pytest.mark.parametrize("name", list(CAMERAS))
def test_camera_round_trip_and_projection(name, tmp_path):
    rng = np.random.default_rng(7)
    cloud = rng.uniform([-1.0, -0.5, -0.8], [1.0, 0.5, 0.8], (400, 3))
    cam = pyvista_camera(cloud, **CAMERAS[name])

    # Round trip through fluidcast's JSON and the CLI.
    cam_json = save_camera(cam, tmp_path / "cam.json")
    px = vtk_project(cam, cloud, *SIZE)
    inside = np.all((px > 12) & (px < np.array(SIZE) - 12), axis=1)
    keep = np.flatnonzero(inside)[spaced(px[inside], 20)]
    assert len(keep) >= 20, f"only {len(keep)} well separated points in view"
    pts = cloud[keep]
    # Support radius: 4 px at the nearest point's depth (blobs never touch), and a
    # half-transparent medium, so each blob's intensity falls off smoothly from its centre.
    depth = (pts - cam.GetPosition()) @ np.array(cam.GetDirectionOfProjection())
    if cam.GetParallelProjection():
        footprint = 2 * cam.GetParallelScale() / SIZE[1]
    else:
        footprint = 2 * depth.min() * np.tan(np.radians(cam.GetViewAngle() / 2)) / SIZE[1]
    h = 4 * footprint
    data = write_particles(tmp_path / "blobs.vtp", pts, value=np.ones(len(pts)))
    tf = tmp_path / "white.json"
    tf.write_text(json.dumps([{"Name": "white", "RGBPoints": [0, 1, 1, 1, 1, 1, 1, 1],
                               "Points": [0, 0.5, 0.5, 0, 1, 0.5, 0.5, 0]}]))
    out = tmp_path / "blobs.png"
    saved = tmp_path / "saved.json"
    fluidcast("render", data, "--array", "value", "--range", "0,1", "--tf", tf,
              "--support-radius", h, "--uniform-volume", "--opacity-unit-distance", 2 * h,
              "--camera", cam_json, "--save-camera", saved, "--size", f"{SIZE[0]}x{SIZE[1]}",
              "--background", "0,0,0", "--mode", "reference", "-o", out)
    back = load_camera(saved)
    np.testing.assert_allclose(matrix(back), matrix(cam), rtol=0, atol=1e-12)

    # Projection: intensity centroid of each blob vs VTK's projected centre.
    img = read_png(out).astype(np.float64)[:, :, 0]
    want = px[keep]
    jj, ii = np.mgrid[0:SIZE[1], 0:SIZE[0]]
    errors = []
    for x, y in want:
        win = (np.abs(ii + 0.5 - x) < 9) & (np.abs(jj + 0.5 - y) < 9)
        w = img * win
        assert w.sum() > 0, f"no blob near ({x:.1f}, {y:.1f})"
        cx = (w * (ii + 0.5)).sum() / w.sum()
        cy = (w * (jj + 0.5)).sum() / w.sum()
        errors.append(np.hypot(cx - x, cy - y))
    assert max(errors) <= 0.5, f"blob centroids off by up to {max(errors):.3f} px"
    # Nothing is drawn away from the blobs.
    far = np.ones_like(img, bool)
    for x, y in want:
        far &= np.hypot(ii + 0.5 - x, jj + 0.5 - y) > 9
    assert img[far].max() == 0


def test_auto_camera_is_vtk_reset_camera(tmp_path):
    rng = np.random.default_rng(3)
    cloud = rng.uniform([0.2, -0.3, 1.0], [2.2, 0.4, 1.5], (300, 3))
    data = write_particles(tmp_path / "c.vtp", cloud, value=np.ones(len(cloud)))
    saved = tmp_path / "auto.json"
    fluidcast("render", data, "--array", "value", "--support-radius", 0.05, "--uniform-volume",
              "--azimuth", 40, "--elevation", 25, "--zoom", 1.3, "--save-camera", saved,
              "--size", f"{SIZE[0]}x{SIZE[1]}", "--mode", "reference", "-o", tmp_path / "a.png")
    ours = load_camera(saved)
    # fluidcast resets on the particles' bounds grown by the support radius (their extent).
    b = np.c_[cloud.min(0) - 0.05, cloud.max(0) + 0.05].ravel()
    vtk_cam = reset_camera(b, 40, 25, 1.3, SIZE)
    # fluidcast holds positions in single precision: agreement to 1e-6 of the scene size.
    tol = 1e-6 * np.linalg.norm(cloud.max(0) - cloud.min(0))
    for get in ("GetPosition", "GetFocalPoint", "GetViewUp"):
        np.testing.assert_allclose(getattr(ours, get)(), getattr(vtk_cam, get)(), rtol=0,
                                   atol=tol, err_msg=get)
    assert ours.GetViewAngle() == pytest.approx(vtk_cam.GetViewAngle(), abs=1e-12)
