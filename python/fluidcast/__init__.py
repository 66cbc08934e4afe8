"""fluidcast: direct volume rendering of SPH particles in VTK and pyvista.

Direct volume rendering ray casts the particles themselves (no resampling onto a grid)
with a screen-space error the user chooses.

* ``fluidcast.vtkFluidCastVolumeMapper``: the VTK volume mapper (a ``vtkAbstractVolumeMapper``
  for a ``vtkVolume``), and ``fluidcast.vtkFluidCastReader``, fluidcast's checked particle-file
  reader as a VTK source. Both are compiled against the VTK of the Python that installed the
  package (see docs/vtk-and-python.md); they load on first use.
* ``fluidcast.add_particles(plotter, mesh, ...)``: the mapper in a pyvista ``Plotter``, with
  pyvista's ``add_volume`` conventions; ``fluidcast.read(path)`` reads particles into pyvista.
* Helpers for working beside VTK, used by the tests and examples: cameras
  (:mod:`fluidcast.camera`), transfer functions (:mod:`fluidcast.transfer`), particle data
  (:mod:`fluidcast.data`), VTK's own SPH pipeline (:mod:`fluidcast.vtk_sph`), images
  (:mod:`fluidcast.images`) and the CLI (:mod:`fluidcast.cli`).
"""
from __future__ import annotations

import importlib

__version__ = "0.1.0"

__all__ = ["add_particles", "read", "vtkFluidCastReader", "vtkFluidCastVolumeMapper"]

# The compiled classes and the pyvista helpers load on first use, so that the pure helpers
# work in a Python without the mapper (pip install ... FLUIDCAST_PYTHON_MAPPER=OFF) or pyvista.
_LAZY = {
    "vtkFluidCastVolumeMapper": "._rendering",
    "vtkFluidCastReader": "._rendering",
    "add_particles": ".plotting",
    "read": ".plotting",
}


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'fluidcast' has no attribute '{name}'")
    return getattr(importlib.import_module(module, __name__), name)


def __dir__():
    return sorted(list(globals()) + list(_LAZY))
