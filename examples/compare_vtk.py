#!/usr/bin/env python3
"""Render one particle file four ways and put them side by side.

    .venv/bin/python examples/compare_vtk.py DATA.vtu --array velocity:mag [--out DIR]

One dataset, one camera, one transfer function, rendered with

  (a) VTK's own SPH pipeline: vtkSPHInterpolator onto a vtkImageData grid (one image per
      --resolution), then vtkSmartVolumeMapper;
  (b) Point Gaussian splats (pyvista, style='points_gaussian');
  (c) fluidcast, reference and adaptive modes (the CLI);
  (d) with --iso V (default 0.5; "none" skips it), the free surface: fluidcast's
      ``render --iso V`` beside VTK's vtkFlyingEdges3D contour of the colour field Σ V W
      resampled by vtkSPHInterpolator (one per --resolution), both white under a headlight
      with vtkProperty's Ambient 0.1, Diffuse 0.7, Specular 0.2, SpecularPower 10 (a third
      row in the figure, rows "surface: ..." in the table, differences to fluidcast's surface).

Writes to DIR: each image as PNG, ``figure.png`` (the images in a row, the difference to
fluidcast's reference below each), ``table.md`` and ``table.json`` (wall time to image,
max abs / RMSE / 99th percentile vs fluidcast's reference, memory of the intermediate grid),
and the ``camera.json`` and ``tf.json`` fluidcast used (made from the VTK camera and transfer
function with the fluidcast package's helpers, fluidcast.camera and fluidcast.transfer).

Differences are in 0..1 on the 8-bit images (PNG as VTK writes screenshots). Timings are
wall-clock seconds on this machine, including reading the file; run on a quiet machine and
compare ratios, not absolute numbers.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import time
from pathlib import Path

import numpy as np
from fluidcast.camera import load_camera, reset_camera, save_camera
from fluidcast.cli import fluidcast_binary, run_fluidcast
from fluidcast.data import point_array, read_points, support_radius, volume_arrays
from fluidcast.images import difference, read_png, write_png
from fluidcast.transfer import matplotlib_tf, preset_to_vtk, rescaled, tf_to_preset
from fluidcast.vtk_sph import (
    VTK_KERNELS,
    colour_field,
    render_iso_surface,
    render_splats,
    render_volume,
    sph_volume,
)


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("data", type=Path, help="a .vtu, .vtp or legacy .vtk particle file")
    p.add_argument("--array", required=True, help="NAME, NAME:mag or NAME:K (as fluidcast)")
    p.add_argument("--out", type=Path, default=Path("compare_vtk_out"),
                   help="output folder (default: ./compare_vtk_out)")
    p.add_argument("--size", default="800x600", help="image size WxH in pixels")
    p.add_argument("--resolution", default="128,256",
                   help="VTK grid points along the longest side, comma separated")
    p.add_argument("--kernel", default="cubic", choices=list(VTK_KERNELS))
    p.add_argument("--support-radius", type=float,
                   help="support radius H in world units (default: the file's support_radius "
                        "field data, else fluidcast's suggestion)")
    p.add_argument("--radius-array", help="per-particle radius array (must be constant: VTK's "
                                          "interpolator takes one spatial step)")
    p.add_argument("--radius-scale", type=float, default=1.0,
                   help="H = scale x radius array (PySPH's h with cubic: 2)")
    p.add_argument("--cmap", default="viridis", help="matplotlib colour map name")
    p.add_argument("--opacity", default="0.05,0.3,0.8",
                   help="opacity at evenly spaced values over the range (pyvista's opacity=[...])")
    p.add_argument("--tf", type=Path, help="a ParaView colour-map preset .json instead of "
                                           "--cmap/--opacity")
    p.add_argument("--range", help="lo,hi of the colour map (default: the array's range)")
    p.add_argument("--opacity-unit-distance", type=float,
                   help="world distance the opacity applies to (default: bounds diagonal / "
                        "cube root of the particle count, fluidcast's default)")
    p.add_argument("--azimuth", type=float, default=30.0)
    p.add_argument("--elevation", type=float, default=25.0)
    p.add_argument("--zoom", type=float, default=1.0)
    p.add_argument("--camera", type=Path, help="camera JSON (vtkCamera fields) instead of "
                                               "ResetCamera + azimuth/elevation/zoom")
    p.add_argument("--error-tolerance", default="0.004",
                   help="fluidcast adaptive mode's E_I (default 0.004)")
    p.add_argument("--background", default="1,1,1", help="r,g,b in 0..1")
    p.add_argument("--splat-radius", type=float,
                   help="Point Gaussian radius in world units (default H/2)")
    p.add_argument("--iso", default="0.5",
                   help="colour-field iso value of the surface row, or 'none' (default 0.5)")
    p.add_argument("--no-figure", action="store_true", help="skip figure.png (no matplotlib)")
    return p.parse_args(argv)


def numbers(s, n=None, name="value"):
    v = [float(x) for x in s.split(",")]
    if n is not None and len(v) != n:
        raise SystemExit(f"{name} '{s}': expected {n} comma-separated numbers")
    return v


def radius_of(ds, path, a, binary) -> float:
    if a.support_radius is not None:
        if not a.support_radius > 0:
            raise SystemExit(f"--support-radius {a.support_radius}: must be > 0")
        return a.support_radius
    if a.radius_array:
        r = point_array(ds, a.radius_array) * a.radius_scale
        if r.max() - r.min() > 1e-9 * max(abs(r.max()), 1e-30):
            raise SystemExit(
                f"{path}: '{a.radius_array}' varies ({r.min():g} to {r.max():g}); VTK's "
                "vtkSPHInterpolator takes one spatial step, so pass --support-radius")
        return float(r[0])
    return support_radius(ds, path, binary)


def run(a) -> dict:
    """Renders everything and writes the outputs; returns the table as a dict."""
    path = a.data
    if not path.exists():
        raise SystemExit(f"{path}: no such file")
    out = a.out
    out.mkdir(parents=True, exist_ok=True)
    try:
        w, h = (int(x) for x in a.size.lower().split("x"))
    except ValueError:
        raise SystemExit(f"--size '{a.size}': expected WxH, e.g. 800x600") from None
    if not (0 < w <= 16384 and 0 < h <= 16384):
        raise SystemExit(f"--size '{a.size}': each side must be 1..16384 pixels")
    size = (w, h)
    background = numbers(a.background, 3, "--background")
    binary = fluidcast_binary(Path(__file__).resolve().parents[1], build=True)
    print(f"fluidcast binary: {binary}")

    t0 = time.perf_counter()
    ds = read_points(path)
    vtk_read_s = time.perf_counter() - t0
    values = point_array(ds, a.array)
    n = len(values)
    if a.range:
        lo, hi = numbers(a.range, 2, "--range")
    else:
        lo, hi = float(values.min()), float(values.max())
    if not hi > lo:
        hi = lo + 1.0
    H = radius_of(ds, path, a, binary)
    mass, density = volume_arrays(ds)
    b = np.array(ds.GetBounds()).reshape(3, 2)
    unit = a.opacity_unit_distance or float(np.linalg.norm(b[:, 1] - b[:, 0]) / np.cbrt(n))
    print(f"{path.name}: {n} particles, H = {H:g}, {a.array} in [{lo:g}, {hi:g}], "
          f"opacity unit distance {unit:g}, volumes from "
          f"{f'{mass}/{density}' if mass else 'uniform'}")

    if a.camera:
        cam = load_camera(a.camera)
    else:
        grown = np.c_[b[:, 0] - H, b[:, 1] + H].ravel()
        cam = reset_camera(grown, a.azimuth, a.elevation, a.zoom, size)
    cam_file = save_camera(cam, out / "camera.json")
    if a.tf:
        preset = json.loads(a.tf.read_text())
        ctf, otf = preset_to_vtk(preset)
        # Rescale the preset onto [lo, hi] as fluidcast and ParaView do.
        ctf, otf = rescaled(ctf, otf, lo, hi)
    else:
        ctf, otf = matplotlib_tf(a.cmap, lo, hi, numbers(a.opacity, name="--opacity"))
    tf_file = out / "tf.json"
    tf_file.write_text(json.dumps([tf_to_preset(ctf, otf, name="compare_vtk")], indent=1))

    rows = []
    images = {}

    # fluidcast: reference and adaptive, timed as a user would see them (process wall time).
    common = ["render", path, "--array", a.array, "--tf", tf_file, "--range", f"{lo},{hi}",
              "--camera", cam_file, "--size", f"{w}x{h}", "--opacity-unit-distance", unit,
              "--support-radius", H, "--kernel", a.kernel, "--background", a.background]
    common += (["--mass-array", mass, "--density-array", density] if mass
               else ["--uniform-volume"])
    for mode, extra in (("reference", ["--mode", "reference"]),
                        ("adaptive", ["--error-tolerance", a.error_tolerance])):
        png = out / f"fluidcast_{mode}.png"
        stats = out / f"fluidcast_{mode}.stats.json"
        t = time.perf_counter()
        run_fluidcast(*common, *extra, "--stats", stats, "-o", png, binary=binary)
        wall = time.perf_counter() - t
        st = json.loads(stats.read_text())
        st = st[0] if isinstance(st, list) else st
        images[f"fluidcast {mode}"] = read_png(png)
        rows.append(dict(method=f"fluidcast {mode}", image=png.name, wall_s=wall,
                         resample_s=None, render_s=st["timings"]["total_ms"] / 1e3,
                         grid_mb=None))
        print(f"  fluidcast {mode:9s} {wall:7.2f} s wall ({st['timings']['total_ms']:.0f} ms "
              f"render)")
    ref = images["fluidcast reference"]

    # VTK's SPH interpolator + volume mapper, per grid resolution.
    null = lo - 0.01 * (hi - lo)
    for res in (int(r) for r in a.resolution.split(",")):
        vol = sph_volume(ds, values, a.kernel, H, res, null, mass, density)
        img, render_s = render_volume(vol, cam, ctf, otf, unit, size, background)
        name = f"VTK SPH {res}"
        png = out / f"vtk_sph_{res}.png"
        write_png(png, img)
        images[name] = img
        dims = "x".join(map(str, vol.image.GetDimensions()))
        rows.append(dict(method=f"{name} ({dims}, spacing {vol.image.GetSpacing()[0]:.3g})",
                         image=png.name, wall_s=vtk_read_s + vol.seconds + render_s,
                         resample_s=vol.seconds, render_s=render_s, grid_mb=vol.bytes / 2**20))
        print(f"  {name:20s} {rows[-1]['wall_s']:7.2f} s wall (resample {vol.seconds:.2f} s, "
              f"render {render_s:.2f} s), grid {dims} = {vol.bytes / 2**20:.1f} MiB")

    # Point Gaussian splats.
    radius = a.splat_radius or H / 2
    img, s = render_splats(ds, values, cam, a.cmap if not a.tf else "viridis", (lo, hi),
                              radius, size=size, background=background)
    png = out / "splats.png"
    write_png(png, img)
    images["Point Gaussian"] = img
    rows.append(dict(method=f"Point Gaussian splats (radius {radius:.3g})", image=png.name,
                     wall_s=vtk_read_s + s, resample_s=None, render_s=s, grid_mb=None))
    print(f"  Point Gaussian       {rows[-1]['wall_s']:7.2f} s wall")

    for r, img in zip(rows, images.values()):
        r.update(difference(img, ref))
    surfaces = {}
    if a.iso.lower() != "none":
        surface_rows, surfaces = surface_row(a, ds, common, binary, cam, size, background, H,
                                             (mass, density))
        rows += surface_rows
    table = dict(data=str(path), array=a.array, particles=n, support_radius=H,
                 size=[w, h], range=[lo, hi], opacity_unit_distance=unit, rows=rows)
    (out / "table.json").write_text(json.dumps(table, indent=1))
    (out / "table.md").write_text(markdown(table))
    print(markdown(table))
    if not a.no_figure:
        figure(images, ref, [r["rmse"] for r in rows], out / "figure.png",
               f"{path.name}: {a.array}", surfaces)
        print(f"wrote {out / 'figure.png'}")
    return table


def markdown(table) -> str:
    def f(v, fmt):
        return "—" if v is None else format(v, fmt)

    lines = [f"**{Path(table['data']).name}**, `{table['array']}`, {table['particles']} "
             f"particles, H = {table['support_radius']:.4g}, {table['size'][0]}x"
             f"{table['size'][1]} px. Differences vs fluidcast reference, in 0..1 (8-bit).",
             "",
             "| method | wall time to image (s) | resample (s) | render (s) | max abs | RMSE "
             "| p99 | intermediate grid (MiB) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in table["rows"]:
        lines.append(f"| {r['method']} | {r['wall_s']:.2f} | {f(r['resample_s'], '.2f')} | "
                     f"{f(r['render_s'], '.2f')} | {r['max_abs']:.3f} | {r['rmse']:.4f} | "
                     f"{r['p99']:.3f} | {f(r['grid_mb'], '.1f')} |")
    return "\n".join(lines) + "\n"


def crop_box(images, pad=12):
    """Rows and columns that hold anything but the background (the top-left pixel), over
    all images, grown by ``pad`` pixels: the figure shows the data, not empty margins."""
    mask = np.zeros(next(iter(images.values())).shape[:2], bool)
    for img in images.values():
        mask |= (img != img[0, 0]).any(axis=2)
    if not mask.any():
        return slice(None), slice(None)
    rows, cols = np.flatnonzero(mask.any(1)), np.flatnonzero(mask.any(0))
    return (slice(max(rows[0] - pad, 0), rows[-1] + pad + 1),
            slice(max(cols[0] - pad, 0), cols[-1] + pad + 1))


def surface_row(a, ds, common, binary, cam, size, background, H, volumes):
    """fluidcast's iso-surface of the colour field and VTK's contours of it (white, the same
    headlight and coefficients); returns the table rows (differences to fluidcast's surface)
    and the images by name."""
    iso = numbers(a.iso, 1, "--iso")[0]
    out = a.out
    png = out / "fluidcast_surface.png"
    t = time.perf_counter()
    run_fluidcast(*common, "--iso", iso, "--iso-color", "1,1,1", "-o", png, binary=binary)
    images = {"fluidcast surface": read_png(png)}
    rows = [dict(method=f"surface: fluidcast --iso {iso:g}", image=png.name,
                 wall_s=time.perf_counter() - t, resample_s=None, render_s=None, grid_mb=None)]
    print(f"  fluidcast surface    {rows[-1]['wall_s']:7.2f} s wall")
    for res in (int(r) for r in a.resolution.split(",")):
        t = time.perf_counter()
        vol = colour_field(ds, a.kernel, H, res, *volumes)
        img = render_iso_surface(vol, iso, cam, size=size, background=background)
        name = f"VTK contour {res}"
        png = out / f"vtk_contour_{res}.png"
        write_png(png, img)
        images[name] = img
        rows.append(dict(method=f"surface: {name} (vtkFlyingEdges3D)", image=png.name,
                         wall_s=time.perf_counter() - t, resample_s=vol.seconds, render_s=None,
                         grid_mb=vol.bytes / 2**20))
        print(f"  {name:20s} {rows[-1]['wall_s']:7.2f} s wall")
    for r, img in zip(rows, images.values()):
        r.update(difference(img, images["fluidcast surface"]))
    return rows, images


def figure(images, ref, rmse, path, title, surfaces=None):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    box = crop_box(images)
    images = {n: i[box] for n, i in images.items()}
    ref = ref[box]
    surfaces = {n: i[box] for n, i in (surfaces or {}).items()}
    k = max(len(images), len(surfaces))
    nrows = 3 if surfaces else 2
    aspect = ref.shape[0] / ref.shape[1]
    fig, ax = plt.subplots(nrows, k, figsize=(3.2 * k + 1.2, nrows * 3.2 * aspect + 1.0),
                           squeeze=False, layout="constrained")
    for c in range(k):
        for r in range(nrows):
            ax[r, c].set_xticks([])
            ax[r, c].set_yticks([])
            ax[r, c].axis("on" if (r < 2 and c < len(images)) or
                          (r == 2 and c < len(surfaces)) else "off")
    for c, (name, img) in enumerate(surfaces.items()):
        ax[2, c].imshow(img)
        ax[2, c].set_title(name, fontsize=9)
    diffs = {n: np.abs(i.astype(float) - ref.astype(float)).max(axis=2) / 255
             for n, i in images.items()}
    vmax = max(0.05, max(np.percentile(d, 99.5) for d in diffs.values()))
    for c, ((name, img), e) in enumerate(zip(images.items(), rmse)):
        ax[0, c].imshow(img)
        ax[0, c].set_title(name, fontsize=9)
        im = ax[1, c].imshow(diffs[name], cmap="magma", vmin=0, vmax=vmax)
        ax[1, c].set_title(f"|diff| (whole image RMSE {e:.4f})", fontsize=8)
    fig.colorbar(im, ax=ax[:, -1].tolist(), shrink=0.8, label="|difference| vs fluidcast "
                 "reference (max channel, 0..1)")
    fig.suptitle(title)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    a = parse_args(argv)
    try:
        run(a)
    except KeyError as e:
        raise SystemExit(f"compare_vtk: {a.data}: {e.args[0]}") from None
    except (ValueError, RuntimeError, OSError, subprocess.CalledProcessError) as e:
        raise SystemExit(f"compare_vtk: {e}") from None


if __name__ == "__main__":
    main()
