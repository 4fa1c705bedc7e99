"""Full-rate check (tuner.identification.full_rate): does a fit made at 200 Hz hold at the file's 1 kHz?

References: the TRUE parameters on data the lumped model generated at 1 kHz with white noise of a
known level (nothing above the fit band but noise: it holds), and the same data with a 130 Hz
force component (a rig resonance the model cannot make, 40 N amplitude, i.e. 28 N rms, above the
9 N of noise the fit band keeps: it does not hold, and the hidden force is measured). The noise level
is given as known: this random stroke has force harmonics above 100 Hz that bias a
noise estimate from the data (tuner.metrics.noise_std reads 95 N)."""
import math

import numpy as np
import pytest

from campaign.synthetic import random_stroke
from damper_fmu import defaults, simulate
from tuner.data.reading import RigTest
from tuner.data.preprocess import prepare
from tuner.identification.fit import to_signals
from tuner.identification.full_rate import MIN_RATE_RATIO, comparison_rate, full_rate_check


@pytest.fixture(scope="module")
def lumped_data():
    t, x, v = random_stroke(5, 8.0, 1000.0, slow_amp=0.02, fast_amp=4e-3)
    truth = defaults("lumped")
    force = simulate("lumped", t, x, v, params=truth, tolerance=1e-6, max_step=2.5e-4)
    return t, x, force + np.random.default_rng(5).normal(0.0, 20.0, t.size), truth


def _check(t, x, force, truth):
    test = RigTest("rand", "identification", "random", t, x, force, sample_rate=1000.0)
    rate = comparison_rate(1000.0, 200.0)
    s = to_signals(prepare(test, rate), 0.5)
    return full_rate_check("lumped", truth, s, 200.0, 1000.0, 20.0, engine="native")   # the known noise


def test_the_true_model_holds_at_full_rate(lumped_data):
    r = _check(*lumped_data)
    expected_above = 20.0 * math.sqrt((r["upper_hz"] - r["fit_band_hz"]) / 500.0)
    assert r["holds"], r
    assert r["rmse_above_n"] == pytest.approx(expected_above, rel=0.2)   # only the noise is left
    assert r["rmse_in_fit_band_n"] == pytest.approx(20.0 * math.sqrt(100.0 / 500.0), rel=0.2)


def test_force_above_the_fit_band_is_found_and_measured(lumped_data):
    t, x, force, truth = lumped_data
    r = _check(t, x, force + 40.0 * np.sin(2 * np.pi * 130.0 * t), truth)
    assert not r["holds"], r
    assert r["hidden_n"] == pytest.approx(40.0 / math.sqrt(2), rel=0.15)
    assert r["rmse_in_fit_band_n"] < 1.3 * r["noise_in_fit_band_n"]     # the fit band does not see it


def test_the_check_needs_a_band_above_the_fit_band():
    assert comparison_rate(300.0, 200.0) is None
    assert comparison_rate(MIN_RATE_RATIO * 200.0, 200.0) == 400.0
