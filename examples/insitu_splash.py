"""SPlisHSPlasH's double dam break rendered in situ: pysplishsplash steps the simulation in
this process and every EVERY steps hands its particles (positions, velocity, density and
mass, SPlisHSPlasH's own float32 buffers, not copied) to fluidcast.insitu, which renders
them through ParaView Catalyst. No particle files are written unless --write-particles
(for checking the images against `fluidcast render`).

Under MPI (mpiexec -n R) this is a stand-in for a distributed code, because SPlisHSPlasH is
not MPI-parallel: every rank runs the same simulation (single-threaded, so the ranks stay
identical) and hands the adaptor only the particles of its own slab along x, as a
distributed code's rank would its own; rank 0 writes the whole frame with --write-particles.

    LD_PRELOAD=/lib/x86_64-linux-gnu/libGLdispatch.so.0 \\
    FLUIDCAST_PARAVIEW_PLUGIN=build/lib/paraview-plugins/fluidcast/fluidcast.so \\
    .venv-paraview/bin/python examples/insitu_splash.py OUTDIR STEPS [--every N] [--write-particles]

Prints the simulation's time per step and the adaptor's per rendered step (ms and %), and
the process's peak memory.
"""
import argparse
import json
import os
import resource
import sys
import time

import numpy as np


def scene(outdir):
    """SPlisHSPlasH's DoubleDamBreak scene (as pysplishsplash installs it) in OUTDIR/scene,
    beside a link to its models: its paths are relative to the scene file."""
    import pysplishsplash

    data = os.path.join(sys.prefix, "bin", "data")
    if not os.path.isdir(os.path.join(data, "Scenes")):
        data = os.path.join(os.path.dirname(pysplishsplash.__file__), "data")
    with open(os.path.join(data, "Scenes", "DoubleDamBreak.json")) as f:
        s = json.load(f)
    root = os.path.join(outdir, "scene")
    os.makedirs(os.path.join(root, "Scenes"), exist_ok=True)
    models = os.path.join(root, "models")
    try:
        os.symlink(os.path.join(data, "models"), models)
    except FileExistsError:
        pass  # another rank made it
    path = os.path.join(root, "Scenes", "DoubleDamBreak.json")
    tmp = f"{path}.{os.getpid()}"
    with open(tmp, "w") as f:
        json.dump(s, f)
    os.replace(tmp, path)  # atomic: ranks write the same scene side by side
    return path


class Done(Exception):
    """Raised by the time-step callback after the last step."""


def particles(fluid, mass):
    """This step's active particles as numpy views of SPlisHSPlasH's own buffers."""
    n = fluid.numActiveParticles()
    pos = np.asarray(fluid.getFieldBuffer("position"))[:n]
    vel = np.asarray(fluid.getFieldBuffer("velocity"))[:n]
    rho = np.asarray(fluid.getFieldBuffer("density"))[:n]
    return pos, {"velocity": vel, "density": rho, "mass": mass[:n]}


def slab(pos, arrays, rank, ranks, box=(-1.55, 1.55)):
    """The particles of slab `rank` of `ranks` equal slabs of `box` along x (all of them on
    one rank): what one rank of a distributed code owns. Selecting copies them, on the
    simulation's side; the adaptor copies nothing."""
    if ranks == 1:
        return pos, arrays
    edges = np.linspace(box[0], box[1], ranks + 1)
    edges[0], edges[-1] = -np.inf, np.inf
    mine = (pos[:, 0] >= edges[rank]) & (pos[:, 0] < edges[rank + 1])
    return pos[mine], {k: v[mine] for k, v in arrays.items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("outdir")
    ap.add_argument("steps", type=int)
    ap.add_argument("--every", type=int, default=10, help="render every N steps")
    ap.add_argument("--size", default="400x300")
    ap.add_argument("--write-particles", action="store_true")
    a = ap.parse_args()
    import pysplishsplash as sph
    from fluidcast.insitu import InSitu, write_frame

    w, h = (int(x) for x in a.size.split("x"))
    os.makedirs(a.outdir, exist_ok=True)
    base = sph.Exec.SimulatorBase()
    base.init(useGui=False, sceneFile=scene(os.path.abspath(a.outdir)),
              outputDir=os.path.join(os.path.abspath(a.outdir), f"splash_{os.getpid()}"),
              initialPause=False,
              stopAt=1.0e6)
    base.initSimulation()
    sim = sph.Simulation.getCurrent()
    fluid = sim.getFluidModel(0)
    mass = np.full(fluid.numParticles(), fluid.getMass(0), dtype=np.float32)
    h_support = sim.getSupportRadius()
    insitu = InSitu(a.outdir, "velocity", size=(w, h), support_radius=h_support)
    rank, ranks = insitu.rank, insitu.ranks
    tm = sph.TimeManager.getCurrent()
    clock = {"step": 0, "sim": 0.0, "render": 0.0, "renders": 0, "t": time.perf_counter()}

    def after_step():
        """SPlisHSPlasH's time-step callback: every --every steps, the particles in situ;
        after the last step, the run stops at the current time."""
        now = time.perf_counter()
        clock["sim"] += now - clock["t"]
        step = clock["step"]
        if step % a.every == 0:
            pos, arrays = particles(fluid, mass)
            if a.write_particles and rank == 0:
                path = os.path.join(a.outdir, f"step_{step:04d}.vtu")
                write_frame(path, pos, arrays, h_support)
                now = time.perf_counter()  # writing is for checking, not the adaptor's cost
            insitu.execute(step, tm.getTime(), *slab(pos, arrays, rank, ranks))
            clock["renders"] += 1
        clock["step"] = step + 1
        clock["render"] += time.perf_counter() - now
        clock["t"] = time.perf_counter()
        if clock["step"] >= a.steps:
            raise Done()  # pysplishsplash has no stop call: leave its run loop

    base.setTimeStepCB(after_step)
    try:
        base.runSimulation()
    except Done:
        pass
    sim_s, render_s, renders = clock["sim"], clock["render"], clock["renders"]
    insitu.finalize()
    base.cleanup()
    per_step = 1e3 * sim_s / max(a.steps, 1)
    per_render = 1e3 * render_s / max(renders, 1)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"rank {rank} of {ranks}: simulation: {a.steps} steps, {per_step:.1f} ms/step; "
          f"in situ: {renders} renders, {per_render:.1f} ms each "
          f"({100 * per_render / (a.every * per_step):.0f} % of the "
          f"{a.every} steps between renders); arrays copied by the adaptor: {insitu.copies}; "
          f"peak memory {peak:.0f} MiB")


if __name__ == "__main__":
    main()
