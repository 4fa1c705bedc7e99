"""Validation metrics against hand-computed cases, the paper's Table 3 and polynomial identities."""
import math

import numpy as np
import pytest

from tuner.metrics import (ErrorMetrics, compare_to_maxwell, error_metrics, fitness, polyfit_odd_even,
                           variation_percent)


def test_error_metrics_hand_case():
    # errors e = F_exp - F_num = [0, 0, 0, -2] N; mean F_exp = 2.5 N, SST = 5 N^2
    m = error_metrics([1.0, 2.0, 3.0, 4.0], [1.0, 2.0, 3.0, 6.0])
    assert m.n == 4
    assert m.sse == pytest.approx(4.0)
    assert m.mse == pytest.approx(1.0)
    assert m.ame == pytest.approx(0.5)
    assert m.rmse == pytest.approx(1.0)
    assert m.nrmse == pytest.approx(1.0 / 3.0)
    assert m.r2 == pytest.approx(1.0 - 4.0 / 5.0)
    assert m.max_abs_error == pytest.approx(2.0)
    assert m.peak_measured == pytest.approx(4.0)
    assert m.fitness == pytest.approx(1.0)


def test_peak_is_absolute_and_sign_of_error_irrelevant():
    meas = np.array([-5.0, 3.0, 1.0])
    a = error_metrics(meas, meas + np.array([1.0, -2.0, 0.5]))
    b = error_metrics(meas, meas - np.array([1.0, -2.0, 0.5]))
    assert a.peak_measured == 5.0
    for field in ("sse", "mse", "ame", "rmse", "max_abs_error", "r2"):
        assert getattr(a, field) == pytest.approx(getattr(b, field))
    assert a.ame == pytest.approx(3.5 / 3)


def test_perfect_fit_and_identities():
    rng = np.random.default_rng(3)
    f = rng.normal(0.0, 1e3, 500)
    perfect = error_metrics(f, f)
    assert perfect.mse == 0.0 and perfect.r2 == 1.0 and perfect.fitness == math.inf
    m = error_metrics(f, f + rng.normal(0.0, 50.0, 500))
    assert m.rmse == pytest.approx(math.sqrt(m.mse))
    assert m.fitness == pytest.approx(1.0 / m.mse)
    assert m.ame <= m.rmse <= m.max_abs_error          # power-mean inequalities
    # R^2 of the mean predictor is 0
    assert error_metrics(f, np.full_like(f, f.mean())).r2 == pytest.approx(0.0, abs=1e-12)


def test_constant_measured_gives_nan_for_normalised_indices():
    m = error_metrics([2.0, 2.0, 2.0], [1.0, 2.0, 3.0])
    assert math.isnan(m.nrmse) and math.isnan(m.r2)
    assert m.mse == pytest.approx(2.0 / 3.0)


@pytest.mark.parametrize("meas, sim, msg", [
    ([1.0, 2.0], [1.0], "length"),
    ([1.0, np.nan], [1.0, 2.0], "measured"),
    ([1.0, 2.0], [np.inf, 2.0], "simulated"),
    ([], [], "empty"),
    ([[1.0, 2.0]], [[1.0, 2.0]], "1-D"),
])
def test_bad_input_rejected(meas, sim, msg):
    with pytest.raises(ValueError, match=msg):
        error_metrics(meas, sim)


def test_fitness_eq5_concatenates_tests():
    a1, b1 = np.array([1.0, 2.0, 3.0]), np.array([1.5, 2.0, 2.0])       # SSE 1.25
    a2, b2 = np.array([10.0, -4.0]), np.array([9.0, -6.0])               # SSE 5
    assert fitness([a1, a2], [b1, b2]) == pytest.approx(5 / 6.25)
    assert fitness([a1, a2], [b1, b2]) == pytest.approx(fitness(np.r_[a1, a2], np.r_[b1, b2]))
    assert fitness(a1, b1) == pytest.approx(error_metrics(a1, b1).fitness)
    assert fitness(a1, a1) == math.inf
    with pytest.raises(ValueError, match="number of tests"):
        fitness([a1, a2], [b1])
    with pytest.raises(ValueError, match="test 1"):
        fitness([a1, a2], [b1, b2[:1]])
    with pytest.raises(ValueError, match="both"):
        fitness([a1, a2], np.r_[b1, b2])


