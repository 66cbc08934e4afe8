"""Peak memory of rendering numpy arrays through the Python module (issue 48).

    .venv-pip/bin/python scripts/module_memory.py FILE ARRAY SUPPORT_RADIUS float32|float64

Writes the file's points and ARRAY's magnitude to .npy files beside FILE (once), then, in a
fresh process with only numpy and the module loaded, renders them at 640x480 on the CPU and
prints the peak resident memory before and after: what the render adds to the arrays the
caller holds.
"""
import subprocess
import sys
from pathlib import Path

import numpy as np

CHILD = """
import resource, sys, numpy as np
from fluidcast import api
dtype = np.dtype(sys.argv[4])
pts = np.load(sys.argv[1]).astype(dtype)
v = np.load(sys.argv[2]).astype(dtype)
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
img = api.render(pts, v, size=(640, 480), support_radius=float(sys.argv[3]), backend="cpu")
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
mib = lambda a: a.nbytes / 2**20
print(f"{dtype.name} input, {len(pts)} particles (points {mib(pts):.0f} MiB, values "
      f"{mib(v):.0f} MiB): peak RSS {base / 1024:.0f} MiB before the render, {peak / 1024:.0f} "
      f"MiB after (+{(peak - base) / 1024:.0f} MiB), {img.stats['total_ms']:.0f} ms")
"""


def arrays(path, array, pts_file, val_file):
    """The .npy files (in their own process: Linux carries a process's peak memory across
    exec, so the measuring child must not descend from one that read the file)."""
    import fluidcast

    p = fluidcast.read(path, arrays=[array])
    values = np.asarray(p[array])
    np.save(pts_file, p.points.astype(np.float32))
    np.save(val_file, (np.linalg.norm(values, axis=1) if values.ndim > 1 else values)
            .astype(np.float32))


def main(path, array, radius, dtype):
    pts_file = Path(path).with_suffix(".points.npy")
    val_file = Path(path).with_suffix(f".{array}.npy")
    if not (pts_file.exists() and val_file.exists()):
        subprocess.run([sys.executable, __file__, "--arrays", path, array, str(pts_file),
                        str(val_file)], check=True)
    subprocess.run([sys.executable, "-c", CHILD, str(pts_file), str(val_file), radius, dtype],
                   check=True)


if __name__ == "__main__":
    if sys.argv[1] == "--arrays":
        arrays(*sys.argv[2:])
    else:
        main(*sys.argv[1:])
