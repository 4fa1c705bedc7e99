"""Residual evidence recovers known effects injected into a synthetic damper force.

The "simulated" force is a blow-off damper law of an analytic multi-sine stroke velocity; the
"measured" force adds one effect of known magnitude computed analytically (not through the module's
filters), so each estimate is checked against the injected value.
"""
import numpy as np
import pytest

from tuner.diagnosis.residual_signatures import EFFECTS, knee_velocity
from tuner.diagnosis.residual_tests import PreparedTest, TestResidual
from tuner.diagnosis.residuals import FIGURE_TOPICS, evidence, figure_files
from tuner.results.diagnosis_figures import residual_figures

FS, DUR = 500.0, 40.0                       # sample rate [Hz], test length [s]
C0, C1, VK = 8e5, 5e4, 0.012                # low-speed / high-speed damping [N s/m], knee scale [m/s]
FREQS = np.array([0.4, 1.1, 2.3, 4.7])     # [Hz]
AMPS = np.array([4e-3, 2e-3, 1e-3, 0.5e-3])  # [m]


def damper(v):
    """Smooth blow-off damper force [N] of velocity v [m/s]."""
    return C1 * v + (C0 - C1) * VK * np.tanh(v / VK)


def stroke(t, seed):
    """Multi-sine stroke x [m], velocity [m/s], acceleration [m/s^2] at times t [s]."""
    ph = np.random.default_rng(seed).uniform(0, 2 * np.pi, FREQS.size)
    w = 2 * np.pi * FREQS
    arg = np.outer(t, w) + ph
    return np.sin(arg) @ AMPS, np.cos(arg) @ (AMPS * w), -np.sin(arg) @ (AMPS * w ** 2)


def make(effect, role, seed):
    t = np.arange(int(DUR * FS)) / FS
    x, v, a = stroke(t, seed)
    sim, temp = damper(v), None
    if effect == "friction":
        meas = sim + 120.0 * np.tanh(v / 0.5e-3)
    elif effect == "time_delay":
        meas = damper(stroke(t - 0.004, seed)[1])          # force recorded 4 ms late
    elif effect == "inertia":
        meas = sim + 80.0 * a
    elif effect == "preload":
        meas = sim - 200.0
    elif effect == "thermal_drift":
        temp = 40.0 - 20.0 * np.exp(-t / 12.0)               # oil heats 20 -> ~40 degC
        meas = sim * np.exp(-0.01 * (temp - 20.0))
    elif effect == "drift_time":                             # no temperature channel
        meas = sim * np.exp(-0.002 * t)
    elif effect == "free_play":                              # dead band of 0.3 mm in series, one sine
        x = 5e-3 * np.sin(3 * np.pi * t)
        v, sim = 5e-3 * 3 * np.pi * np.cos(3 * np.pi * t), damper(5e-3 * 3 * np.pi * np.cos(3 * np.pi * t))
        y, engaged = x[0], np.zeros(t.size, bool)
        for k in range(1, t.size):                           # play operator, half width 0.15 mm
            yn = min(max(y, x[k] - 0.15e-3), x[k] + 0.15e-3)
            engaged[k], y = yn != y, yn
        meas = np.where(engaged, sim, 0.0)
    else:  # no effect: white measurement noise only
        meas = sim + np.random.default_rng(seed + 99).normal(0, 50.0, t.size)
    return TestResidual(f"{effect}_{role}", role, t, x, v, meas, sim, t > 1.0, temp)


def pair(effect):
    return [make(effect, "identification", 1), make(effect, "validation", 2)]


CASES = [("friction", 120.0), ("time_delay", 0.004), ("inertia", 80.0), ("preload", -200.0),
         ("thermal_drift", 0.01), ("free_play", 0.3e-3)]


@pytest.mark.parametrize("effect,true", CASES)
def test_evidence_recovers_injected_effect(effect, true):
    ev = evidence(pair(effect))
    e = ev["effects"][effect]
    assert e["value"] == pytest.approx(true, rel=0.10), e["sentence"]
    assert ev["ranking_by_r2"][0] == effect, {k: ev["effects"][k]["r2"] for k in EFFECTS}
    assert e["r2"] > 0.9
    assert isinstance(e["sentence"], str) and e["sentence"]
    for name, d in e["per_test"].items():              # each test alone tells the same
        assert d["value"] == pytest.approx(true, rel=0.10), name


