"""Damaged input to fluidcast.insitu under MPI (run with mpiexec -n 2): on rank 1, step 1
passes NaN positions, step 2 leaves out the rendered array, step 3 passes no particles;
rank 0 always passes a good block of particles. Each damaged step must raise InSituError on
rank 1 only, naming the problem, while rank 0 renders its image: no rank waits for another.

    mpiexec -n 2 python insitu_damaged.py PLUGIN OUTDIR
Exit code 0 pass, 1 fail.
"""
import os
import sys

import numpy as np
from fluidcast.insitu import InSitu, InSituError

plugin, out = sys.argv[1:3]
insitu = InSitu(out, "velocity", size=(160, 120), plugin=plugin, support_radius=0.1)
rank = insitu.rank
g = np.stack(np.meshgrid(*[np.arange(10) * 0.04] * 3, indexing="ij"), -1).reshape(-1, 3)
pos = (g + [0.5 * rank, 0.0, 0.0]).astype(np.float32)
good = {"velocity": np.linalg.norm(pos, axis=1).astype(np.float32),
        "density": np.full(len(pos), 1000.0, np.float32),
        "mass": np.full(len(pos), 0.064, np.float32)}
bad_pos = pos.copy()
bad_pos[7] = np.nan
steps = [
    (pos, good, None),
    (bad_pos, good, "NaN or infinite"),
    (pos, {k: v for k, v in good.items() if k != "velocity"}, "no array 'velocity'"),
    (np.zeros((0, 3), np.float32), {k: v[:0] for k, v in good.items()}, None),
]
status = 0
for step, (p, arrays, want) in enumerate(steps):
    damaged = want if rank == 1 else None
    try:
        insitu.execute(step, 0.1 * step, p if rank == 1 else pos, arrays if rank == 1 else good)
        got = None
    except InSituError as e:
        got = str(e)
    ok = (got is None) if damaged is None else (got is not None and damaged in got)
    print(f"rank {rank} step {step}: {'ok' if ok else 'FAIL'} ({got or 'rendered'})", flush=True)
    status |= not ok
insitu.finalize()
if rank == 0:
    images = sorted(f for f in os.listdir(out) if f.startswith("insitu_") and f.endswith(".png"))
    print(f"images: {images}")
    status |= len(images) != len(steps)
sys.exit(status)
