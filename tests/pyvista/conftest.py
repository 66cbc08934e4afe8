"""pytest set-up for tests/pyvista: run by scripts/test.sh in .venv-paraview (Debian's Python,
ParaView's VTK, pyvista 0.44, the package `fluidcast` installed with its mapper) under Xvfb
(Debian's VTK needs an X display even offscreen)."""
import pytest
import pyvista as pv


@pytest.fixture(autouse=True)
def _quiet_plotters():
    """Every plotter a test opens is closed after it, whatever happens."""
    yield
    pv.close_all()
