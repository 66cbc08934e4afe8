"""fluidcast in a pyvista ``Plotter``: ``add_particles`` puts particles into a plotter with
pyvista's ``add_volume`` conventions, ``read`` loads particle files into pyvista.

Two routes draw them, to the same image: the VTK mapper where it was built for this Python's
VTK (ParaView's, conda-forge's), else the Python module ``fluidcast._core`` composited into
the plotter (:mod:`fluidcast.overlay`; pip's VTK). Either renders with the plotter's camera
and window into the same image as the other actors: opaque meshes in front of the particles
hide them, and the particles cover what lies behind them.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pyvista as pv
from vtkmodules.util.misc import calldata_type
from vtkmodules.vtkCommonCore import VTK_STRING, vtkCommand
from vtkmodules.vtkCommonDataModel import vtkPiecewiseFunction, vtkPointSet
from vtkmodules.vtkRenderingCore import vtkColorTransferFunction, vtkVolumeProperty

from . import _core, api

try:
    from ._rendering import vtkFluidCastReader, vtkFluidCastVolumeMapper
    MAPPER_ERROR: str | None = None
except ImportError as _e:  # pip's VTK: the module route (fluidcast.overlay)
    vtkFluidCastReader = vtkFluidCastVolumeMapper = None
    MAPPER_ERROR = str(_e)

#: Backend names, in the order of the mapper's constants (``Backend`` property; ParaView's
#: FluidCastBackend): auto, cpu, gpu.
BACKENDS = {name: i for i, name in enumerate(_core.names()["backends"])}

# vtkSmartVolumeMapper's vector modes, which the mapper follows.
_MAGNITUDE_BY_DEFAULT = -1
_COMPONENT = 1


def kernels() -> list[str]:
    """The SPH kernels fluidcast knows (the mapper's ``Kernel`` property)."""
    return list(_core.names()["kernels"])


class _Errors:
    """Collects the messages of a VTK object's ErrorEvents (what vtkErrorMacro reports)."""

    def __init__(self, obj):
        self.messages: list[str] = []
        self._obj = obj
        self._tag = obj.AddObserver(vtkCommand.ErrorEvent, self._on_error)

    @calldata_type(VTK_STRING)
    def _on_error(self, _obj, _event, message):
        # VTK's text: "ERROR: In FILE, line N\nvtkClass (0x...): the message".
        text = str(message).strip()
        self.messages.append(re.sub(r"^ERROR: In .*?\n\S+ \(0x[0-9a-f]+\): ", "", text, flags=re.S))

    def close(self):
        self._obj.RemoveObserver(self._tag)


def read(path: str | Path) -> pv.PolyData:
    """Reads a particle file (.vtu, .vtp, legacy .vtk: one frame; of a .pvd series, read the
    frame's file) with fluidcast's own checked reader, points and point arrays as a
    ``pyvista.PolyData``.

    Raises ``ValueError`` naming the file and the problem for a missing, damaged or lying
    file, and for a mesh (cells other than vertices, cell data, a structured grid), which
    this reader would strip to its points: read meshes with ``pyvista.read``."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    if path.is_dir():
        raise ValueError(f"{path}: a directory, not a particle file (give a .vtu, .vtp, .vtk, "
                         ".pvtu or .pvd file in it)")
    if not path.is_file():
        raise ValueError(f"{path}: not a regular file (a FIFO, socket or device), which "
                         "fluidcast does not read")
    if vtkFluidCastReader is None:
        return _point_set(api.read(path))
    reader = vtkFluidCastReader()
    errors = _Errors(reader)
    reader.SetFileName(str(path))
    reader.Update()
    errors.close()
    if errors.messages:
        raise ValueError(errors.messages[-1])
    return pv.wrap(reader.GetOutput())


def _checked(argument: str, prop: str, value) -> float:
    """``value`` for the argument ``argument`` (the mapper's property ``prop``), as a float,
    checked by fluidcast's one table of settings (:func:`fluidcast.api._checked`, as the CLI
    and ParaView check it); a ``ValueError`` naming the argument otherwise."""
    try:
        return api._checked(argument, prop, value)
    except ValueError as e:
        raise ValueError(f"fluidcast.add_particles: {e}") from None


def _point_set(particles) -> pv.DataSet:
    if isinstance(particles, (str, Path)):
        return read(particles)
    if isinstance(particles, api.Particles):
        mesh = pv.PolyData(np.asarray(particles.points, dtype=float))
        for k, v in particles.point_data.items():
            mesh.point_data[k] = v
        for k, v in particles.field_data.items():
            mesh.field_data[k] = v
        particles = mesh
    if not isinstance(particles, vtkPointSet):
        raise TypeError(
            "fluidcast.add_particles: particles must be a file path or a point set "
            f"(pyvista.PolyData, pyvista.UnstructuredGrid), not {type(particles).__name__}")
    mesh = pv.wrap(particles)
    if mesh.n_points == 0:
        raise ValueError("fluidcast.add_particles: the particles have no points")
    return mesh


def _scalars(mesh: pv.DataSet, scalars) -> tuple[pv.DataSet, str]:
    """The point array to render, by name (None: the active scalars) or as values."""
    if scalars is None:
        scalars = mesh.point_data.active_scalars_name
        if scalars is None:
            raise ValueError(
                "fluidcast.add_particles: no scalars given and the particles have no active "
                f"point scalars; name a point array ({_names(mesh)})")
    if isinstance(scalars, str):
        if scalars not in mesh.point_data:
            where = " (it is cell data; fluidcast renders point data)" \
                if scalars in mesh.cell_data else ""
            raise ValueError(f"fluidcast.add_particles: the particles have no point array "
                             f"'{scalars}'{where}; point arrays: {_names(mesh)}")
        return mesh, scalars
    values = np.asarray(scalars)
    if values.ndim == 0 or values.shape[0] != mesh.n_points:
        count = values.shape[0] if values.ndim else 1
        raise ValueError(f"fluidcast.add_particles: scalars: {count} values for "
                         f"{mesh.n_points} particles")
    _check_scalars(values, "scalars")
    mesh = mesh.copy(deep=False)
    mesh.point_data["Data"] = values
    return mesh, "Data"


def _check_scalars(values: np.ndarray, argument: str):
    """Refuses what the mapper cannot render: complex, text or object values, and arrays of
    more than one value per component (shape (N, 2, 2))."""
    if values.dtype.kind not in "biuf":
        raise ValueError(f"fluidcast.add_particles: {argument}: values of type {values.dtype} "
                         "(real numbers, integers or booleans only)")
    if values.ndim > 2:
        raise ValueError(f"fluidcast.add_particles: {argument}: shape {values.shape}; one "
                         "value or one vector per particle, (N,) or (N, components)")


def _names(mesh: pv.DataSet) -> str:
    return ", ".join(mesh.point_data.keys()) or "none"


def _rendered_values(values: np.ndarray, component: int | None) -> np.ndarray:
    """What the mapper renders: the values, a vector's magnitude, or one component."""
    if values.ndim == 1:
        if component not in (None, 0):
            raise ValueError(f"fluidcast.add_particles: component {component} of a scalar")
        return values
    if component is None:
        return np.linalg.norm(values, axis=1)
    if not 0 <= component < values.shape[1]:
        raise ValueError(f"fluidcast.add_particles: component {component} of an array with "
                         f"{values.shape[1]} components")
    return values[:, component]


def _clim(values: np.ndarray, clim) -> tuple[float, float]:
    if clim is None:
        finite = values[np.isfinite(values)]
        if finite.size == 0:
            raise ValueError("fluidcast.add_particles: the scalars have no finite value")
        clim = (float(finite.min()), float(finite.max()))
    elif np.isscalar(clim):
        clim = (-float(clim), float(clim))
    try:
        lo, hi = map(float, clim)
    except (TypeError, ValueError):
        raise ValueError(f"fluidcast.add_particles: clim must be two numbers, not {clim!r}") \
            from None
    if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
        raise ValueError(f"fluidcast.add_particles: clim must be two finite numbers, low <= "
                         f"high, not {clim!r}")
    if not lo < hi:
        hi = lo + max(abs(lo), 1.0) * 1e-6  # a constant field: one colour, as pyvista
    return lo, hi


def transfer_functions(lut: pv.LookupTable, clim: tuple[float, float]):
    """A pyvista lookup table as VTK colour and opacity functions in data units, one node
    per table entry spread evenly over ``clim`` (pyvista's own ``to_color_tf`` is in table
    indices, for the 0..255 data ``add_volume`` makes; the mapper reads the data itself)."""
    table = np.asarray(lut.values, dtype=np.float64) / 255.0
    ctf = vtkColorTransferFunction()
    ctf.SetColorSpaceToRGB()
    otf = vtkPiecewiseFunction()
    for x, (r, g, b, a) in zip(np.linspace(clim[0], clim[1], len(table)), table):
        ctf.AddRGBPoint(x, r, g, b)
        otf.AddPoint(x, a)
    return ctf, otf


def _lookup_table(plotter, cmap, n_colors, flip_scalars, opacity, clim) -> pv.LookupTable:
    if isinstance(cmap, pv.LookupTable):
        lut = cmap
    else:
        lut = pv.LookupTable(cmap=cmap or plotter.theme.cmap, n_values=n_colors,
                             flip=flip_scalars)
        lut.apply_opacity(opacity)
    lut.scalar_range = clim
    return lut


def _configure(mapper, mesh, name, values, *, component, support_radius, radius_array,
               radius_scale, kernel, error_tolerance, backend, adapter):
    mapper.SetInputData(mesh)
    mapper.SetScalarModeToUsePointFieldData()
    mapper.SelectScalarArray(name)
    if values.ndim > 1 and component is not None:
        mapper.SetVectorMode(_COMPONENT)
        mapper.SetVectorComponent(component)
    else:
        mapper.SetVectorMode(_MAGNITUDE_BY_DEFAULT)
    if kernel not in kernels():
        raise ValueError(f"fluidcast.add_particles: unknown kernel '{kernel}' "
                         f"(one of {', '.join(kernels())})")
    mapper.SetKernel(kernel)
    if support_radius is not None:
        mapper.SetSupportRadius(_checked("support_radius", "SupportRadius", support_radius))
    if radius_array is not None:
        mapper.SetRadiusArray(radius_array)
    mapper.SetRadiusScale(_checked("radius_scale", "RadiusScale", radius_scale))
    mapper.SetErrorTolerance(_checked("error_tolerance", "ErrorTolerance", error_tolerance))
    if backend not in BACKENDS:
        raise ValueError(f"fluidcast.add_particles: unknown backend '{backend}' "
                         f"(one of {', '.join(BACKENDS)})")
    mapper.SetBackend(BACKENDS[backend])
    if adapter is not None:
        mapper.SetAdapter(adapter)


def _isosurfaces(isosurfaces) -> list[float]:
    if isosurfaces is None:
        return []
    try:
        values = np.atleast_1d(np.asarray(isosurfaces, dtype=float))
    except (TypeError, ValueError):
        raise ValueError(f"fluidcast.add_particles: isosurfaces must be numbers, not "
                         f"{isosurfaces!r}") from None
    if values.ndim != 1:
        raise ValueError(f"fluidcast.add_particles: isosurfaces must be a list of values, not "
                         f"of shape {values.shape}")
    return [_checked("isosurfaces", "IsoValue", v) for v in values]


def _default_unit_distance(mesh: pv.DataSet) -> float:
    """The CLI's default: the diagonal of the finite points' bounds over cbrt(their count)."""
    points = np.asarray(mesh.points, dtype=float)
    finite = points[np.isfinite(points).all(axis=1)]
    diagonal = float(np.linalg.norm(finite.max(axis=0) - finite.min(axis=0))) \
        if len(finite) else 0.0
    return diagonal / np.cbrt(len(finite)) if diagonal > 0 else 1.0


def add_particles(plotter: pv.Plotter, particles, scalars=None, *, component: int | None = None,
                  clim=None, cmap=None, opacity="linear", n_colors: int = 256,
                  flip_scalars: bool = False, opacity_unit_distance: float | None = None,
                  support_radius: float | None = None, radius_array: str | None = None,
                  radius_scale: float = 1.0, kernel: str = "cubic",
                  error_tolerance: float = 0.004, backend: str = "auto",
                  adapter: str | None = None, isosurfaces=None,
                  isosurface_field: str = "colour", isosurface_opacity: float = 1.0,
                  isosurface_with_volume: bool = False, shade: bool = True,
                  ambient: float = 0.1, diffuse: float = 0.7, specular: float = 0.2,
                  specular_power: float = 10.0, show_scalar_bar: bool | None = None,
                  scalar_bar_args: dict | None = None, name: str | None = None,
                  reset_camera: bool | None = None, render: bool = True,
                  route: str = "auto"):
    """Adds SPH particles to ``plotter`` as a volume rendered by fluidcast, and returns the
    ``pyvista.Volume`` (its ``mapper`` is the ``vtkFluidCastVolumeMapper``: every property,
    e.g. ``SetKernel``, ``SetRadiusArray``, ``SetBackendToGPU``, stays reachable).

    The arguments follow ``pyvista.Plotter.add_volume``:

    * ``particles``: a ``pyvista.PolyData``/``UnstructuredGrid`` (any ``vtkPointSet``) whose
      points are the particles, or a file path (read with :func:`read`).
    * ``scalars``: a point array's name (default: the active scalars) or one value per
      particle. A vector renders its magnitude, or ``component``.
    * ``clim`` (default: the rendered values' range), ``cmap`` (a matplotlib colour-map name
      or a ``pyvista.LookupTable``; default: the plotter theme's), ``opacity`` (a pyvista
      opacity: "linear", "sigmoid", "geom", ... with "_r" to reverse, a float, or values spread
      over ``clim``), ``n_colors``, ``flip_scalars``, ``show_scalar_bar``,
      ``scalar_bar_args``, ``name``, ``reset_camera``, ``render``.
    * ``opacity_unit_distance`` (world units over which the opacity applies, ParaView's Scalar
      Opacity Unit Distance; default as the CLI: bounds diagonal / cbrt(particles)).

    fluidcast's own settings (the mapper's properties):

    * ``support_radius`` H (world units; the kernel vanishes beyond it) for every particle,
      or ``radius_array`` (per-particle H = ``radius_scale`` × the array); default: the
      data's "support_radius" field data, else twice the mean particle spacing.
    * ``kernel``: one of :func:`kernels` ("cubic", "wendland-c2", ...).
    * ``error_tolerance``: the screen-space error E_I the adaptive renderer keeps below
      (0 renders at full rate).
    * ``backend`` "auto" (a hardware GPU if there is one, else the CPU), "cpu" or "gpu";
      ``adapter``: a GPU adapter's name (part of it).
    * ``isosurfaces``: values (e.g. ``[0.5]``) of ``isosurface_field`` — "colour" (Σ V W,
      V = m/ρ: about 1 inside the fluid, so 0.5 is the free surface), "density" or a point
      array's name — drawn as surfaces coloured by the colour map instead of the volume
      (``isosurface_with_volume``: the volume too, in depth order), with
      ``isosurface_opacity``, lit when ``shade`` with ``ambient``, ``diffuse``, ``specular``
      and ``specular_power`` (pyvista's ``add_volume`` names; a headlight). They render on the
      CPU (the mapper's iso-surface blend mode and the property's iso values, as VTK's GPU
      mapper takes them).

    ``route``: "auto" (the VTK mapper where it is importable, else the module), "mapper" or
    "module" (:mod:`fluidcast.overlay`: rendered by ``fluidcast._core`` and composited into
    the plotter, depth-correctly; returns a :class:`fluidcast.overlay.ParticlesOverlay`).

    Bad input (no points, a missing array, NaN radii, ...) and bad arguments (NaN, inf, a
    negative radius, complex scalars, ...; the same table of settings as the CLI and ParaView
    decides) raise ``ValueError`` naming the argument, and add nothing; the mapper reports
    later problems (data changed to something it cannot render) as VTK errors and draws
    nothing.
    """
    mesh = _point_set(particles)
    mesh, name_ = _scalars(mesh, scalars)
    values = np.asarray(mesh.point_data[name_])
    _check_scalars(values, f"point array '{name_}'")
    iso = _isosurfaces(isosurfaces)
    if opacity_unit_distance is not None:
        opacity_unit_distance = _checked("opacity_unit_distance", "ScalarOpacityUnitDistance",
                                         opacity_unit_distance)
    isosurface_opacity = _checked("isosurface_opacity", "IsoSurfaceOpacity",
                                  isosurface_opacity)
    clim = _clim(_rendered_values(values, component), clim)
    lut = _lookup_table(plotter, cmap, n_colors, flip_scalars, opacity, clim)

    if opacity_unit_distance is None:
        opacity_unit_distance = _default_unit_distance(mesh)
    surfaces = dict(isosurfaces=iso or None, isosurface_field=isosurface_field,
                    isosurface_opacity=isosurface_opacity,
                    isosurface_with_volume=isosurface_with_volume, shade=shade,
                    ambient=ambient, diffuse=diffuse, specular=specular,
                    specular_power=specular_power)
    data = dict(component=component, support_radius=support_radius, radius_array=radius_array,
                radius_scale=radius_scale, kernel=kernel, error_tolerance=error_tolerance,
                backend=backend, adapter=adapter)
    if _route(route) == "module":
        added = _add_through_module(plotter, mesh, name_, data, lut, clim,
                                    opacity_unit_distance, surfaces, name, reset_camera)
    else:
        added = _add_mapper(plotter, mesh, name_, values, data, lut, clim,
                            opacity_unit_distance, surfaces, name, reset_camera)
    if show_scalar_bar is None:
        show_scalar_bar = plotter.theme.show_scalar_bar
    if show_scalar_bar:
        bar = pv.DataSetMapper(theme=plotter.theme)
        bar.lookup_table = lut
        bar.scalar_range = clim
        args = dict(scalar_bar_args or {})
        args.setdefault("title", name_)
        plotter.add_scalar_bar(mapper=bar, **args)
    if render:
        plotter.render()
    return added


def _route(route: str) -> str:
    if route not in ("auto", "mapper", "module"):
        raise ValueError(f"fluidcast.add_particles: route '{route}': auto, mapper or module")
    if route == "mapper" and vtkFluidCastVolumeMapper is None:
        raise ValueError(f"fluidcast.add_particles: route 'mapper': {MAPPER_ERROR}")
    if route == "auto":
        return "mapper" if vtkFluidCastVolumeMapper is not None else "module"
    return route


def _add_mapper(plotter, mesh, name_, values, data, lut, clim, unit_distance, surfaces, name,
                reset_camera) -> pv.Volume:
    """The VTK mapper in a ``pyvista.Volume``."""
    mapper = vtkFluidCastVolumeMapper()
    _configure(mapper, mesh, name_, values, **data)
    errors = _Errors(mapper)  # keeps the mapper's message off the console: it is raised
    ok = mapper.UpdateParticles()
    errors.close()
    if not ok:
        raise ValueError(f"fluidcast.add_particles: {mapper.GetLastError()}")
    prop = vtkVolumeProperty()
    ctf, otf = transfer_functions(lut, clim)
    prop.SetColor(ctf)
    prop.SetScalarOpacity(otf)
    prop.SetScalarOpacityUnitDistance(unit_distance)
    prop.SetInterpolationTypeToLinear()
    prop.SetShade(bool(surfaces["shade"]))
    prop.SetAmbient(surfaces["ambient"])
    prop.SetDiffuse(surfaces["diffuse"])
    prop.SetSpecular(surfaces["specular"])
    prop.SetSpecularPower(surfaces["specular_power"])
    if surfaces["isosurfaces"]:
        for i, v in enumerate(surfaces["isosurfaces"]):
            prop.GetIsoSurfaceValues().SetValue(i, v)
        mapper.SetBlendModeToIsoSurface()
        mapper.SetIsoSurfaceField(surfaces["isosurface_field"])
        mapper.SetIsoSurfaceOpacity(surfaces["isosurface_opacity"])
        mapper.SetIsoSurfaceWithVolume(bool(surfaces["isosurface_with_volume"]))
    volume = pv.Volume()
    volume.mapper = mapper
    volume.prop = prop
    plotter.add_actor(volume, reset_camera=reset_camera, name=name, render=False)
    return volume


def _add_through_module(plotter, mesh, name_, data, lut, clim, unit_distance, surfaces, name,
                        reset_camera):
    """The particles rendered by the Python module and composited into the plotter."""
    from .overlay import ParticlesOverlay

    try:
        scene = api.Scene(mesh, name_, **data)
    except ValueError as e:
        raise ValueError(f"fluidcast.add_particles: {e}") from None
    table = np.asarray(lut.values, dtype=np.float64) / 255.0
    options = dict(cmap=None, tf=None, clim=clim, opacity_unit_distance=unit_distance,
                   isosurfaces=surfaces["isosurfaces"],
                   isosurface_field=surfaces["isosurface_field"],
                   isosurface_opacity=surfaces["isosurface_opacity"],
                   isosurface_with_volume=surfaces["isosurface_with_volume"],
                   shade=surfaces["shade"], ambient=surfaces["ambient"],
                   diffuse=surfaces["diffuse"], specular=surfaces["specular"],
                   specular_power=surfaces["specular_power"], table=table)
    # The field's bounds (the finite points grown by the largest support radius, as the
    # mapper reports them) as an invisible actor, so that the plotter's camera frames them.
    pts = np.asarray(scene.particles.points, dtype=float)
    pts = pts[np.isfinite(pts).all(axis=1)]
    h = scene.info["radius_max"]
    lo, hi = pts.min(0) - h, pts.max(0) + h
    corners = pv.PolyData(np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                                    for z in (lo[2], hi[2])], dtype=float))
    bounds = plotter.add_mesh(corners, opacity=0.0, reset_camera=reset_camera, name=name,
                              render=False, pickable=False)
    return ParticlesOverlay(plotter, scene, options, bounds)
