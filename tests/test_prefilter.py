"""The lab's declared filter (tuner.data.prefilter) against closed forms, and its effect on a comparison:
the simulated force passes the same filter as the measured one."""
import numpy as np
import pytest
from scipy import signal

from tuner.data.prefilter import parse_prefilter


def test_a_causal_moving_average_delays_a_sine_by_half_its_window_and_scales_it_by_the_sinc():
    """Closed form: the mean over the last T of sin(w t) is sinc(f T) sin(w (t - T/2)); over the last N
    samples at R Hz the centre lies (N - 1) / (2 R) behind; centred (zero-phase) it has no delay."""
    rate, f, window = 1000.0, 2.0, 0.1
    t = np.arange(0.0, 5.0, 1.0 / rate)
    x = np.sin(2 * np.pi * f * t)
    steady = t > window
    for spec, delay in (("moving-average:0.1", window / 2), ("moving-average:100@1000", 99 / 2000),
                        ("moving-average:0.1:zero-phase", 0.0)):
        y = parse_prefilter(spec).apply(x, rate)
        expected = np.sinc(f * window) * np.sin(2 * np.pi * f * (t - delay))
        np.testing.assert_allclose(y[steady & (t < 4.9)], expected[steady & (t < 4.9)], atol=1e-4, err_msg=spec)
        # the same on a grid five times coarser: the window is time, not samples
        np.testing.assert_allclose(parse_prefilter(spec).apply(x[::5], rate / 5)[steady[::5] & (t[::5] < 4.9)],
                                   expected[::5][steady[::5] & (t[::5] < 4.9)], atol=2e-3, err_msg=spec)


def test_undoing_a_filter_gives_the_signal_back_in_its_band_and_butterworth_matches_scipy():
    rate, f = 1000.0, 3.0
    t = np.arange(0.0, 4.0, 1.0 / rate)
    x = np.sin(2 * np.pi * f * t) + 0.3 * np.sin(2 * np.pi * 7.0 * t + 1.0)
    inner = (t > 0.3) & (t < 3.5)
    for spec in ("moving-average:0.05", "butterworth:4:20", "butterworth:2:25:zero-phase"):
        lab = parse_prefilter(spec)
        # within 1 % of the amplitude (the mirror extension's kink rings through the limited inverse near the end)
        np.testing.assert_allclose(lab.unapply(lab.apply(x, rate), rate)[inner], x[inner], atol=1e-2, err_msg=spec)
    sos = signal.butter(4, 10.0, fs=rate, output="sos")
    causal = parse_prefilter("butterworth:4:10").apply(x, rate)
    np.testing.assert_allclose(causal, signal.sosfilt(sos, x, zi=signal.sosfilt_zi(sos) * x[0])[0], atol=1e-12)
    np.testing.assert_allclose(parse_prefilter("butterworth:4:10:zero-phase").apply(x, rate),
                               signal.sosfiltfilt(sos, x), atol=1e-12)


def test_declarations_round_trip_and_bad_ones_name_the_forms():
    for spec in ("moving-average:0.05", "moving-average:0.05:zero-phase", "butterworth:2:15.5",
                 "moving-average:30@200:force-only", "butterworth:4:10:force-only:zero-phase"):
        assert parse_prefilter(parse_prefilter(spec).spec) == parse_prefilter(spec)
    assert parse_prefilter("none") is None and parse_prefilter(None) is None
    assert parse_prefilter("moving-average:0.1").settling_s == 0.1
    for bad in ("moving-average", "moving-average:-1", "butterworth:4", "butterworth:0:10", "kalman:3"):
        with pytest.raises(ValueError, match="'moving-average:T'"):
            parse_prefilter(bad, "--prefilter")
    with pytest.raises(ValueError, match="Nyquist"):
        parse_prefilter("butterworth:2:600").apply(np.zeros(10), 1000.0)


def test_a_declared_filter_makes_filtered_data_comparable(tmp_path):
    """Lumped-model data whose force and stroke were smoothed by a causal 60 ms moving average (as a lab
    script does) before writing at 1 kHz, noise-free, compared at 200 Hz: undeclared, the true parameters
    leave ~1 kN rms (the model under the smoothed stroke is not the smoothed force: a damper of 20 kN);
    declared, the stroke is undone and the simulated force smoothed alike, and the residual falls tenfold."""
    import pandas as pd

    from damper_dataset.writer import write_dataset
    from damper_fmu import defaults, simulate
    from tuner.data.reading import load_tests
    from tuner.identification.engine import Engine, fastest_engine
    from tuner.identification.problem import to_signals
    from tuner.data.preprocess import prepare
    from campaign.synthetic import random_stroke

    t, x, v = random_stroke(3, 8.0, 1000.0)
    f = simulate("lumped", t, x, v, params=defaults("lumped"))
    ma = parse_prefilter("moving-average:0.06")
    xs, fs = ma.apply(x, 1000.0), ma.apply(f, 1000.0)
    path = tmp_path / "smoothed.csv"
    pd.DataFrame({"time": t, "stroke": xs, "force": fs}).to_csv(path, index=False)
    rms = {}
    for spec in (None, "moving-average:0.06"):
        test = load_tests(path, prefilter=spec)[0]
        s = to_signals(prepare(test, 200.0), 0.5)
        with Engine("lumped", [s], engine=fastest_engine(), workers=0) as eng:
            r = eng.residuals_batch([defaults("lumped")])[0]
        rms[spec] = float(np.sqrt(np.mean(r ** 2)))
    assert rms["moving-average:0.06"] < 0.1 * rms[None], rms
