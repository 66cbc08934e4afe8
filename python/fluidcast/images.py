"""8-bit RGB images as numpy arrays ``(height, width, 3)``, top row first (fluidcast's PNG
output and a VTK screenshot), and their differences."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import vtk
from vtkmodules.util import numpy_support as ns


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
