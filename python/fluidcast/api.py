"""fluidcast on numpy, without VTK: read particle files, render particles to images (with
depth) and interpolate their SPH field, through the compiled module ``fluidcast._core``
(the Rust library; the same engine as the VTK mapper and ParaView).

    import fluidcast
    p = fluidcast.read("run/PartFluid_0100.vtu")
    img = fluidcast.render(p, "velocity", size=(800, 600), cmap="viridis")
    img.save("frame.png")                  # as `fluidcast render` writes it
    plt.imshow(img.to_rgb())               # premultiplied RGBA over white, H x W x 3

Arguments follow ``pyvista.Plotter.add_volume`` where pyvista has one (scalars, clim, cmap,
opacity, n_colors, flip_scalars, opacity_unit_distance); fluidcast's own settings take the
names of ``fluidcast.add_particles`` (support_radius, radius_array, kernel,
error_tolerance, backend, ...) and, for the rest, of the library's settings table
(``settings={"relax": 0.5, "tiles": 4}``; see docs/python.md).
"""
from __future__ import annotations

import math
import os
import stat
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import _core

__all__ = ["Image", "Particles", "Scene", "interpolate", "read", "render"]

#: The arguments each setting of the library's table takes in Python, by property.
_ARGUMENTS = {prop: py for prop, _flag, py, _meaning in _core.settings_table() if py}


class Particles:
    """Particles as numpy arrays: ``points`` (N×3, world space), ``point_data`` ({name: N or
    N×k array}) and ``field_data`` ({name: array}); ``path``, ``time`` and ``times`` where
    they came from a file (``times``: a ``.pvd`` series' time steps)."""

    def __init__(self, points, point_data=None, field_data=None, *, path: str = "",
                 time: float | None = None, times=()):
        self.points = np.asarray(points)
        self.point_data = dict(point_data or {})
        self.field_data = dict(field_data or {})
        self.path = str(path)
        self.time = time
        self.times = list(times)

    @property
    def n_points(self) -> int:
        return int(self.points.shape[0]) if self.points.ndim else 0

    def __getitem__(self, name: str) -> np.ndarray:
        return self.point_data[name]

    def __repr__(self) -> str:
        arrays = ", ".join(self.point_data) or "none"
        where = f" from {self.path}" if self.path else ""
        return f"<fluidcast.Particles: {self.n_points} points{where}; point arrays: {arrays}>"


