"""fluidcast.add_particles refuses what it cannot render at the call, with a ValueError naming
the argument (issue 45), and whatever it accepts renders without an error.

Hand-picked cases first, then property-based ones (hypothesis): random values, NaN and
infinities included, for the numeric arguments, and random shapes and types of scalars.
"""
import math
import os

import fluidcast
import numpy as np
import pytest
import pyvista as pv
from fluidcast import vtkFluidCastVolumeMapper
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from vtkmodules.vtkCommonCore import vtkCommand

SIZE = (64, 48)


def particles(n=64):
    """A small lattice of particles with a scalar "q", 0.1 apart."""
    g = np.stack(np.meshgrid(*[np.arange(4) * 0.1] * 3, indexing="ij"), -1).reshape(-1, 3)
    mesh = pv.PolyData(g[:n].copy())
    mesh["q"] = np.linspace(0.0, 1.0, mesh.n_points)
    return mesh


def plotter():
    p = pv.Plotter(off_screen=True, window_size=list(SIZE))
    p.set_background("white")
    return p


def add(**kw):
    kw = {"scalars": "q", "show_scalar_bar": False, "render": False, "support_radius": 0.2,
          **kw}
    p = plotter()
    try:
        return p, fluidcast.add_particles(p, kw.pop("mesh", None) or particles(), **kw)
    except Exception:
        assert p.renderer.GetVolumes().GetNumberOfItems() == 0, "a failed call left a volume"
        p.close()
        raise


@pytest.mark.parametrize("kw, names", [
    ({"opacity_unit_distance": math.nan}, "opacity_unit_distance"),
    ({"opacity_unit_distance": 0}, "opacity_unit_distance"),
    ({"isosurfaces": [math.nan]}, "isosurfaces"),
    ({"isosurfaces": [[0.5, 1.0]]}, "isosurfaces"),
    ({"clim": [math.nan, 1]}, "clim"),
    ({"clim": [2, 1]}, "clim"),
    ({"support_radius": math.inf}, "support_radius"),
    ({"support_radius": -1}, "support_radius"),
    ({"radius_scale": 0}, "radius_scale"),
    ({"error_tolerance": math.inf}, "error_tolerance"),
    ({"isosurface_opacity": 2}, "isosurface_opacity"),
    ({"scalars": np.zeros((64, 2, 2))}, "scalars: shape"),
    ({"scalars": np.zeros(64, dtype=complex)}, "scalars: values of type complex"),
    ({"scalars": np.zeros(10)}, "scalars: 10 values for 64 particles"),
])
def test_a_bad_argument_raises_at_the_call_naming_it(kw, names):
    with pytest.raises(ValueError, match=names):
        add(**kw)


def test_a_single_infinite_point_says_so():
    mesh = pv.PolyData(np.array([[math.inf, 0.0, 0.0]]))
    mesh["q"] = [1.0]
    with pytest.raises(ValueError, match="all 1 points have NaN or infinite coordinates"):
        add(mesh=mesh)


def test_accepted_arguments_render_the_particles():
    """The checks refuse no good value: the edge values render, and draw."""
    p, volume = add(opacity_unit_distance=1e-3, clim=[0.0, 0.0], support_radius=0.0,
                    isosurfaces=[], error_tolerance=1.0)
    p.render()
    assert volume.mapper.GetLastError() == ""
    assert (p.screenshot(return_img=True) != 255).any()


numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                    st.integers(-10, 10), st.sampled_from([0.0, -0.0, 1e-30, 1e30]))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(argument=st.sampled_from(["opacity_unit_distance", "support_radius", "radius_scale",
                                 "error_tolerance", "isosurface_opacity"]), value=numbers)
def test_a_number_either_raises_naming_its_argument_or_renders(argument, value):
    try:
        p, volume = add(**{argument: value})
    except ValueError as e:
        assert argument in str(e), str(e)
        return
    p.render()
    assert volume.mapper.GetLastError() == "", f"{argument}={value}: accepted, then " \
        f"{volume.mapper.GetLastError()}"
    p.close()


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(shape=st.lists(st.integers(1, 3), min_size=0, max_size=2),
       dtype=st.sampled_from([np.float64, np.float32, np.int32, np.uint8, bool, complex,
                              object, str]),
       clim=st.one_of(st.none(), st.lists(numbers, min_size=2, max_size=2)),
       isosurfaces=st.one_of(st.none(), st.lists(numbers, max_size=3)))
def test_scalars_clim_and_isosurfaces_raise_or_render(shape, dtype, clim, isosurfaces):
    values = np.ones((64, *shape)).astype(dtype)
    try:
        p, volume = add(scalars=values, clim=clim, isosurfaces=isosurfaces)
    except ValueError as e:
        assert any(a in str(e) for a in ("scalars", "clim", "isosurfaces")), str(e)
        return
    p.render()
    assert volume.mapper.GetLastError() == "", volume.mapper.GetLastError()
    p.close()


def test_read_says_what_a_path_is(tmp_path):
    with pytest.raises(ValueError, match="a directory, not a particle file"):
        fluidcast.read(tmp_path)
    with pytest.raises(FileNotFoundError, match="no such file"):
        fluidcast.read(tmp_path / "missing.vtu")
    fifo = tmp_path / "fifo.vtu"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match="not a regular file"):
        fluidcast.read(fifo)


def test_the_mapper_refuses_a_bad_value_and_keeps_the_last_good_one():
    """Set methods check their value (the library's table of settings, the bridge's names):
    a refused value is a VTK error naming the property, and the mapper keeps what it had."""
    _, volume = add()
    m = volume.mapper
    errors = []
    m.AddObserver(vtkCommand.ErrorEvent, lambda *_: errors.append(True))
    for setter, bad, getter, kept in [
        (m.SetSupportRadius, math.inf, m.GetSupportRadius, 0.2),
        (m.SetSupportRadius, -1.0, m.GetSupportRadius, 0.2),
        (m.SetErrorTolerance, math.nan, m.GetErrorTolerance, 0.004),
        (m.SetGridCell, 0, m.GetGridCell, 1),
        (m.SetKernel, "nonsense", m.GetKernel, "cubic"),
        (m.SetField, "nonsense", m.GetField, "csph"),
        (m.SetMode, "fast", m.GetMode, "auto"),
    ]:
        errors.clear()
        setter(bad)
        assert errors, f"{setter.__name__}({bad!r}) was not refused"
        assert getter() == kept, f"{setter.__name__}({bad!r}) left {getter()!r}"
    assert vtkFluidCastVolumeMapper.CheckSetting("SupportRadius", math.inf) != ""
    assert vtkFluidCastVolumeMapper.CheckSetting("SupportRadius", 0.5) == ""