def test_delay_shifts_both_sides_of_the_knee_alike():
    vl = evidence(pair("time_delay"))["effects"]["valve_lag"]
    assert vl["value"] == pytest.approx(0.004, rel=0.10)
    assert vl["tau_below_knee"] == pytest.approx(0.004, rel=0.10)


def test_thermal_signs_and_halves():
    th = evidence(pair("thermal_drift"))["effects"]["thermal_drift"]
    assert th["quantity"] == "beta" and th["unit"] == "1/K"
    assert th["gain_change_per_100s"] < 0 and th["half_gain_change"] < 0
    # gain ratio of the halves lies between the end-point extremes of exp(-0.01 dT), dT <= 20 K
    assert np.exp(-0.2) - 1 < th["half_gain_change"] < 0


def test_drift_in_time_without_temperature():
    ev = evidence(pair("drift_time"))
    th = ev["effects"]["thermal_drift"]
    assert th["quantity"] == "gain_change_per_100s" and th["beta"] is None
    assert th["value"] == pytest.approx(np.expm1(-0.2), rel=0.10)      # exp(-0.002/s x 100 s) - 1
    assert ev["ranking_by_r2"][0] == "thermal_drift"
    assert np.expm1(-0.002 * DUR) < th["half_gain_change"] < 0


def test_knee_matches_analytic_slope_third():
    preps = [PreparedTest(t) for t in pair("friction")]
    v = np.concatenate([np.abs(p.t.velocity[p.use]) for p in preps])
    bin_width = np.percentile(v, 98) / 20
    # slope C1 + (C0 - C1) sech^2(v/VK) = C0/3
    exact = VK * np.arccosh(1 / np.sqrt((C0 / 3 - C1) / (C0 - C1)))
    assert abs(knee_velocity(preps) - exact) <= bin_width


def test_general_numbers_and_spectrum():
    tests = pair("preload")
    g = evidence(tests)["general"]
    t = tests[0]
    rms_meas = np.sqrt(np.mean(t.measured[t.mask][10:-10] ** 2))
    d = g["per_test"][t.name]
    assert d["rms_residual"] == pytest.approx(200.0, rel=1e-9)
    assert d["residual_pct"] == pytest.approx(100 * 200.0 / rms_meas, rel=1e-3)
    assert d["band_fraction"]["<1 Hz"] > 0.99                  # a constant is all DC
    assert g["pooled"]["samples"] == sum(g["per_test"][k]["samples"] for k in g["per_test"])


def test_pure_noise_explains_nothing():
    ev = evidence(pair("none"))
    assert max(ev["effects"][k]["r2"] for k in EFFECTS) < 0.01


def test_bad_input_is_named():
    t = make("friction", "identification", 1)
    with pytest.raises(ValueError, match="role"):
        TestResidual("x", "training", t.time, t.stroke, t.velocity, t.measured, t.simulated, t.mask)
    with pytest.raises(ValueError, match="stroke"):
        TestResidual("x", "validation", t.time, t.stroke[:-1], t.velocity, t.measured, t.simulated, t.mask)
    with pytest.raises(ValueError, match="uniformly"):
        TestResidual("x", "validation", t.time ** 1.1, t.stroke, t.velocity, t.measured, t.simulated, t.mask)
    with pytest.raises(ValueError, match="mask"):
        TestResidual("x", "validation", t.time, t.stroke, t.velocity, t.measured, t.simulated, t.mask * 1)
    with pytest.raises(ValueError, match="unique"):
        evidence([t, t])