@pytest.mark.parametrize("mse_max, mse_prop, var_mse, ame_max, ame_prop, var_ame", [
    (5.88e6, 2.18e5, -96.3, 1.80e3, 346.0, -80.8),   # paper Table 3, test 1
    (5.05e6, 5.32e5, -89.5, 1.73e3, 569.0, -67.1),   # test 2
    (4.07e6, 4.19e5, -89.7, 1.55e3, 526.0, -66.1),   # test 3
])
def test_variation_reproduces_paper_table3(mse_max, mse_prop, var_mse, ame_max, ame_prop, var_ame):
    # Table 3 rounds to 0.1 %
    assert variation_percent(mse_prop, mse_max) == pytest.approx(var_mse, abs=0.05)
    assert variation_percent(ame_prop, ame_max) == pytest.approx(var_ame, abs=0.05)


def test_compare_to_maxwell_and_errors():
    meas = np.array([0.0, 1.0, 2.0, 3.0])
    model = error_metrics(meas, meas + 1.0)      # MSE 1, AME 1
    maxwell = error_metrics(meas, meas + 2.0)    # MSE 4, AME 2
    v = compare_to_maxwell(model, maxwell)
    assert v["mse"] == pytest.approx(-75.0) and v["ame"] == pytest.approx(-50.0)
    with pytest.raises(ValueError, match="zero"):
        variation_percent(1.0, 0.0)
    with pytest.raises(ValueError, match="different length"):
        compare_to_maxwell(model, error_metrics(meas[:3], meas[:3]))
    assert isinstance(model, ErrorMetrics) and model.to_dict()["mse"] == pytest.approx(1.0)


# ---- polynomial odd/even split (Fig. 11, eqs. 9-10) ----

X_STROKE = np.linspace(-0.012, 0.02, 61)   # deliberately asymmetric range [m]


def _poly(c, x):
    return sum(ck * x ** k for k, ck in enumerate(c))


