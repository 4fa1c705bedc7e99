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

    paths = {kind: ensure_fmu(kind) for kind in ("lumped", "maxwell", "maxwell_table", "empty")}
    paths.update({f"{kind}_py": ensure_fmu(kind, flavour="python") for kind in ("lumped", "maxwell", "maxwell_table")})
    return paths
