"""Shared fixtures: built FMUs (rebuilt only when their sources changed)."""
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


@pytest.fixture(scope="session")
def fmu_paths():
    from build_fmu import ensure_fmu

    kinds = ("lumped", "maxwell", "maxwell_table", "twochamber")
    paths = {kind: ensure_fmu(kind) for kind in (*kinds, "empty")}
    paths.update({f"{kind}_py": ensure_fmu(kind, flavour="python") for kind in kinds})
    return paths
