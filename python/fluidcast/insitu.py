"""In situ rendering: a running simulation hands its particles to ParaView Catalyst every few
steps, and fluidcast's ParaView representation renders them where they are, without particle
files.

    from fluidcast.insitu import InSitu
    insitu = InSitu("out", array="velocity", support_radius=0.1,
                    plugin="build/lib/paraview-plugins/fluidcast/fluidcast.so")
    for step in range(steps):
        simulate()
        if step % 10 == 0:
            insitu.execute(step, t, positions, {"velocity": v, "density": rho, "mass": m})
    insitu.finalize()

The adaptor wraps the numpy arrays as VTK arrays without copying them (float32 and float64
arrays that are C-contiguous; anything else is converted once, and `copies` counts those),
and runs the Catalyst pipeline `fluidcast/catalyst_pipeline.py` through the legacy Catalyst
bridge that ParaView 5.11 ships (`paraview.catalyst.bridge`): the particles shown with the
fluidcast representation, coloured by `array` over a range fixed for the run, written as
`OUTDIR/insitu_%04d.png`. The camera is the given one or, by default, ParaView's reset camera
on the first step's particles, kept for the run; the first step writes what a post-hoc
render needs to draw the same image: `camera.json` (the CLI's `--camera` format), `range.txt`
(`lo,hi`) and `array.txt` (the CLI's `--array`). Under MPI (pvbatch-style symmetric mode:
every rank runs the simulation's script) each rank passes only its own particles.

Must run in ParaView's Python (`paraview` importable: Debian's /usr/bin/python3 or a venv on
it with --system-site-packages) before anything else initialises ParaView.
"""
import json
import math
import os

import numpy as np

#: The Catalyst pipeline script the adaptor runs (a Catalyst 2 style Python script).
PIPELINE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "catalyst_pipeline.py")
#: The environment variable through which the adaptor hands its settings to the pipeline.
CONFIG_ENV = "FLUIDCAST_INSITU_CONFIG"


class InSituError(ValueError):
    """A damaged input to the adaptor (missing array, NaN positions, mismatched lengths)."""


def _vtk_array(name, values, keep):
    """`values` as a VTK array named `name`, sharing numpy's memory where the dtype allows
    (float32, float64, C-contiguous); the numpy array is appended to `keep` so that it lives
    as long as the VTK array. Returns (array, copied)."""
    from vtkmodules.util.numpy_support import numpy_to_vtk

    a = np.asarray(values)
    copied = False
    if a.dtype not in (np.float32, np.float64) or not a.flags["C_CONTIGUOUS"]:
        a = np.ascontiguousarray(a, dtype=np.float32)
        copied = True
    keep.append(a)
    columns = int(np.prod(a.shape[1:])) if a.ndim > 1 else 1
    v = numpy_to_vtk(a if a.ndim == 1 else a.reshape(a.shape[0], columns), deep=False)
    v.SetName(name)
    return v, copied


def particles_grid(positions, arrays, support_radius=None):
    """A vtkUnstructuredGrid of one vertex per particle: `positions` (n x 3) and `arrays`
    (name -> n or n x k values) as point data, the support radius as field data
    `support_radius` (what fluidcast's reader and representation take). Returns the grid,
    the numpy arrays it shares memory with, and how many arrays had to be copied.
    Raises InSituError for NaN or infinite positions and arrays of another length."""
    from vtkmodules.util.numpy_support import numpy_to_vtkIdTypeArray
    from vtkmodules.vtkCommonCore import vtkDoubleArray, vtkPoints
    from vtkmodules.vtkCommonDataModel import VTK_VERTEX, vtkCellArray, vtkUnstructuredGrid

    p = np.asarray(positions)
    if p.ndim != 2 or p.shape[1] != 3:
        raise InSituError(f"positions must be n x 3, got shape {p.shape}")
    n = len(p)
    if n and not np.isfinite(p).all():
        bad = int((~np.isfinite(p).all(axis=1)).sum())
        raise InSituError(f"{bad} of {n} particle positions are NaN or infinite")
    keep, copies = [], 0
    pts, copied = _vtk_array("positions", p, keep)
    copies += copied
    points = vtkPoints()
    points.SetData(pts)
    grid = vtkUnstructuredGrid()
    grid.SetPoints(points)
    conn = np.empty(2 * n, dtype=np.int64)
    conn[0::2] = 1
    conn[1::2] = np.arange(n)
    keep.append(conn)
    cells = vtkCellArray()
    cells.SetCells(n, numpy_to_vtkIdTypeArray(conn, deep=False))
    grid.SetCells(VTK_VERTEX, cells)
    for name, values in arrays.items():
        if len(values) != n:
            raise InSituError(f"array '{name}' has {len(values)} values for {n} particles")
        v, copied = _vtk_array(name, values, keep)
        copies += copied
        grid.GetPointData().AddArray(v)
    if support_radius is not None:
        if not (math.isfinite(support_radius) and support_radius > 0):
            raise InSituError(f"support radius {support_radius} must be a positive number")
        h = vtkDoubleArray()
        h.SetName("support_radius")
        h.InsertNextValue(float(support_radius))
        grid.GetFieldData().AddArray(h)
    return grid, keep, copies


