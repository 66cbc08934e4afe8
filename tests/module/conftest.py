"""pytest set-up for tests/module: the Python module fluidcast._core and fluidcast.add_particles
without the VTK mapper. scripts/test.sh runs it in .venv-pip (a plain venv with PyPI's VTK and
pyvista) and, with the mapper beside the module, in .venv-paraview (ParaView's VTK), under
Xvfb."""
import pytest
import pyvista as pv


@pytest.fixture(autouse=True)
def _quiet_plotters():
    """Every plotter a test opens is closed after it, whatever happens."""
    yield
    pv.close_all()
