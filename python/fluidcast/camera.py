"""Cameras: a ``vtkCamera`` (pyvista's ``plotter.camera``) to fluidcast's camera JSON and back,
and VTK's own projection of world points into fluidcast's pixel convention (x from the left
edge, y from the *top* edge, pixel centres at +0.5)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import vtk


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
