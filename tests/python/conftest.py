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


def info_json(path):
    return json.loads(fluidcast("info", path, "--json").stdout)
