"""Band-limited comparison (tuner.identification.engine): the measured force reaches the fit rate through an
anti-aliasing low-pass, so the simulated force must too. Reference: the TRUE parameters on data
the model generated, whose only misfit is the measurement noise that survives the same low-pass
(computed from the noise realisation itself, not from the code under test)."""
import numpy as np

from campaign.synthetic import random_stroke
from damper_fmu import SolverOptions, defaults, simulate
from tuner.data.reading import RigTest
from tuner.data.preprocess import Resampler, prepare
from tuner.identification.engine import oversampling, simulate_signals
from tuner.identification.problem import to_signals


def _data(seed=3, noise_n=20.0):
    t, x, v = random_stroke(seed, 8.0, 1000.0, slow_amp=0.02, fast_amp=4e-3)
    truth = defaults("lumped")
    force = simulate("lumped", t, x, v, params=truth, solver=SolverOptions(tolerance=1e-6, max_step=2.5e-4))
    noise = np.random.default_rng(seed).normal(0.0, noise_n, t.size)
    return truth, RigTest("rand", "identification", "random", t, x, force + noise, sample_rate=1000.0), noise


def test_true_parameters_reach_the_in_band_noise_only_when_band_limited():
    truth, test, noise = _data()
    p = prepare(test, 200.0)
    band_noise = Resampler.design(1000.0, 200.0).apply(noise)  # the noise the fit band keeps
    rms = {}
    for m in (1, oversampling(200.0)):
        s = to_signals(p, 0.5, oversample=m)
        # converged internal steps (the FMU's defaults): this checks the comparison, not the step
        r = (s.force - simulate_signals("lumped", truth, s, engine="native", max_internal_step=None,
                                        tolerance=None))[s.mask]
        rms[m] = float(np.sqrt(np.mean(r ** 2)))
        noise_rms = float(np.sqrt(np.mean(band_noise[s.mask] ** 2)))
    assert oversampling(200.0) == 5
    assert rms[5] <= 1.1 * noise_rms, (rms, noise_rms)
    assert rms[1] >= 1.5 * noise_rms, (rms, noise_rms)  # the aliasing bias this removes


def test_fmu_and_native_give_the_same_band_limited_force():
    truth, test, _ = _data(seed=4)
    s = to_signals(prepare(test, 200.0), 0.5)
    a = simulate_signals("lumped", truth, s, engine="native")
    b = simulate_signals("lumped", truth, s, engine="fmu")
    assert np.allclose(a, b, rtol=0, atol=1e-9 * np.abs(a).max())
    assert not s.mask[-1] and s.mask.sum() > 0.8 * len(s.time)  # filter edge not counted
