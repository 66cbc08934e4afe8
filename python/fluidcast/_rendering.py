"""The compiled VTK classes (module FluidCast::Rendering), with a clear error where this
installation has none."""
from __future__ import annotations

# The mapper draws through VTK's OpenGL render window: load VTK's OpenGL factory overrides
# (what pyvista and ParaView do too) before the classes are used.
import vtkmodules.vtkRenderingOpenGL2  # noqa: F401
import vtkmodules.vtkRenderingVolumeOpenGL2  # noqa: F401

try:
    from .fluidcastRendering import vtkFluidCastReader, vtkFluidCastVolumeMapper
except ImportError as e:
    import vtkmodules

    raise ImportError(
        "fluidcast's VTK mapper is not available in this Python (VTK "
        f"{vtkmodules.__version__}): {e}. It is compiled against the VTK this Python imports; "
        "install fluidcast with `pip install .` from a checkout into a Python whose VTK has "
        "development files (ParaView's on Debian, conda-forge's vtk), see docs/vtk-and-python.md's "
        "'Use from VTK and pyvista'."
    ) from e

__all__ = ["vtkFluidCastReader", "vtkFluidCastVolumeMapper"]
