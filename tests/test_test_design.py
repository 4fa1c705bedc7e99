"""Test design (tuner.identification.rig_test_design) on known truth: a lumped damper identified from slow strokes
alone leaves its piston mass M_P not determined (its force M_P x'' is a few N against 25 N of noise). The
design ranks candidate tests; the physics says a mass shows at high frequency (x'' = (2 pi f)^2 x: at the
velocity limit the mass force grows as f), so the best candidate for M_P must be a fast one, and a slow sine
must not help. Then the recommended test is simulated on the truth (finely integrated, with the same noise),
added to the fit, and the refit's interval of M_P must shrink by the promised factor (within a factor of 2:
the prediction is linear, at the fit's residual level)."""
import numpy as np
import pytest

from interval_cases import FS, fitted, rig_tests, run_on_truth, truth
from tuner.identification.engine import fastest_engine
from tuner.identification.rig_test_design import RigLimits, candidate_tests, rank_candidates


def test_the_recommended_test_shrinks_the_mass_interval_it_promised():
    known = truth()
    tests = rig_tests(known, "slow", 5, (6.0,), noise_n=25.0)
    _, _, est, iv, _ = fitted(known, tests)
    assert iv.get("M_P").status == "not determined"
    limits = RigLimits(stroke_m=0.01, velocity_m_s=0.15, force_n=3.0e4)
    pool = {c.name: c for c in candidate_tests(limits, duration=4.0, rate=FS)}
    cands = [pool[n] for n in ("sine_0.5Hz", "sine_2Hz", "sine_16Hz", "small_sine_30Hz")]
    ranked = rank_candidates("lumped", est, iv, cands, fit_rate_hz=200.0, warmup_s=0.5, targets=["M_P"],
                             limits=limits, engine=fastest_engine())
    best = ranked[0]
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
