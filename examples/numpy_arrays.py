"""Render SPH particles straight from numpy arrays (no files, no VTK) into a matplotlib figure.

    python examples/numpy_arrays.py figure.png

The arrays here come from a column of water at rest, laid out on a lattice (what a solver's
initial condition is); a solver running in Python hands over its own arrays the same way:

* PySPH (a ``ParticleArray`` ``fluid``; ``h`` is the smoothing length, the support is 2h
  for its cubic spline)::

      pts = np.column_stack([fluid.x, fluid.y, fluid.z])
      speed = np.sqrt(fluid.u**2 + fluid.v**2 + fluid.w**2)
      p = fluidcast.Particles(pts, {"speed": speed, "h": fluid.h, "m": fluid.m,
                                    "rho": fluid.rho})
      img = fluidcast.render(p, "speed", radius_array="h", radius_scale=2)

* SPlisHSPlasH's pysplishsplash (``f = sim.getFluidModel(0)``)::

      n = f.numActiveParticles()
      pts = np.array([f.getPosition(i) for i in range(n)])   # one vector per call
      img = fluidcast.render(pts, support_radius=sim.getSupportRadius())

Pass float32 or float64 arrays: fluidcast reads them in place (other dtypes are converted
once). Rendering many frames of the same particles, keep a ``fluidcast.Scene``.
"""
import sys

import fluidcast
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def water_column(spacing=0.02):
    """A 0.4 x 0.8 x 0.4 column of particles at rest, with a hydrostatic pressure."""
    axes = [np.arange(0.0, side, spacing) for side in (0.4, 0.8, 0.4)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    rho = 1000.0
    pressure = rho * 9.81 * (0.8 - pts[:, 1])
    mass = np.full(len(pts), rho * spacing**3)
    return pts.astype(np.float32), pressure.astype(np.float32), mass, rho


def main(out="figure.png"):
    pts, pressure, mass, rho = water_column()
    particles = fluidcast.Particles(pts, {"pressure": pressure, "mass": mass,
                                          "density": np.full(len(pts), rho)})
    camera = dict(position=(1.6, 1.2, 1.9), focal_point=(0.2, 0.4, 0.2), view_up=(0, 1, 0),
                  view_angle=30.0)
    img = fluidcast.render(particles, "pressure", camera=camera, size=(480, 480),
                           cmap="viridis", opacity=[0.0, 0.3, 0.8], support_radius=0.04)
    fig, ax = plt.subplots(figsize=(5, 4.4))
    shown = ax.imshow(img.to_rgb(), extent=(0, 1, 0, 1))
    shown.set_cmap("viridis")
    shown.set_clim(*img.clim)
    fig.colorbar(shown, ax=ax, label="pressure (Pa)")
    ax.set_axis_off()
    ax.set_title(f"{img.stats['particles']} particles, {img.stats['total_ms']:.0f} ms")
    fig.savefig(out, dpi=100)
    print(f"wrote {out}: {img.stats['particles']} particles rendered in "
          f"{img.stats['total_ms']:.0f} ms on {img.stats['device']}")
    return img


if __name__ == "__main__":
    main(*sys.argv[1:2])
