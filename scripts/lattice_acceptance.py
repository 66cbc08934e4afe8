"""How much of a full-rate image the image-space refinement could interpolate, and what it
would cast, for two first passes: the lattice fluidcast casts (every second pixel of every
second row, the others from Catmull–Rom midpoints of four lattice pixels per line) and
every second row (the others from four pixels of their column). A pixel between lattice
pixels is counted as accepted when, along every line of its stencil and in every channel,
both second differences are at most 2 E_I: the rule of `fluidcast_render::interpolate`
without its silhouette, depth and per-bundle checks, so an upper bound on what it accepts.

    python scripts/lattice_acceptance.py FULL_RATE.exr [--tolerance 0.004]

FULL_RATE.exr: `fluidcast render FILE ... --error-tolerance off -o FULL_RATE.exr`. Needs
`numpy` and the `OpenEXR` module (`pip install numpy OpenEXR`); a development measurement
(docs/performance.md, 2026-12-06 (second)), not part of the test suite.

Prints, over the pixels that hold fluid (alpha > 0): the candidates each scheme would
interpolate, the share accepted, the share of the fluid's pixels it would cast (first pass
plus the rejected), and the share accepted yet further than E_I from the full-rate value
(what the refinement's recheck must catch).
"""
import argparse

import numpy as np
import OpenEXR

CATMULL_ROM = np.array([-1.0, 9.0, 9.0, -1.0]) / 16.0


def load(path: str) -> np.ndarray:
    """The premultiplied RGBA of an EXR written by fluidcast, (height, width, 4) float64."""
    f = OpenEXR.File(path)
    return np.asarray(f.parts[0].channels["RGBA"].pixels, dtype=np.float64)


def smooth(taps: np.ndarray, e: float) -> np.ndarray:
    """Taps (..., 4, channels): both second differences at most 2 E_I in every channel."""
    d1 = np.abs(taps[..., 0, :] - 2 * taps[..., 1, :] + taps[..., 2, :])
    d2 = np.abs(taps[..., 1, :] - 2 * taps[..., 2, :] + taps[..., 3, :])
    return np.maximum(d1, d2).max(-1) <= 2 * e


def lattice(img: np.ndarray, fluid: np.ndarray, e: float):
    """The 2 × 2 lattice: candidates, accepted and estimates (pixels 3 from the edge)."""
    h, w, _ = img.shape
    cand = np.zeros((h, w), bool)
    acc = np.zeros((h, w), bool)
    est = np.zeros_like(img)
    for j in range(3, h - 4):
        for i in range(3, w - 4):
            if (i % 2 == 0 and j % 2 == 0) or not fluid[j, i]:
                continue
            cols = [i] if i % 2 == 0 else [i - 3, i - 1, i + 1, i + 3]
            rows = [j] if j % 2 == 0 else [j - 3, j - 1, j + 1, j + 3]
            block = img[np.ix_(rows, cols)]
            ok = True
            if len(cols) == 4:
                ok &= bool(smooth(block, e).all())
            if len(rows) == 4:
                ok &= bool(smooth(np.swapaxes(block, 0, 1), e).all())
            wr = CATMULL_ROM if len(rows) == 4 else np.ones(1)
            wc = CATMULL_ROM if len(cols) == 4 else np.ones(1)
            cand[j, i], acc[j, i] = True, ok
            est[j, i] = np.einsum("r,c,rck->k", wr, wc, block)
    return cand, acc, est


def rows(img: np.ndarray, fluid: np.ndarray, e: float):
    """Every second row: candidates, accepted and estimates (rows 3 from the edge)."""
    h, w, _ = img.shape
    cand = np.zeros((h, w), bool)
    acc = np.zeros((h, w), bool)
    est = np.zeros_like(img)
    for j in range(3, h - 4, 2):
        taps = np.swapaxes(img[[j - 3, j - 1, j + 1, j + 3]], 0, 1)
        cand[j] = fluid[j]
        acc[j] = smooth(taps, e) & fluid[j]
        est[j] = np.einsum("t,wtk->wk", CATMULL_ROM, taps)
    return cand, acc, est


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("image")
    ap.add_argument("--tolerance", type=float, default=0.004)
    a = ap.parse_args()
    img = load(a.image)
    fluid = img[..., 3] > 0
    n = int(fluid.sum())
    print(f"{a.image}: {n} pixels hold fluid, E_I = {a.tolerance}")
    for name, scheme in (("2x2 lattice", lattice), ("every 2nd row", rows)):
        cand, acc, est = scheme(img, fluid, a.tolerance)
        miss = acc & (np.abs(est - img).max(-1) > a.tolerance)
        cast = n - int(acc.sum())
        print(f"  {name}: {int(cand.sum())} candidates, {acc.sum() / cand.sum():.1%} accepted; "
              f"casts {cast / n:.1%} of the fluid's pixels; accepted and > E_I: "
              f"{miss.sum() / n:.2%} of them")


if __name__ == "__main__":
    main()
