"""Writes rust/fluidcast-view/src/presets_data.rs: the built-in colour maps sampled at 33
points (x, r, g, b) from matplotlib (its perceptual maps viridis, plasma, inferno, magma,
cividis are CC0; turbo is Apache-2.0, Google; jet, hot and rainbow are classic formulas;
twilight and the diverging RdBu, Spectral and seismic are matplotlib's), and the HSV hue sweep
from blue to red that ParaView calls "Blue to Red Rainbow" (a formula, computed here).

    .venv/bin/python scripts/make_presets.py
"""
from pathlib import Path

import matplotlib
import numpy as np

MAPS = {"VIRIDIS": "viridis", "INFERNO": "inferno", "PLASMA": "plasma", "MAGMA": "magma",
        "CIVIDIS": "cividis", "TURBO": "turbo", "JET": "jet", "HOT": "hot",
        "RAINBOW": "rainbow", "TWILIGHT": "twilight", "RDBU": "RdBu", "SPECTRAL": "Spectral",
        "SEISMIC": "seismic"}


def hue_sweep(x):
    """HSV at full saturation and value, hue from blue (2/3) down to red (0)."""
    return matplotlib.colors.hsv_to_rgb(np.stack([(1 - x) * 2 / 3, np.ones_like(x),
                                                  np.ones_like(x)], axis=1))


def table(name: str) -> str:
    x = np.linspace(0.0, 1.0, 33)
    rgb = hue_sweep(x) if name == "hue sweep" else matplotlib.colormaps[name](x)[:, :3]
    values = [f"{v:.6f}" for row in zip(x, *rgb.T) for v in row]
    lines = ["    " + ", ".join(values[i:i + 9]) + "," for i in range(0, len(values), 9)]
    return "\n".join(lines)


def main():
    out = ["//! Colour tables of the built-in presets (written by scripts/make_presets.py from "
           "matplotlib).", ""]
    for const, name in {**MAPS, "BLUE_TO_RED_RAINBOW": "hue sweep"}.items():
        what = "the HSV hue sweep blue to red" if name == "hue sweep" else f"matplotlib's {name}"
        out += [f"/// {what}, sampled at 33 points (x, r, g, b).",
                f"pub const {const}: [f64; 132] = [", table(name), "];", ""]
    path = Path(__file__).resolve().parents[1] / "rust/fluidcast-view/src/presets_data.rs"
    path.write_text("\n".join(out))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
