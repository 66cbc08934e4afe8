"""The shared SPH data beside the checkout (../shared/data) for the pytest suites: a missing
file skips its test, or fails it with FLUIDCAST_REQUIRE_DATA=1 (set by scripts/test.sh)."""
import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
#: The double dam break frame the VTK and ParaView tests use too.
DDB = "splash_doubledambreak/DoubleDamBreak_r0.0125_0011.vtu"


def shared(rel):
    """../shared/data/REL, or a skip when it is missing; a failure with
    FLUIDCAST_REQUIRE_DATA=1 (set by the test command)."""
    p = SHARED / rel
    if not p.exists():
        if os.environ.get("FLUIDCAST_REQUIRE_DATA") == "1":
            pytest.fail(f"FLUIDCAST_REQUIRE_DATA=1 but {p} is missing")
        pytest.skip(f"{p} not present")
    return p
