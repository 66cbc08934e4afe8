"""Running the ``fluidcast`` command-line renderer from Python."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path


def fluidcast_binary(checkout: Path | None = None, build: bool = False) -> Path:
    """The ``fluidcast`` executable.

    Looked up in this order: ``$FLUIDCAST_BIN``; with ``checkout`` (a source checkout's
    root), its ``target/release`` then ``target/debug`` build (``build=True`` runs
    ``cargo build --release`` there when neither exists); the one ``pip install`` put beside
    this Python; ``fluidcast`` on ``PATH``.
    """
    env = os.environ.get("FLUIDCAST_BIN")
    if env:
        return Path(env)
    if checkout is not None:
        for profile in ("release", "debug"):
            p = Path(checkout) / "target" / profile / "fluidcast"
            if p.exists():
                return p
        if build:
            subprocess.run(["cargo", "build", "--release", "--bin", "fluidcast"],
                           cwd=checkout, check=True)
            return Path(checkout) / "target" / "release" / "fluidcast"
    beside = Path(sys.executable).parent / "fluidcast"
    if beside.exists():
        return beside
    found = shutil.which("fluidcast")
    if found:
        return Path(found)
    raise FileNotFoundError(
        "no fluidcast executable: set FLUIDCAST_BIN, put it on PATH, or build it with "
        "`cargo build --release --bin fluidcast` in a fluidcast checkout")


def run_fluidcast(*args, binary: Path | None = None) -> subprocess.CompletedProcess:
    """Runs the CLI with ``args``; raises ``RuntimeError`` carrying its stderr when it fails."""
    cmd = [str(binary or fluidcast_binary()), *map(str, args)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({r.returncode}):\n{r.stderr}")
    return r