def test_polyfit_odd_function():
    c = [0.0, 1.3e7, 0.0, 4.7e12, 0.0, -9.0e17]
    r = polyfit_odd_even(X_STROKE, _poly(c, X_STROKE))
    scale = np.abs(_poly(c, X_STROKE)).max()
    np.testing.assert_allclose(r.fit, _poly(c, X_STROKE), rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(r.even, 0.0, atol=1e-9 * scale)
    assert r.asymmetry_index < 1e-9
    for k in (1, 3, 5):
        assert r.coefficients[k] == pytest.approx(c[k], rel=1e-7)


def test_polyfit_even_function():
    v = np.linspace(-0.3, 0.1, 40)         # velocity-like abscissa [m/s]
    c = [58.0, 0.0, -1.17e5, 0.0, 3.9e6, 0.0]
    r = polyfit_odd_even(v, _poly(c, v))
    scale = np.abs(_poly(c, v)).max()
    np.testing.assert_allclose(r.odd, 0.0, atol=1e-9 * scale)
    assert r.asymmetry_index == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_allclose(r.coefficients, c, rtol=1e-7, atol=1e-9 * np.abs(c).max())


def test_polyfit_mixed_paper_eq9():
    # paper eq. 9 coefficients (ascending powers), x = x4 - x3 [m], F [N]
    c = [12.37, 1.335e7, -2.558e8, 4.689e12, 1.149e14, -9.047e17]
    y = _poly(c, X_STROKE)
    r = polyfit_odd_even(X_STROKE, y)
    np.testing.assert_allclose(r.coefficients, c, rtol=1e-6)
    odd = c[1] * X_STROKE + c[3] * X_STROKE ** 3 + c[5] * X_STROKE ** 5
    even = c[0] + c[2] * X_STROKE ** 2 + c[4] * X_STROKE ** 4
    atol = 1e-9 * np.abs(y).max()
    np.testing.assert_allclose(r.odd, odd, atol=atol)
    np.testing.assert_allclose(r.even, even, atol=atol)
    expected = np.sqrt(np.mean(even ** 2)) / np.sqrt(np.mean(y ** 2))
    assert r.asymmetry_index == pytest.approx(expected, rel=1e-6)


def test_polyfit_least_squares_matches_numpy_polynomial():
    rng = np.random.default_rng(11)
    x = np.sort(rng.uniform(-0.05, 0.08, 200))
    y = 1.2e6 * x - 6.9e8 * x ** 3 + rng.normal(0.0, 300.0, x.size)
    r = polyfit_odd_even(x, y, order=5)
    ref = np.polynomial.Polynomial.fit(x, y, 5).convert().coef
    np.testing.assert_allclose(r.coefficients, ref, rtol=1e-6, atol=1e-9 * np.abs(ref).max())
    # residual orthogonal to the basis (normal equations)
    V = np.vander(x / np.abs(x).max(), 6, increasing=True)
    assert np.abs(V.T @ (y - r.fit)).max() < 1e-8 * np.abs(V.T @ y).max()


def test_polyfit_other_order_and_errors():
    x = np.linspace(-1.0, 2.0, 5)
    r = polyfit_odd_even(x, 3.0 * x - 1.0, order=1)
    np.testing.assert_allclose(r.coefficients, [-1.0, 3.0], atol=1e-12)
    with pytest.raises(ValueError, match="at least"):
        polyfit_odd_even(x[:3], x[:3], order=5)
    with pytest.raises(ValueError, match="distinct"):
        polyfit_odd_even(np.r_[x, x, x], np.r_[x, x, x], order=5)
    with pytest.raises(ValueError, match="order"):
        polyfit_odd_even(x, x, order=-1)
    with pytest.raises(ValueError, match="all zero"):
        polyfit_odd_even(np.zeros(8), np.ones(8))


@pytest.mark.parametrize("fs", [300.0, 1000.0, 5000.0])
def test_noise_estimate_sees_white_noise_under_a_large_damper_signal(fs):
    from tuner.metrics import noise_std

    rng = np.random.default_rng(int(fs))
    t = np.arange(0.0, 20.0, 1.0 / fs)
    signal = 2e4 * np.sin(2 * np.pi * 1.7 * t) + 5e3 * np.sin(2 * np.pi * 6.3 * t + 1.0)
    est = noise_std(signal + rng.normal(0.0, 25.0, t.size), fs)
    assert est == pytest.approx(25.0, rel=0.1)


@pytest.mark.parametrize("fs, within", [(300.0, 4.5), (1000.0, 1.15)])
def test_noise_estimate_on_a_damper_force_with_kinks(fs, within):
    """The lumped model's force (blow-off kinks: broadband harmonics) at 300 Hz and 1 kHz, 20 N of
    white noise: the estimate is never below the noise and at most `within` x it (at 300 Hz the
    harmonics reach every band below 0.3 fs: 4 x; the earlier 0.1-0.3 fs median read 5 x)."""
    from campaign.synthetic import model_tests
    from damper_fmu import defaults
    from tuner.metrics import noise_std

    frame = model_tests("lumped", defaults("lumped"), seed=3, durations=(30.0,), roles=("identification",),
                        fs=fs)[0]["frame"]
    est = noise_std(frame["force"].to_numpy(), fs)
    assert 20.0 * 0.95 <= est <= 20.0 * within


def test_noise_estimate_is_not_lowered_by_the_rigs_anti_alias_filter():
    """Noise through the virtual rig's sensor chain (FIR anti-alias filter, cut-off 0.4 fs, 20 N rms
    after it): the estimate is the white-equivalent level of the low band the fit uses, not less (an
    estimate from the filter's transition band would be)."""
    from campaign.sensors import SensorChain
    from tuner.metrics import noise_std

    fs, n = 1000.0, 40000
    chain = SensorChain(force_range=1e6)
    zeros = np.zeros(chain.oversampling * (n - 1) + 1)
    _, force, _ = chain.acquire(zeros, zeros, zeros, seed=4)
    from scipy.signal import welch

    f, psd = welch(force, fs=fs, nperseg=1024)
    low = np.sqrt(np.median(psd[(f > 0.01 * fs) & (f < 0.1 * fs)]) * fs / 2)  # the level in the fit band
    assert 0.97 * low <= noise_std(force, fs) <= 1.1 * low


def test_pooled_mse_is_the_mse_of_all_samples_together():
    from tuner.metrics import error_metrics, pooled_mse

    rng = np.random.default_rng(4)
    a, b = rng.normal(0, 3, 50), rng.normal(1, 7, 150)
    rows = [error_metrics(a, np.zeros(50)).to_dict(), error_metrics(b, np.zeros(150)).to_dict()]
    assert pooled_mse(rows) == pytest.approx(np.mean(np.concatenate([a, b]) ** 2))
    assert pooled_mse([]) == float("inf")
