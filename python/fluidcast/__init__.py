"""fluidcast: direct volume rendering of SPH particles in VTK and pyvista.

Direct volume rendering ray casts the particles themselves (no resampling onto a grid)
with a screen-space error the user chooses.

* ``fluidcast.vtkFluidCastVolumeMapper``: the VTK volume mapper (a ``vtkAbstractVolumeMapper``
  for a ``vtkVolume``), and ``fluidcast.vtkFluidCastReader``, fluidcast's checked particle-file
  reader as a VTK source. Both are compiled against the VTK of the Python that installed the
  package (see docs/vtk-and-python.md); they load on first use.
* ``fluidcast.read``, ``fluidcast.render``, ``fluidcast.interpolate`` (and ``Scene`` for many
  renders of the same particles): files to numpy, numpy to images with depth and to field
  values, through the compiled module ``fluidcast._core`` (the Rust library; no VTK needed).
* ``fluidcast.add_particles(plotter, mesh, ...)``: particles in a pyvista ``Plotter``, with
  pyvista's ``add_volume`` conventions: the VTK mapper where it was built for this VTK, else
  the module composited into the plotter (any VTK, pip's included).
* Helpers for working beside VTK, used by the tests and examples: cameras
  (:mod:`fluidcast.camera`), transfer functions (:mod:`fluidcast.transfer`), particle data
  (:mod:`fluidcast.data`), VTK's own SPH pipeline (:mod:`fluidcast.vtk_sph`), images
  (:mod:`fluidcast.images`) and the CLI (:mod:`fluidcast.cli`).
"""
from __future__ import annotations

import importlib

__version__ = "0.1.0"

__all__ = ["Image", "Particles", "Scene", "add_particles", "interpolate", "read", "render",
           "vtkFluidCastReader", "vtkFluidCastVolumeMapper"]

# The compiled classes and the pyvista helpers load on first use, so that the pure helpers
# work in a Python without the mapper (pip install ... FLUIDCAST_PYTHON_MAPPER=OFF) or pyvista.
_LAZY = {
    "vtkFluidCastVolumeMapper": "._rendering",
    "vtkFluidCastReader": "._rendering",
    "add_particles": ".plotting",
    "read": ".api",
    "render": ".api",
    "interpolate": ".api",
    "Particles": ".api",
    "Image": ".api",
    "Scene": ".api",
}


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'fluidcast' has no attribute '{name}'")
    return getattr(importlib.import_module(module, __name__), name)


def __dir__():
    return sorted(list(globals()) + list(_LAZY))
