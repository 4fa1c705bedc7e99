"""Shared fixtures: built FMUs (rebuilt only when their sources changed); the ``full`` marker.

The suite runs in two processes (``python -m pytest -q -n 2``, pytest-xdist) and many tests start worker
pools of their own: one BLAS thread per process (set here, before numpy is imported, and inherited by
every process the tests start) keeps OpenBLAS's spinning threads from oversubscribing the cores (measured:
the suite 481 s so against 676 s serial with the default threads)."""
import os
import sys
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

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


@pytest.fixture
def small_lumped(tmp_path):
    """(identification tests, validation tests) of a 4 s + 3 s dataset of the preset lumped model with
    20 N of force noise (``campaign.synthetic``), read as a user's dataset."""
    from campaign.synthetic import write_model_dataset
    from damper_fmu import defaults
    from tuner.data.reading import load_dataset

    tests = load_dataset(write_model_dataset(tmp_path / "d", "lumped", defaults("lumped"), seed=4,
                                             durations=(4.0, 3.0), roles=("identification", "validation"),
                                             noise_n=20.0))
    return [t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"]


@pytest.fixture
def prepared_names(monkeypatch):
    """The (name, rate [Hz]) of every test ``tuner.identification.problem`` prepares, in order (a spy on
    ``prepare``: every stage prepares its tests there, the fit's and the diagnosis's at the fit rate, the full-rate
    check at its comparison rate)."""
    import tuner.identification.problem as problem_module

    names, real = [], problem_module.prepare
    monkeypatch.setattr(problem_module, "prepare",
                        lambda t, rate, *a, **k: names.append((t.name, rate)) or real(t, rate, *a, **k))
    return names
