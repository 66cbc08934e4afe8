"""fluidcast in a pyvista ``Plotter`` without the VTK mapper (pip's VTK has no development
files to build it against): the particles are rendered by the Python module
(``fluidcast._core``) after the plotter's renderer has drawn its own props, with the
renderer's depth buffer as each ray's limit, and blended over it, premultiplied, as the
mapper blends its image. Every render of the plotter (a camera move, a new window size, a
screenshot) renders the particles anew for its camera; an unchanged camera, size and depth
reuse the last image.
"""
from __future__ import annotations

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkCommand, vtkFloatArray
from vtkmodules.vtkCommonMath import vtkMatrix4x4

from .api import Scene

# OpenGL's blend factors (the values of the GL enums).
_GL_ONE = 1
_GL_SRC_ALPHA = 0x0302
_GL_ONE_MINUS_SRC_ALPHA = 0x0303
_GL_BLEND = 0x0BE2


def depth_limits(renderer, zbuf: np.ndarray) -> np.ndarray | None:
    """The view depth (world units along the camera's axis) of each pixel's opaque geometry,
    rows top first, +inf where there is none; None when nothing is drawn. ``zbuf``: the
    window depths of the renderer's viewport, rows from the bottom (VTK's order)."""
    h, w = zbuf.shape
    hit = zbuf < 1.0
    if not hit.any():
        return None
    cam = renderer.GetActiveCamera()
    m = vtkMatrix4x4()
    m.DeepCopy(cam.GetCompositeProjectionTransformMatrix(renderer.GetTiledAspectRatio(), -1, 1))
    m.Invert()
    inv = np.array([[m.GetElement(r, c) for c in range(4)] for r in range(4)])
    jv, i = np.mgrid[0:h, 0:w]
    ndc = np.stack([2.0 * (i + 0.5) / w - 1.0, 2.0 * (jv + 0.5) / h - 1.0,
                    2.0 * zbuf.astype(np.float64) - 1.0, np.ones((h, w))], axis=-1)
    world = ndc @ inv.T
    world = world[..., :3] / world[..., 3:]
    p = np.array(cam.GetPosition())
    fwd = np.array(cam.GetFocalPoint()) - p
    fwd /= np.linalg.norm(fwd)
    d = np.maximum((world - p) @ fwd, 0.0)
    limit = np.where(hit, d, np.inf).astype(np.float32)
    return np.ascontiguousarray(limit[::-1])


class ParticlesOverlay:
    """The particles of one ``add_particles`` call drawn into a plotter's renderer by the
    Python module. ``scene`` is the :class:`fluidcast.Scene`, ``last`` the last rendered
    :class:`fluidcast.Image`; ``remove()`` takes the particles out of the plotter."""

    def __init__(self, plotter, scene: Scene, render_options: dict, bounds_actor=None):
        self.plotter = plotter
        self.scene = scene
        self.options = render_options
        self.last = None
        self.error: str | None = None
        self._key = None
        self._bounds_actor = bounds_actor
        self.renderer = plotter.renderer
        self._tag = self.renderer.AddObserver(vtkCommand.EndEvent, self._on_end)

    def remove(self):
        self.renderer.RemoveObserver(self._tag)
        if self._bounds_actor is not None:
            self.plotter.remove_actor(self._bounds_actor, render=False)

    def _viewport(self):
        x0, y0 = self.renderer.GetOrigin()
        w, h = self.renderer.GetSize()
        return int(x0), int(y0), int(w), int(h)

    def _on_end(self, renderer, _event):
        win = renderer.GetRenderWindow()
        x0, y0, w, h = self._viewport()
        if w < 1 or h < 1:
            return
        z = vtkFloatArray()
        win.GetZbufferData(x0, y0, x0 + w - 1, y0 + h - 1, z)
        if z.GetNumberOfValues() == w * h:
            zbuf = vtk_to_numpy(z).reshape(h, w)
        else:  # the depth could not be read: nothing opaque is assumed (as the mapper does)
            zbuf = np.ones((h, w), np.float32)
        cam = renderer.GetActiveCamera()
        key = (cam.GetPosition(), cam.GetFocalPoint(), cam.GetViewUp(), cam.GetViewAngle(),
               cam.GetParallelProjection(), cam.GetParallelScale(), w, h, hash(zbuf.tobytes()))
        if key != self._key:
            try:
                self.last = self.scene.render(cam, (w, h), depth_limit=depth_limits(renderer, zbuf),
                                              **self.options)
                self.error = None
            except ValueError as e:  # said once, and nothing drawn (as the mapper does)
                if str(e) != self.error:
                    print(f"fluidcast: {e}")
                self.error, self.last = str(e), None
            self._key = key
        if self.last is not None:
            composite(win, self.last.rgba, (x0, y0, w, h))


def composite(win, rgba: np.ndarray, viewport) -> None:
    """Blends premultiplied ``rgba`` (rows top first) over the window's viewport, as the
    mapper does (glBlendFuncSeparate(ONE, ONE_MINUS_SRC_ALPHA, ...), SetRGBAPixelData)."""
    x0, y0, w, h = viewport
    flipped = np.ascontiguousarray(rgba[::-1], dtype=np.float32).reshape(-1, 4)
    data = numpy_to_vtk(flipped, deep=True)
    state = win.GetState()
    state.vtkglEnable(_GL_BLEND)
    state.vtkglBlendFuncSeparate(_GL_ONE, _GL_ONE_MINUS_SRC_ALPHA, _GL_ONE,
                                 _GL_ONE_MINUS_SRC_ALPHA)
    try:
        win.SetRGBAPixelData(x0, y0, x0 + w - 1, y0 + h - 1, data, 0, 1)
    finally:
        state.vtkglBlendFuncSeparate(_GL_SRC_ALPHA, _GL_ONE_MINUS_SRC_ALPHA, _GL_ONE,
                                     _GL_ONE_MINUS_SRC_ALPHA)
