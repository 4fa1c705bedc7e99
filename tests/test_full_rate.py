"""Full-rate check (tuner.identification.full_rate): does a fit made at 200 Hz hold at the file's 1 kHz?

Through the production path (``tuner.identification.fit.full_rate_checks``: the comparison rate,
the velocity, the noise estimate from the data). References: the TRUE parameters on data the lumped
model generated at 1 kHz from a railway-like multi-sine stroke (0.4-4.7 Hz) with 20 N of white noise:
nothing above the fit band but noise, so it holds and the above-band residual is the known noise;
and the same data with a 130 Hz force component (a rig resonance the model cannot make, 40 N
amplitude = 28 N rms, above the 9 N of noise the fit band keeps), which must be found and measured."""
import math

import numpy as np
import pytest

from damper_fmu import SolverOptions, defaults, simulate
from tuner.data.reading import RigTest
from tuner.identification.fit import FitSettings, full_rate_checks
from tuner.identification.full_rate import MIN_RATE_RATIO, comparison_rate

FREQS = np.array([0.4, 1.1, 2.3, 4.7])        # [Hz]
AMPS = np.array([4e-3, 2e-3, 1e-3, 0.5e-3])   # [m]
NOISE_N = 20.0


@pytest.fixture(scope="module")
def lumped_data():
    t = np.arange(0.0, 12.0, 1e-3)
    arg = np.outer(t, 2 * np.pi * FREQS) + np.random.default_rng(5).uniform(0, 2 * np.pi, FREQS.size)
    x, v = np.sin(arg) @ AMPS, np.cos(arg) @ (AMPS * 2 * np.pi * FREQS)
    truth = defaults("lumped")
    force = simulate("lumped", t, x, v, params=truth, solver=SolverOptions(tolerance=1e-6, max_step=2.5e-4))
    return t, x, force + np.random.default_rng(6).normal(0.0, NOISE_N, t.size), truth


def _check(t, x, force, truth):
    test = RigTest("sines", "identification", "sines", t, x, force, sample_rate=1000.0)
    settings = FitSettings(models=("lumped",))
    res = full_rate_checks([test], {"lumped": {"values": truth}}, settings, log=lambda m: None)["lumped"]
    return res["holds"], res["tests"]["sines"]


def test_the_true_model_holds_at_full_rate(lumped_data):
    holds, r = _check(*lumped_data)
    assert holds and r["holds"], r
    assert r["noise_std_n"] == pytest.approx(NOISE_N, rel=0.15)                 # estimated from the data
    assert r["rmse_above_n"] == pytest.approx(NOISE_N * math.sqrt(60.0 / 500.0), rel=0.15)   # 100-160 Hz
    assert r["rmse_in_fit_band_n"] == pytest.approx(NOISE_N * math.sqrt(100.0 / 500.0), rel=0.2)


def test_force_above_the_fit_band_is_found_and_measured(lumped_data):
    t, x, force, truth = lumped_data
    holds, r = _check(t, x, force + 40.0 * np.sin(2 * np.pi * 130.0 * t), truth)
    assert not holds and not r["holds"], r
    assert r["hidden_n"] == pytest.approx(40.0 / math.sqrt(2), rel=0.15)
    assert r["rmse_in_fit_band_n"] < 1.3 * r["noise_in_fit_band_n"]     # the fit band does not see it


def test_the_check_needs_a_band_above_the_fit_band():
    assert comparison_rate(300.0, 200.0) is None
    assert comparison_rate(MIN_RATE_RATIO * 200.0, 200.0) == 400.0