def read(path: str | os.PathLike, step: int = 0, arrays=None) -> Particles:
    """Reads a particle file with fluidcast's checked reader: ``.vtu``, ``.vtp``, legacy
    ``.vtk``, ``.pvtu``/``.pvtp`` (with their pieces) or time step ``step`` of a ``.pvd``
    series (its data sets appended). No VTK is needed. ``arrays``: the names of the point
    arrays to read (default: all; the others are not decoded).

    Raises ``FileNotFoundError`` for a missing file and ``ValueError`` naming the file and the
    problem for a directory, a FIFO, a damaged or lying file."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    mode = path.stat().st_mode
    if stat.S_ISDIR(mode):
        raise ValueError(f"{path}: a directory, not a particle file (give a .vtu, .vtp, .vtk, "
                         ".pvtu or .pvd file in it)")
    if not stat.S_ISREG(mode):
        raise ValueError(f"{path}: not a regular file (a FIFO, socket or device), which "
                         "fluidcast does not read")
    d = _core.read(str(path), int(step), None if arrays is None else [str(a) for a in arrays])
    return Particles(d["points"], d["point_data"], d["field_data"], path=d["path"],
                     time=d["time"], times=d["times"])


@dataclass
class Image:
    """A rendered frame: ``rgba`` (H×W×4 float32, premultiplied linear colour and opacity,
    rows top first), ``depth`` (H×W float32: view depth, world units, where the opacity first
    passed 1/2; +inf elsewhere), ``stats`` (particles, samples, milliseconds, device, notes),
    the ``camera`` (vtkCamera's fields) and the colour map's ``clim``."""

    rgba: np.ndarray
    depth: np.ndarray
    stats: dict
    camera: dict
    clim: tuple[float, float]
    _extra: dict = field(default_factory=dict, repr=False)

    def to_rgb(self, background=(1.0, 1.0, 1.0)) -> np.ndarray:
        """The colour over ``background`` (H×W×3 float32 in 0..1), e.g. for ``imshow``."""
        bg = np.asarray(background, dtype=np.float32)
        return np.clip(self.rgba[..., :3] + (1.0 - self.rgba[..., 3:]) * bg, 0.0, 1.0)

    def to_uint8(self, background=(1.0, 1.0, 1.0)) -> np.ndarray:
        """8-bit RGB over ``background``, as ``fluidcast render`` writes PNGs."""
        return np.round(self.to_rgb(background) * 255.0).astype(np.uint8)

    def save(self, path: str | os.PathLike, background=(1.0, 1.0, 1.0), srgb=False) -> Path:
        """Writes ``.png`` (8-bit over ``background``) or ``.exr`` (float RGBA + Z)."""
        _core.save_image(str(path), np.ascontiguousarray(self.rgba, np.float32),
                         np.ascontiguousarray(self.depth, np.float32),
                         [float(c) for c in background], bool(srgb))
        return Path(path)


def _floats(values, what: str) -> np.ndarray:
    """``values`` as a C-contiguous float32/float64 array: float32 and float64 are passed as
    they are (no copy), anything else converted once."""
    a = np.asarray(values)
    if a.dtype.kind not in "biuf":
        raise ValueError(f"{what}: values of type {a.dtype} (real numbers, integers or "
                         "booleans only)")
    if a.dtype not in (np.float32, np.float64):
        a = a.astype(np.float64)
    return np.ascontiguousarray(a)


def _as_particles(particles, needed=None) -> Particles:
    """Particles from a path (reading the point arrays ``needed`` only, when given), a
    ``Particles``, a pyvista/VTK point set (anything with ``points`` and ``point_data``) or an
    N×3 array."""
    if isinstance(particles, Particles):
        return particles
    if isinstance(particles, (str, os.PathLike)):
        return read(particles, arrays=needed)
    if hasattr(particles, "points") and hasattr(particles, "point_data"):
        fd = getattr(particles, "field_data", {}) or {}
        return Particles(np.asarray(particles.points),
                         {k: np.asarray(particles.point_data[k]) for k in particles.point_data},
                         {k: np.asarray(fd[k]) for k in fd})
    if isinstance(particles, np.ndarray) or isinstance(particles, (list, tuple)):
        return Particles(np.asarray(particles))
    raise TypeError("particles must be a file path, fluidcast.Particles, a pyvista point set "
                    f"or an (N, 3) array, not {type(particles).__name__}")


def _scalars(p: Particles, scalars) -> tuple[dict, str]:
    """The point arrays to hand over and the rendered one's name ("" for none)."""
    if scalars is None:
        return {}, ""
    if isinstance(scalars, str):
        if scalars not in p.point_data:
            names = ", ".join(p.point_data) or "none"
            raise ValueError(f"no point array '{scalars}' in the particles; point arrays: "
                             f"{names}")
        return {scalars: p.point_data[scalars]}, scalars
    values = np.asarray(scalars)
    if values.ndim == 0 or values.shape[0] != p.n_points:
        count = values.shape[0] if values.ndim else 1
        raise ValueError(f"scalars: {count} values for {p.n_points} particles")
    if values.ndim > 2:
        raise ValueError(f"scalars: shape {values.shape}; one value or one vector per "
                         "particle, (N,) or (N, components)")
    return {"scalars": values}, "scalars"


def _checked(argument: str, prop: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{argument} must be a number, not {value!r}") from None
    why = _core.check_setting(prop, v)
    if why:
        raise ValueError(f"{argument}: {why}")
    return v


def _settings(scalars: str, component, support_radius, radius_array, radius_scale, kernel,
              field_, error_tolerance, backend, adapter, mode, extra) -> dict:
    s = dict(extra or {})
    s.update(scalars=scalars, kernel=str(kernel), field=str(field_), mode=str(mode),
             error_tolerance=_checked("error_tolerance", "ErrorTolerance", error_tolerance),
             radius_scale=_checked("radius_scale", "RadiusScale", radius_scale))
    s["component"] = -2 if component is None else int(component)
    if support_radius is not None:
        s["support_radius"] = _checked("support_radius", "SupportRadius", support_radius)
    if radius_array is not None:
        s["radius_array"] = str(radius_array)
    names = _core.names()["backends"]
    if str(backend).lower() not in names:
        raise ValueError(f"backend '{backend}': one of {', '.join(names)}")
    s["backend"] = names.index(str(backend).lower())
    if adapter is not None:
        s["adapter"] = str(adapter)
    return s


def _camera(camera, defaults: dict) -> dict:
    """vtkCamera's fields from None (the CLI's automatic camera), a dict, a vtkCamera or
    pyvista Camera, or a pyvista camera position [(position), (focal point), (view up)]."""
    if camera is None:
        return dict(defaults)
    if isinstance(camera, dict):
        return {**defaults, **camera}
    if hasattr(camera, "GetPosition"):
        return dict(position=camera.GetPosition(), focal_point=camera.GetFocalPoint(),
                    view_up=camera.GetViewUp(), view_angle=camera.GetViewAngle(),
                    parallel_projection=bool(camera.GetParallelProjection()),
                    parallel_scale=camera.GetParallelScale())
    try:
        position, focal, up = (tuple(map(float, v)) for v in camera)
    except (TypeError, ValueError):
        raise ValueError(f"camera: a dict of vtkCamera fields, a vtkCamera or a pyvista "
                         f"camera position [(position), (focal point), (view up)], not "
                         f"{camera!r}") from None
    return {**defaults, "position": position, "focal_point": focal, "view_up": up}


_OPACITY = {
    "linear": lambda x: x,
    "geom": lambda x: (np.geomspace(1e-6, 1.0, x.size) - 1e-6) / (1 - 1e-6),
    "sigmoid": lambda x: 1.0 / (1.0 + np.exp(-10.0 * (x - 0.5))),
}


def _opacity(opacity, n: int) -> np.ndarray:
    """A pyvista-style opacity over ``n`` entries: a name ("linear", "geom", "sigmoid", "_r"
    reversed), a number or values spread over the range."""
    x = np.linspace(0.0, 1.0, n)
    if isinstance(opacity, str):
        name, rev = (opacity[:-2], True) if opacity.endswith("_r") else (opacity, False)
        if name not in _OPACITY:
            raise ValueError(f"opacity '{opacity}': one of {', '.join(_OPACITY)} (with _r to "
                             "reverse), a number or a list of values")
        a = np.asarray(_OPACITY[name](x), dtype=float)
        return a[::-1].copy() if rev else a
    a = np.atleast_1d(np.asarray(opacity, dtype=float))
    if not np.isfinite(a).all():
        raise ValueError(f"opacity: {opacity!r} holds NaN or infinite values")
    if a.size == 1:
        return np.full(n, float(np.clip(a[0], 0.0, 1.0)))
    return np.clip(np.interp(x, np.linspace(0.0, 1.0, a.size), a), 0.0, 1.0)


def _preset(cmap) -> str | None:
    """The fluidcast preset (any case; None: Viridis, the CLI's default) or ParaView preset
    file ``cmap`` names, or None for a matplotlib colour map."""
    if cmap is None:
        return "Viridis"
    presets = {name.lower(): name for name in _core.names()["presets"]}
    if str(cmap).lower() in presets:
        return presets[str(cmap).lower()]
    return str(cmap) if str(cmap).lower().endswith(".json") else None


def _colours(cmap, n: int) -> tuple[np.ndarray, np.ndarray | None]:
    """(n×3 colours, the preset's own opacities or None) of a fluidcast preset (any case), a
    ParaView preset file or a matplotlib colour map."""
    preset = _preset(cmap)
    if preset is not None:
        rgb, alpha = _core.preset_table(preset, n)
        return rgb, alpha
    presets = {name.lower(): name for name in _core.names()["presets"]}
    try:
        import matplotlib
    except ImportError:
        raise ValueError(f"colour map '{cmap}': not one of fluidcast's presets "
                         f"({', '.join(presets.values())}), and matplotlib (for its maps) is "
                         "not installed") from None
    try:
        m = matplotlib.colormaps[str(cmap)]
    except KeyError:
        raise ValueError(f"colour map '{cmap}': neither one of fluidcast's presets "
                         f"({', '.join(presets.values())}) nor a matplotlib colour map") \
            from None
    return np.asarray(m(np.linspace(0.0, 1.0, n))[:, :3], dtype=float), None


def _clim(clim, default: tuple[float, float]) -> tuple[float, float]:
    if clim is None:
        return tuple(map(float, default))
    if np.isscalar(clim):
        clim = (-float(clim), float(clim))
    try:
        lo, hi = map(float, clim)
    except (TypeError, ValueError):
        raise ValueError(f"clim must be two numbers, not {clim!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
        raise ValueError(f"clim must be two finite numbers, low <= high, not {clim!r}")
    return lo, hi


class Scene:
    """Particles with their settings, kept for many renders: the particles are built once,
    and a GPU opened once (what a movie, an orbit or an interactive window wants).

    ``Scene(particles, scalars, **options).render(camera=..., size=...)``; the options are
    :func:`render`'s, the ones about the data and how it is sampled. ``arrays``: point arrays
    to read besides the rendered, radius and volume ones when ``particles`` is a path (e.g. an
    iso-surface's)."""

    def __init__(self, particles, scalars=None, *, component: int | None = None,
                 support_radius: float | None = None, radius_array: str | None = None,
                 radius_scale: float = 1.0, kernel: str = "cubic", field: str = "csph",
                 error_tolerance: float = 0.004, backend: str = "auto",
                 adapter: str | None = None, mode: str = "auto", spp: int | None = None,
                 shadows: bool = False, settings: dict | None = None, arrays=()):
        needed = [a for a in (scalars, radius_array, *arrays) if isinstance(a, str)]
        p = _as_particles(particles, needed + list(_core.names()["volume_arrays"]))
        if p.points.ndim != 2 or p.points.shape[1:] != (3,) or p.n_points == 0:
            raise ValueError(f"particles: points of shape {p.points.shape}; expected (N, 3) "
                             "with N > 0 (the particles are empty)")
        held, name = _scalars(p, scalars)
        if radius_array is not None and radius_array not in p.point_data:
            raise ValueError(f"radius_array: no point array '{radius_array}' in the particles")
        # The float point arrays are held by reference (the build reads only those it needs:
        # the radius, the volumes' and an iso-surface's arrays); others of those converted.
        wanted = set(needed) | set(_core.names()["volume_arrays"])
        for k, v in p.point_data.items():
            dtype = np.asarray(v).dtype
            if k not in held and (dtype in (np.float32, np.float64) or
                                  (k in wanted and dtype.kind in "biu")):
                held[k] = v
        self.particles = p
        self.scalars = name
        self._core = _core.Renderer()
        field_data = {k: float(np.ravel(v)[0]) for k, v in p.field_data.items()
                      if np.size(v) and np.asarray(v).dtype.kind in "biuf"}
        self._core.set_data(p.path or "particles", _floats(p.points, "points"),
                            {k: _floats(v, f"point array '{k}'") for k, v in held.items()},
                            field_data)
        extra = dict(settings or {}, shadows=bool(shadows))
        if spp is not None:
            extra["samples_per_pixel"] = int(_checked("spp", "SamplesPerPixel", spp))
        self._core.configure(_settings(name, component, support_radius, radius_array,
                                       radius_scale, kernel, field, error_tolerance, backend,
                                       adapter, mode, extra))
        self.info = self._core.prepare()
        self.defaults = self._core.defaults()

    def render(self, camera=None, size=(800, 600), *, cmap=None, tf=None, clim=None,
               opacity=None, n_colors: int = 256, flip_scalars: bool = False,
               opacity_unit_distance: float | None = None, isosurfaces=None,
               isosurface_field: str = "colour", isosurface_opacity: float = 1.0,
               isosurface_with_volume: bool = False, shade: bool = True,
               ambient: float = 0.1, diffuse: float = 0.7, specular: float = 0.2,
               specular_power: float = 10.0, depth_limit=None, table=None) -> Image:
        """Renders one view; see :func:`render`. ``table``: an n×4 colour and opacity table
        (0..1) spread over ``clim``, instead of ``cmap``/``opacity`` (a pyvista
        LookupTable's values / 255)."""
        width, height = (int(v) for v in size)
        cam = _camera(camera, self.defaults["camera"])
        self._core.set_camera(**cam)
        lo, hi = _clim(clim, self.defaults["range"])
        unit = self.defaults["unit_distance"] if opacity_unit_distance is None else \
            _checked("opacity_unit_distance", "ScalarOpacityUnitDistance",
                     opacity_unit_distance)
        if table is not None:
            t = np.asarray(table, dtype=float)
            self._core.set_transfer_function(lo, hi, np.ascontiguousarray(t[:, :3]),
                                             np.ascontiguousarray(t[:, 3]), unit)
        else:
            self._transfer(cmap if cmap is not None else tf, opacity, n_colors, flip_scalars,
                           (lo, hi), unit)
        iso = [] if isosurfaces is None else \
            [_checked("isosurfaces", "IsoValue", v) for v in np.atleast_1d(isosurfaces)]
        self._core.set_surfaces(dict(
            iso_values=iso, iso_field=str(isosurface_field), shade=bool(shade),
            opacity=_checked("isosurface_opacity", "IsoSurfaceOpacity", isosurface_opacity),
            with_volume=bool(isosurface_with_volume), ambient=float(ambient),
            diffuse=float(diffuse), specular=float(specular),
            specular_power=float(specular_power)))
        limit = None if depth_limit is None else \
            np.ascontiguousarray(depth_limit, dtype=np.float32)
        rgba, depth, stats = self._core.render(width, height, limit)
        return Image(rgba, depth, stats, cam, (lo, hi))

    def _transfer(self, cmap, opacity, n_colors, flip, clim, unit):
        preset = _preset(cmap)
        if preset is not None and opacity is None and not flip:
            self._core.set_preset(preset, clim[0], clim[1], unit)  # exactly as the CLI's --tf
            return
        n = int(n_colors)
        rgb, own = _colours("Viridis" if cmap is None else cmap, n)
        alpha = own if opacity is None and own is not None else \
            _opacity("linear" if opacity is None else opacity, n)
        if flip:
            rgb, alpha = rgb[::-1], alpha[::-1]
        self._core.set_transfer_function(clim[0], clim[1], np.ascontiguousarray(rgb, float),
                                         np.ascontiguousarray(alpha, float), unit)

    def interpolate(self, points) -> dict:
        """The field at ``points`` (M×3): a dict of M-arrays ``value`` (the scene's field,
        NaN where undefined), ``shepard`` (Σ V W, the colour field), ``density`` (Σ m W)
        and ``neighbours``."""
        pts = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
        return self._core.interpolate(pts)


def render(particles, scalars=None, *, camera=None, size=(800, 600), cmap=None, tf=None,
           clim=None, opacity=None, n_colors: int = 256, flip_scalars: bool = False,
           opacity_unit_distance: float | None = None, isosurfaces=None,
           isosurface_field: str = "colour", isosurface_opacity: float = 1.0,
           isosurface_with_volume: bool = False, shade: bool = True, depth_limit=None,
           **options) -> Image:
    """Renders particles to an :class:`Image` (premultiplied float RGBA, depth, statistics).

    * ``particles``: a file path, :class:`Particles`, a pyvista point set or an N×3 array;
      ``scalars``: a point array's name or one value (or vector) per particle; None renders
      the particle density.
    * ``camera``: None (as ``fluidcast render``: every support in view, looking down -z), a
      dict of vtkCamera's fields, a vtkCamera/pyvista Camera or a camera position
      [(position), (focal point), (view up)]; ``size``: (width, height) pixels.
    * ``cmap``/``tf``: a fluidcast preset ("Viridis", "Inferno", "Cool to Warm",
      "Grayscale"; default Viridis with its own opacity ramp), a ParaView preset ``.json``
      or a matplotlib colour map; ``clim`` (default: the rendered values' range),
      ``opacity`` (pyvista's: "linear", "geom", "sigmoid", "_r", a number or values),
      ``n_colors``, ``flip_scalars``, ``opacity_unit_distance`` (world units; default:
      support-bounds diagonal / cbrt(N)).
    * ``isosurfaces`` (values of ``isosurface_field``: "colour", "density" or an array),
      ``isosurface_opacity``, ``isosurface_with_volume``, ``shade``.
    * ``depth_limit``: H×W view depths past which nothing is composited (opaque geometry).
    * ``options``: :class:`Scene`'s (``support_radius``, ``radius_array``,
      ``radius_scale``, ``kernel``, ``field`` ("csph", "sph", "density", "rbf"),
      ``error_tolerance``, ``backend``, ``adapter``, ``mode``, ``component``, ``spp``
      (the RBF field's and shadows' passes) and ``shadows``, and ``settings`` for the rest of
      the library's settings, e.g. ``{"rbf_classification": "pre", "tiles": 4}``).

    Bad input (NaN radii, wrong-length arrays, a missing array, no points) raises
    ``ValueError`` with the library's message. The GIL is released while it renders."""
    iso_array = () if str(isosurface_field).lower() in ("colour", "color", "density") \
        else (str(isosurface_field),)
    scene = Scene(particles, scalars, arrays=iso_array, **options)
    return scene.render(camera, size, cmap=cmap, tf=tf, clim=clim, opacity=opacity,
                        n_colors=n_colors, flip_scalars=flip_scalars,
                        opacity_unit_distance=opacity_unit_distance, isosurfaces=isosurfaces,
                        isosurface_field=isosurface_field,
                        isosurface_opacity=isosurface_opacity,
                        isosurface_with_volume=isosurface_with_volume, shade=shade,
                        depth_limit=depth_limit)


def interpolate(particles, points, scalars=None, *, field: str = "csph", **options):
    """The SPH field of ``particles`` at ``points`` (M×3, world space) as an M-array:
    ``field`` "csph" (the normalised attribute ``scalars``; NaN where no particle reaches),
    "sph", "density" (Σ m W) or "colour" (Σ V W). ``options``: :class:`Scene`'s (radius,
    kernel). Equals ``fluidcast probe`` at the same points."""
    colour = str(field).lower() in ("colour", "color")
    scene = Scene(particles, scalars, field="csph" if colour else field, **options)
    out = scene.interpolate(points)
    return out["shepard"] if colour else out["value"]
