"""Test design (tuner.identification.rig_test_design) on known truth: a lumped damper identified from slow strokes
alone leaves its piston mass M_P not determined (its force M_P x'' is a few N against 25 N of noise). The
design ranks candidate tests; the physics says a mass shows at high frequency (x'' = (2 pi f)^2 x: at the
velocity limit the mass force grows as f), so the best candidate for M_P must be a fast one, and a slow sine
must not help. Then the recommended test is simulated on the truth (finely integrated, with the same noise),
added to the fit, and the refit's interval of M_P must shrink by the promised factor (within a factor of 2:
the prediction is linear, at the fit's residual level).

The combined fit's representation shift (``combined_shift``) against its definition, on synthetic
Jacobians: the Gauss-Newton projection of the stacked differences on the stacked Jacobians, solved by
numpy's least squares on the stacked system (coordinates held at a bound left out of it)."""
import numpy as np
import pytest

from interval_cases import FS, fitted, rig_tests, run_on_truth, truth
from tuner.identification.engine import fastest_engine
from tuner.identification.rig_test_design import (RankingOptions, RigLimits, candidate_tests, combined_shift,
                                                  held_coordinates, rank_candidates)


def test_the_recommended_test_shrinks_the_mass_interval_it_promised():
    known = truth()
    tests = rig_tests(known, "slow", 5, (6.0,), noise_n=25.0)
    _, _, est, iv, _ = fitted(known, tests)
    assert iv.get("M_P").status == "not determined"
    limits = RigLimits(stroke_m=0.01, velocity_m_s=0.15, force_n=3.0e4)
    pool = {c.name: c for c in candidate_tests(limits, duration=4.0, rate=FS)}
    cands = [pool[n] for n in ("sine_0.5Hz", "sine_2Hz", "sine_16Hz", "small_sine_30Hz")]
    ranked = rank_candidates("lumped", est, iv, cands, RankingOptions(fit_rate_hz=200.0, warmup_s=0.5, targets=["M_P"],
                                                                      limits=limits, engine=fastest_engine()))
    best = ranked[0]
    # "before" is the fit's own interval, the representation shift included
    assert best.widths_before["M_P"] == pytest.approx(iv.get("M_P").high - iv.get("M_P").low, rel=1e-6)
    assert best.candidate.name in ("sine_16Hz", "small_sine_30Hz"), [(g.candidate.name, g.score) for g in ranked]
    slow = next(g for g in ranked if g.candidate.name == "sine_0.5Hz")
    assert slow.shrink("M_P") > 0.8 > 0.5 > best.shrink("M_P")
    # run it on the "rig": the truth's force under the recommended stroke, plus the same noise
    new = run_on_truth(known, best.candidate, seed=77)
    _, _, _, iv2, _ = fitted(known, [*tests, new])
    before, after = best.widths_before["M_P"], iv2.get("M_P").high - iv2.get("M_P").low
    assert after < 0.5 * before
    assert 0.5 < after / best.widths_after["M_P"] < 2.0, (after, best.widths_after["M_P"], before)


def test_candidates_stay_within_the_rig_limits_and_bad_limits_are_named():
    limits = RigLimits(stroke_m=0.02, velocity_m_s=0.1, force_n=2.0e4)
    for c in candidate_tests(limits, duration=4.0, rate=FS):
        assert np.max(np.abs(c.stroke)) <= limits.stroke_m * (1 + 1e-9), c.name
        assert c.peak_velocity <= limits.velocity_m_s * 1.01, (c.name, c.peak_velocity)
        assert abs(c.stroke[0]) < 1e-9  # eased in from rest
    with pytest.raises(ValueError, match="--velocity-limit"):
        RigLimits(0.01, -1.0, 1e4).check()


def test_the_combined_shift_is_the_stacked_gauss_newton_projection():
    rng = np.random.default_rng(3)
    k, w = 5, 1.0 / (25.0 ** 2 * 1.3)  # coordinates; the weight 1/(s^2 tau) [1/N^2]
    J0, Jc = rng.normal(size=(400, k)) * [1e3, 5e2, 2e2, 1e1, 1.0], rng.normal(size=(300, k)) * 3e2
    d0, dc = rng.normal(size=400), rng.normal(size=300)
    for held in ([], [3]):
        free = [i for i in range(k) if i not in held]
        s0 = np.zeros(k)  # the fit's shift: its own projection, the held coordinate at 0
        s0[free] = np.linalg.lstsq(J0[:, free], d0, rcond=None)[0]
        expected = np.zeros(k)
        expected[free] = np.linalg.lstsq(np.vstack([J0, Jc])[:, free], np.concatenate([d0, dc]), rcond=None)[0]
        got = combined_shift(w * J0.T @ J0, s0, Jc, dc, w, held)
        assert np.allclose(got, expected, rtol=1e-7, atol=1e-12), (held, got, expected)
    # no candidate difference known: the fit's shift diluted by the candidate's information alone
    got = combined_shift(w * J0.T @ J0, s0, Jc, None, w, [3])
    expected[free] = np.linalg.lstsq(np.vstack([J0, Jc])[:, free], np.concatenate([d0, 0 * dc]), rcond=None)[0]
    assert np.allclose(got, expected, rtol=1e-7, atol=1e-12)


def test_held_at_a_bound_unless_the_candidate_decides_and_inside_when_it_says_nothing():
    u = np.array([0.5, 1.0, 1.0, 0.0, 0.0, 0.3, 0.7])
    before = np.diag([1e-6, 1e-6, 1.0, 1.0, 1.0, 1.0, 1.0])  # coordinate 1 determined at its bound by the fit
    # 2 and 4 (at a bound) determined by the candidate, 3 not; inside: 5 placed (interval 0.78 of the range),
    # 6 not (1.18 of it)
    after = np.diag([1e-6, 1e-6, 1e-6, 1.0, 1e-6, 0.2 ** 2, 0.3 ** 2])
    assert held_coordinates(u, before, after) == [1, 3, 6]
