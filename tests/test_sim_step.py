"""The grid the identification simulates the model on (``DataSettings.sim_step_s``, ``--sim-step``).

Fixed sub-steps keep the objective smooth in the parameters; how fine they must be depends on the damper. The
reference is the same model through the same band-limited comparison, error-controlled on a grid 20 times finer
(converged: a grid twice finer again moves it by a small fraction of the errors asserted). A free play closing on
impact-like silent blocks (1e9 N/m damped at 2e4 N s/m, a class damper, noise-free data) is integrated to tens of
newtons at 1 ms and converges as the grid is refined; without the gap the same blocks are integrated several
times better at 1 ms already."""
import numpy as np
import pytest

from campaign.damper_class import write_class_dataset
from tuner.data.reading import load_dataset, read_manifest
from tuner.identification.engine import fastest_engine, oversampling, simulate_signals
from tuner.identification.problem import DataSettings, prepared_signals


def _forces(tests, params, step_s, tolerance):
    _, sigs = prepared_signals(tests, DataSettings(sim_step_s=step_s))
    return np.concatenate([simulate_signals("lumped", params, s, engine=fastest_engine(), tolerance=tolerance)[s.mask]
                           for s in sigs])


def _errors(tmp_path, hidden):
    d = tmp_path / "data"
    d.parent.mkdir(parents=True, exist_ok=True)
    write_class_dataset(d, "lumped", 7, noise_n=0.0, sample_rate=500.0, hidden=hidden, durations=(4.0, 4.0))
    truth = read_manifest(d)["generator"]["parameters"]
    tests = load_dataset(d, check_plausible=False)
    ref = _forces(tests, truth, 5e-5, 1e-6)
    finer = _forces(tests, truth, 2.5e-5, 1e-6)
    rms = {step: float(np.sqrt(np.mean((_forces(tests, truth, step, 0.0) - ref) ** 2))) for step in (1e-3, 1e-4)}
    return rms, float(np.sqrt(np.mean((finer - ref) ** 2))), float(np.sqrt(np.mean(ref ** 2)))


def test_a_stiff_free_play_needs_a_finer_grid_and_converges_on_it(tmp_path):
    err, ref_spread, scale = _errors(tmp_path, {"k_B": 1e9, "c_B": 2e4, "free_play": 0.3e-3})
    assert ref_spread < 0.1 * err[1e-3]  # the reference is converged at the scale of what is asserted
    assert err[1e-3] > 2e-3 * scale  # at 1 ms: tens of newtons on a few kN
    assert err[1e-4] < 0.25 * err[1e-3]


def test_it_is_the_gap_that_1_ms_misses(tmp_path):
    """The same impact-like blocks without the gap: 1 ms is several times closer (5.6 N against 54 N measured)."""
    blocks = {"k_B": 1e9, "c_B": 2e4}
    with_gap, _, _ = _errors(tmp_path / "gap", {**blocks, "free_play": 0.3e-3})
    without, _, scale = _errors(tmp_path / "none", blocks)
    assert without[1e-3] < 0.2 * with_gap[1e-3] and without[1e-3] < 2e-3 * scale


def test_the_grid_follows_the_step_and_a_bad_step_is_refused():
    assert oversampling(200.0) == 5 and oversampling(200.0, 1e-4) == 50 and oversampling(500.0, 2.5e-4) == 8
    with pytest.raises(ValueError, match="positive number of seconds"):
        oversampling(200.0, 0.0)