def test_figures_are_png(tmp_path):
    tests = pair("thermal_drift") + [make("free_play", "validation", 3)]
    paths = residual_figures(tests, tmp_path / "fig", prefix="diag")
    assert len(paths) == len(FIGURE_TOPICS) and len(set(paths)) == len(FIGURE_TOPICS) and "map" in FIGURE_TOPICS
    assert [str(p) for p in paths] == figure_files(tmp_path / "fig")  # the names the diagnosis's record lists
    import matplotlib.image as mpimg
    for p in paths:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert mpimg.imread(p).shape[0] > 100
    # drawn in two worker processes (the job's way): the same files
    again = residual_figures(tests, tmp_path / "workers", prefix="diag", workers=2)
    assert [p.read_bytes() for p in again] == [p.read_bytes() for p in paths]


def _with_residual(r_of, seed=3):
    t = np.arange(int(DUR * FS)) / FS
    x, v, a = stroke(t, seed)
    sim = damper(v)
    return TestResidual("r", "identification", t, x, v, sim + r_of(t, x, v), sim, t > 1.0)


def test_linear_share_tells_a_missing_linear_element_from_a_nonlinear_error():
    """A parallel Maxwell branch (k = 2e6 N/m, tau = 50 ms: a linear filter of the stroke) is ~100 %
    coherent with the stroke; a force even in the stroke (a |x| spring) or a white noise is not."""
    from scipy.signal import lfilter

    k, tau = 2e6, 0.05
    al = np.exp(-1 / (FS * tau))
    maxwell = evidence([_with_residual(lambda t, x, v: k * lfilter([1, -1], [1, -al], x))])["general"]["pooled"]
    even = evidence([_with_residual(lambda t, x, v: 4e6 * (np.abs(x) - np.abs(x).mean()))])["general"]["pooled"]
    noise = evidence([_with_residual(lambda t, x, v: np.random.default_rng(1).normal(0, 50, t.size))])
    assert maxwell["linear_share"] > 0.95
    assert even["linear_share"] < 0.3
    assert noise["general"]["pooled"]["linear_share"] < 0.2


def test_where_in_the_loop_the_residual_lies():
    """A residual only at speeds below the knee lands there; extension/compression split by sign."""
    knee = knee_velocity([PreparedTest(_with_residual(lambda t, x, v: 0 * t))])
    ev = evidence([_with_residual(lambda t, x, v: np.where((np.abs(v) < 0.5 * knee) & (v > 0), 300.0, 0.0))])
    loop = ev["general"]["pooled"]["loop"]
    assert loop["below_knee_extension"]["power_share"] > 0.99
    assert sum(d["time_share"] for d in loop.values()) == pytest.approx(1.0)


def _two_effects(seed, friction_n=120.0, inertia_kg=80.0, noise_n=20.0):
    """Friction and inertia injected together (analytic forces) plus white noise."""
    t = np.arange(int(DUR * FS)) / FS
    x, v, a = stroke(t, seed)
    sim = damper(v)
    meas = (sim + friction_n * np.tanh(v / 0.5e-3) + inertia_kg * a
            + np.random.default_rng(seed + 7).normal(0, noise_n, t.size))
    return TestResidual(f"two_{seed}", "identification", t, x, v, meas, sim, t > 1.0)


def test_joint_screen_keeps_the_two_injected_effects_with_their_magnitudes():
    """Two effects at once: the joint screen keeps exactly those two, with their injected sizes
    (friction force [N], inertia [kg] as the coefficients of tanh(v / 0.5 mm/s) and x'')."""
    scr = evidence([_two_effects(1), _two_effects(2)], noise_n=20.0)["joint_screen"]
    assert sorted(scr["kept"]) == ["friction", "inertia"], scr
    assert scr["terms"]["friction"]["coefficient"] == pytest.approx(120.0, rel=0.05)
    assert scr["terms"]["inertia"]["coefficient"] == pytest.approx(80.0, rel=0.05)
    assert scr["r2_kept"] > 0.9


def test_joint_screen_keeps_nothing_on_noise():
    """White noise only (50 N): no signature carries even a tenth of the noise (each picks up about
    50 N / sqrt(n) = 0.3 N); together they explain almost none of it (7 regressors on ~20 000
    samples: R^2 ~ 7 / n)."""
    scr = evidence([make("none", "identification", 3)], noise_n=5.0)["joint_screen"]
    assert scr["kept"] == [] and scr["r2_all"] < 0.01, scr