def write_frame(path, positions, arrays, support_radius=None):
    """Writes particles as the adaptor wraps them to a .vtu file (raw appended data): for
    checking in-situ images against `fluidcast render` of the same step."""
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridWriter

    grid, _keep, _ = particles_grid(positions, arrays, support_radius)
    w = vtkXMLUnstructuredGridWriter()
    w.SetFileName(path)
    w.SetInputData(grid)
    w.SetDataModeToAppended()
    w.EncodeAppendedDataOff()
    if not w.Write():
        raise OSError(f"could not write {path}")


class InSitu:
    """The adaptor: one per simulation run (and per rank under MPI).

    outdir: where the images go. array: the point array to colour by (`name` or `name:mag`, as the
    CLI's --array; vectors by magnitude). size: image pixels (w, h). camera: a camera file
    (the CLI's format) or None (reset on the first step). value_range: (lo, hi) or None (the
    first step's range, kept). plugin: the fluidcast ParaView plugin (.so; default
    $FLUIDCAST_PARAVIEW_PLUGIN). support_radius: the particles' support radius (world units)
    when no array gives it. tf: the transfer function, as the CLI's --tf (default Viridis,
    the CLI's default)."""

    def __init__(self, outdir, array, size=(640, 480), camera=None, value_range=None,
                 plugin=None, support_radius=None, background=(1.0, 1.0, 1.0), tf="Viridis"):
        plugin = plugin or os.environ.get("FLUIDCAST_PARAVIEW_PLUGIN")
        if not plugin or not os.path.isfile(plugin):
            raise InSituError(f"the fluidcast ParaView plugin was not found at {plugin!r}: pass "
                              "plugin= or set FLUIDCAST_PARAVIEW_PLUGIN")
        os.makedirs(outdir, exist_ok=True)
        self.outdir = os.path.abspath(outdir)
        self.support_radius = support_radius
        self.copies = 0
        self.array = array.split(":")[0]
        self._keep = []
        name = array.split(":")[0]
        config = {"outdir": self.outdir, "array": name, "size": list(size), "plugin": plugin,
                  "camera": os.path.abspath(camera) if camera else None,
                  "range": list(value_range) if value_range else None,
                  "background": list(background), "tf": tf}
        path = os.path.join(self.outdir, "catalyst_config.json")
        with open(path, "w") as f:
            json.dump(config, f)
        with open(os.path.join(self.outdir, "array.txt"), "w") as f:
            f.write(f"{name}:mag\n")
        os.environ[CONFIG_ENV] = path
        from paraview.catalyst import bridge

        self._bridge = bridge
        bridge.initialize()
        bridge.add_pipeline(PIPELINE, 2)

    @property
    def rank(self):
        """This process's rank (0 without MPI)."""
        from paraview.modules.vtkRemotingCore import vtkProcessModule

        return vtkProcessModule.GetProcessModule().GetPartitionId()

    @property
    def ranks(self):
        """The number of ranks (1 without MPI)."""
        from paraview.modules.vtkRemotingCore import vtkProcessModule

        return vtkProcessModule.GetProcessModule().GetNumberOfLocalPartitions()

    def execute(self, step, time, positions, arrays, support_radius=None):
        """Renders this step's particles: `positions` (n x 3) and `arrays` (name -> values),
        this rank's own (a rank with none passes n = 0). Every rank must call it for every
        rendered step (the render is collective): a rank whose input is damaged (NaN
        positions, an array of another length) still takes part with no particles, so that
        the others do not wait for it, and then raises InSituError naming the problem."""
        h = support_radius or self.support_radius
        try:
            if self.array not in arrays:
                raise InSituError(f"no array '{self.array}' among {sorted(arrays)}")
            grid, keep, copies = particles_grid(positions, arrays, h)
            damaged = None
        except (InSituError, ValueError, TypeError) as e:
            empty = {name: np.zeros((0,) + np.shape(v)[1:], dtype=np.float32)
                     for name, v in arrays.items()}
            empty.setdefault(self.array, np.zeros(0, dtype=np.float32))
            grid, keep, copies = particles_grid(np.zeros((0, 3), np.float32), empty, h)
            damaged = e
        self.copies += copies
        self._keep = keep  # alive until the next step replaces them
        self._bridge.coprocess(float(time), int(step), grid)
        if damaged is not None:
            raise InSituError(f"step {step}, rank {self.rank}: {damaged} (this rank rendered "
                              "no particles)")

    def finalize(self):
        """Ends Catalyst (once, after the last step)."""
        self._bridge.finalize()
