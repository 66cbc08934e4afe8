import json
import os
import subprocess

import pytest
from shared_data import ROOT, SHARED, shared  # noqa: F401 (re-exported to the tests)

BIN = ROOT / "target" / "debug" / "fluidcast"

# The package's helpers (fluidcast.cli) must run the binary scripts/test.sh just built, not a
# stale release one.
os.environ["FLUIDCAST_BIN"] = str(BIN)


def fluidcast(*args, check=True):
    """Runs the fluidcast CLI (built by scripts/test.sh) and returns the CompletedProcess."""
    if not BIN.exists():
        pytest.fail(f"{BIN} missing: run `cargo build --bin fluidcast` (scripts/test.sh does)")
    r = subprocess.run([str(BIN), *map(str, args)], capture_output=True, text=True)
    if check and r.returncode != 0:
        raise AssertionError(f"fluidcast {' '.join(map(str, args))} failed:\n{r.stderr}")
    return r


def render_png(path, array=None, **options):
    """The Python module's render (``fluidcast.render``) of ``path`` as 8-bit RGB over white,
    as the CLI writes PNGs; ``array`` as the CLI's --array: NAME, NAME:mag or NAME:K."""
    from fluidcast import api

    scalars, component = None, None
    if array:
        scalars, _, comp = array.partition(":")
        component = None if comp in ("", "mag") else int(comp)
    return api.render(path, scalars, component=component, **options).to_uint8()


def info_json(path):
    return json.loads(fluidcast("info", path, "--json").stdout)