# --------------------------------------------------------------------------- the restoring-force map
# A sine stroke x = A sin(w t) at the fit rate, so that the truth of every share is analytic: the time share of
# |v| < s x peak is (2 / pi) arcsin(s), of the stroke band [x1, x2] (arcsin(x2 / A) - arcsin(x1 / A)) / pi.

SINE_A, SINE_W, SINE_FS = 0.02, 2 * np.pi * 0.5, 200.0   # amplitude [m], angular frequency [rad/s], rate [Hz]
SINE_VPK = SINE_A * SINE_W                                # peak velocity [m/s]


def _sine(r_of, role="identification", name="sine"):
    """A 40 s sine test whose measured force is the simulated one plus r_of(x [m], v [m/s]) [N]."""
    t = np.arange(int(40 * SINE_FS)) / SINE_FS
    x, v = SINE_A * np.sin(SINE_W * t), SINE_VPK * np.cos(SINE_W * t)
    sim = damper(v)
    return TestResidual(name, role, t, x, v, sim + r_of(x, v), sim, t > 1.0)


def _where(r_of):
    return evidence([_sine(r_of)])["residual_map"]


def test_the_map_bins_the_residual_over_stroke_and_velocity_and_leaves_thin_bins_empty():
    """A residual of 100 N in extension (x > 0), 0 in compression: every bin wholly at x > 0 reads 100 N rms, every
    bin wholly at x < 0 reads 0; the counts hold every usable sample once; a bin is empty (NaN) exactly when it
    has fewer than MIN_BIN_SAMPLES. A missing spring r = k x on the sine is -k |x| on the a >= 0 branch (x <= 0
    there) and +k |x| on the a < 0 one, |x| = A sqrt(1 - (v / v_peak)^2) at velocity v."""
    from tuner.diagnosis.residual_map import MIN_BIN_SAMPLES, residual_map

    p = PreparedTest(_sine(lambda x, v: np.where(x > 0, 100.0, 0.0)))
    m = residual_map([p])
    assert m.count.sum() == p.use.sum() and m.branch_count.sum() == p.use.sum()
    assert np.array_equal(np.isnan(m.rms_n), m.count < MIN_BIN_SAMPLES)
    full = ~np.isnan(m.rms_n)
    above, below = m.stroke_edges_m[:-1] > 0, m.stroke_edges_m[1:] < 0
    assert full[above].any() and full[below].any()
    assert np.allclose(m.rms_n[above][full[above]], 100.0) and np.allclose(m.rms_n[below][full[below]], 0.0)

    k = 2e4                                                   # [N/m]
    m = residual_map([PreparedTest(_sine(lambda x, v: k * x))])
    vc = 0.5 * (m.velocity_edges_m_s[1:] + m.velocity_edges_m_s[:-1])
    mid = np.abs(vc) < 0.5 * SINE_VPK                         # where |x| hardly changes across a bin
    expected = k * SINE_A * np.sqrt(1 - (vc[mid] / SINE_VPK) ** 2)
    assert m.branch_mean_n[0, mid] == pytest.approx(-expected, rel=0.03)
    assert m.branch_mean_n[1, mid] == pytest.approx(expected, rel=0.03)


def test_a_residual_near_velocity_reversal_is_placed_there_with_its_true_share():
    """400 N more while |v| < 0.1 v_peak (a step the base's smooth tables cannot follow, as a friction they
    absorbed leaves) on a 100 N offset: the near-reversal region (|v| < 0.2 v_peak) holds the analytic share of
    the power, and the verdict names it with its shares."""
    from tuner.diagnosis.verdict import map_text, unexplained_record, verdict_text

    ev = evidence([_sine(lambda x, v: 100.0 + np.where(np.abs(v) < 0.1 * SINE_VPK, 400.0, 0.0))])
    s = ev["residual_map"]
    t1, t2 = (2 / np.pi) * np.arcsin(0.1), (2 / np.pi) * np.arcsin(0.2)
    true = (t1 * 500 ** 2 + (t2 - t1) * 100 ** 2) / (t1 * 500 ** 2 + (1 - t1) * 100 ** 2)
    rev = s["regions"]["near_reversal"]
    assert rev["power_share"] == pytest.approx(true, abs=0.03)
    assert rev["time_share"] == pytest.approx(t2, abs=0.01)
    assert s["concentrated_in"][0] == "near_reversal" and not s["branch_asymmetry"]["hysteresis"]
    said = (f"near velocity reversal ({100 * rev['power_share']:.0f} % of the power in "
            f"{100 * rev['time_share']:.0f} % of the time)")
    assert said in map_text(s)
    record = unexplained_record(300.0, 20.0, 25.0, 15.0, ev, True)
    assert record["residual_map"] == s
    assert said in verdict_text([], {}, {}, [], record, 20.0)


