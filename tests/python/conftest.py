import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SHARED = ROOT.parent / "shared" / "data"
BIN = ROOT / "target" / "debug" / "fluidcast"

# The examples' helper module (cameras, transfer functions, VTK's SPH pipeline) is shared
# with the tests; it must run the binary scripts/test.sh just built, not a stale release one.
os.environ["FLUIDCAST_BIN"] = str(BIN)
sys.path.insert(0, str(ROOT / "examples"))


def fluidcast(*args, check=True):
    """Runs the fluidcast CLI (built by scripts/test.sh) and returns the CompletedProcess."""
    if not BIN.exists():
        pytest.fail(f"{BIN} missing: run `cargo build --bin fluidcast` (scripts/test.sh does)")
    r = subprocess.run([str(BIN), *map(str, args)], capture_output=True, text=True)
    if check and r.returncode != 0:
        raise AssertionError(f"fluidcast {' '.join(map(str, args))} failed:\n{r.stderr}")
    return r


def shared(rel):
    """../shared/data/REL, or a skip when it is missing; a failure with
    FLUIDCAST_REQUIRE_DATA=1 (set by the test command)."""
    p = SHARED / rel
    if not p.exists():
        if os.environ.get("FLUIDCAST_REQUIRE_DATA") == "1":
            pytest.fail(f"FLUIDCAST_REQUIRE_DATA=1 but {p} is missing")
        pytest.skip(f"{p} not present")
    return p


def info_json(path):
    return json.loads(fluidcast("info", path, "--json").stdout)
