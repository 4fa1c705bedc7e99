"""Shared fixtures: built FMUs (rebuilt only when their sources changed); the ``full`` marker."""
import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from damper_fmu.fmu import ensure_fmu  # noqa: E402  (this checkout's package, by the path above)


@pytest.fixture(scope="session")
def fmu_paths():
    kinds = ("lumped", "maxwell", "maxwell_table", "twochamber")
    paths = {kind: ensure_fmu(kind) for kind in (*kinds, "empty")}
    paths.update({f"{kind}_py": ensure_fmu(kind, flavour="python") for kind in kinds})
    return paths


def pytest_collection_modifyitems(config, items):
    """Tests marked ``full`` (benchmark-length checks, minutes each) run only with DAMPER_FULL_TESTS=1;
    otherwise they are deselected (not skipped: nothing here stops them from running)."""
    if os.environ.get("DAMPER_FULL_TESTS") == "1":
        return
    keep = [it for it in items if it.get_closest_marker("full") is None]
    if len(keep) != len(items):
        config.hook.pytest_deselected(items=[it for it in items if it.get_closest_marker("full") is not None])
        items[:] = keep