def test_a_residual_that_differs_between_the_branches_shows_the_hysteresis():
    """A missing spring (r = k x: on the sine the F-v loop opens) is all branch difference at equal velocity;
    a residual of the velocity alone (a characteristic's shape, r = 300 N (v / v_peak)^3) has none."""
    from tuner.diagnosis.verdict import map_text

    loop = _where(lambda x, v: 2e4 * x)["branch_asymmetry"]
    assert loop["power_share"] > 0.9 and loop["hysteresis"]
    assert loop["time_share"] == pytest.approx(1.0, abs=0.05)
    assert "(a hysteresis)" in map_text(_where(lambda x, v: 2e4 * x))
    shape = _where(lambda x, v: 300.0 * (v / SINE_VPK) ** 3)
    assert shape["branch_asymmetry"]["power_share"] < 0.02 and not shape["branch_asymmetry"]["hysteresis"]
    assert "hysteresis" not in map_text(shape)


def test_a_residual_at_one_stroke_position_is_located_there():
    """300 N within 1 mm of x = +6 mm (a groove) on a +-20 mm sine: the band found holds x = 6 mm and all the
    power in the band's analytic time share; nothing near reversal or at the ends."""
    from tuner.diagnosis.verdict import map_text

    x0 = 0.3 * SINE_A
    s = _where(lambda x, v: np.where(np.abs(x - x0) < 0.05 * SINE_A, 300.0, 0.0))
    band = s["regions"]["stroke_band"]
    assert band["stroke_from_m"] < x0 < band["stroke_to_m"]
    assert band["power_share"] > 0.99
    x1, x2 = band["stroke_from_m"] / SINE_A, band["stroke_to_m"] / SINE_A
    assert band["time_share"] == pytest.approx((np.arcsin(x2) - np.arcsin(x1)) / np.pi, abs=0.01)
    assert s["concentrated_in"] == ["stroke_band"]
    assert s["regions"]["near_reversal"]["power_share"] < 0.01 and s["regions"]["stroke_ends"]["power_share"] < 0.01
    assert f"at one stroke position, {1e3 * band['stroke_from_m']:.3g} to" in map_text(s)


def test_white_noise_lives_nowhere_in_particular():
    """50 N of white noise: every region's power share is its time share (ratio near 1), no region holds it and
    the branches do not differ; the verdict adds nothing."""
    from tuner.diagnosis.verdict import map_text

    s = _where(lambda x, v: np.random.default_rng(4).normal(0.0, 50.0, x.size))
    assert all(0.8 < d["ratio"] < 1.25 for d in s["regions"].values()), s["regions"]
    assert s["concentrated_in"] == [] and s["branch_asymmetry"]["power_share"] < 0.02
    assert map_text(s) == ""


def test_the_map_summary_is_of_the_identification_tests_and_strict_json():
    """The map shows the residual the model was fitted on: a validation test's residual does not enter it, and
    without an identification test there is no map (None)."""
    import json

    ident = _sine(lambda x, v: np.where(np.abs(v) < 0.1 * SINE_VPK, 400.0, 0.0), name="id")
    valid = _sine(lambda x, v: 2e4 * x, role="validation", name="val")
    s = evidence([ident, valid])["residual_map"]
    assert s["tests"] == ["id"] and not s["branch_asymmetry"]["hysteresis"]
    assert s == evidence([ident])["residual_map"]
    json.loads(json.dumps(s, allow_nan=False))
    assert evidence([valid])["residual_map"] is None
