"""Intervals and identifiability of the identified parameters (tuner.identification.intervals) against a
lumped damper of known parameters (tests/interval_cases.py: the model's own force, finely integrated,
plus white load-cell noise; the fit polishes from the truth).

What physics and statistics say, not numbers of our own output:
(a) a damping ordinate inside the velocity range the strokes reach is determined and its interval covers
    the truth (most of them: 95 % intervals);
(b) the piston-side mass M_P only shows as M_P x'' in the force: under slow strokes (a few tenths of
    m/s^2, a few N against 25 N of noise) it is not determined; with 12-20 Hz harmonics (several m/s^2)
    it is;
(c) a damping ordinate whose abscissa lies beyond the element rate the truth reaches under these strokes
    (simulated here by the reference integrator, independently of the FMU run the tuner uses) is flagged
    extrapolated, and no other; ordinates of segments the strokes never enter have no finite interval;
(d) the interval of a parameter the noise limits scales as sigma / sqrt(N): 4 x the noise gives 4 x the
    width, 4 x the test length half the width;
(e) the representation shift: undoing the fit band's resampling restores a sine stroke to the accuracy its
    passband gain (scipy's frequency response of the same filter) allows; under 12-20 Hz strokes the
    identification's 1 ms internal steps bias the masses by several standard errors, the shift predicts
    that bias, and the interval, which holds it, covers the truth.
"""
import math
import zipfile
from xml.etree import ElementTree

import numpy as np
import pytest

from damper_fmu import REPLAY, Simulator, make_model
from interval_cases import FS, fitted, rig_tests, stroke, truth
from scipy import signal

from tuner import strict_json
from tuner.data.preprocess import Resampler
from tuner.identification.engine import Signals
from tuner.identification.intervals import (DETERMINED_WIDTH, ModelIntervals, ParameterInterval, classify,
                                              resampling_compensated)


def fc_ordinates(iv):
    return [p for p in iv.parameters if p.name.startswith("Fc_") and p.abscissa is not None]


def reached_ordinates(iv):
    """Fc ordinates strictly inside the rates the tests reach, with both neighbouring segments entered."""
    r = next(x for x in iv.reached if x.table == "Fc")
    return [p for p in fc_ordinates(iv) if 0.8 * r.low < p.abscissa < 0.8 * r.high]


def test_a_damping_ordinate_in_the_reached_range_is_determined_and_covers_the_truth():
    known = truth()
    _, par, _, iv, refined = fitted(known, rig_tests(known, "multisine", 3, (10.0, 10.0), noise_n=25.0))
    assert refined.converged, refined.stop
    inside = reached_ordinates(iv)
    assert len(inside) >= 8, [p.name for p in inside]
    assert all(p.determined for p in inside), [(p.name, p.flags) for p in inside]
    cover = [p.low <= known[p.name] <= p.high for p in inside]
    assert sum(cover) >= 0.8 * len(cover), [(p.name, p.low, known[p.name], p.high) for p in inside]
    # the interval is a real one: not wider than the noise can explain, not zero
    assert all(0.0 < p.high - p.low < 0.05 * abs(p.value) + 200.0 for p in inside)


def test_b_a_mass_is_not_determined_by_slow_strokes_and_determined_by_fast_ones():
    known = truth()
    _, _, _, slow, _ = fitted(known, rig_tests(known, "slow", 5, (10.0,), noise_n=25.0))
    _, _, _, fast, _ = fitted(known, rig_tests(known, "fast", 5, (10.0,), noise_n=25.0))
    m_slow, m_fast = slow.get("M_P"), fast.get("M_P")
    assert m_slow.status == "not determined", m_slow
    assert m_fast.status == "determined", m_fast
    assert m_slow.width_fraction > DETERMINED_WIDTH >= m_fast.width_fraction
    # the mass's information grows with the stroke acceleration: the widths are ordered as the
    # accelerations are, by far
    acc = {kind: np.std(np.gradient(stroke(kind, 500, 10.0)[2], 1.0 / FS)) for kind in ("slow", "fast")}
    assert acc["fast"] > 10 * acc["slow"]
    assert (m_slow.high - m_slow.low) > 3 * (m_fast.high - m_fast.low)
    # the outer mass M_C moves the force by M_C x4'', with x4 the far silent block's deflection (F / k_B):
    # no stroke of these makes it visible
    assert slow.get("M_C").status == fast.get("M_C").status == "not determined"


def element_rates(params: dict, t, x, v) -> np.ndarray:
    """Damping element rate x2' - x3' [m/s] of the truth under the stroke, by the reference integrator."""
    model = make_model("lumped", params)
    sim = Simulator(model, input_mode=REPLAY)
    sim.initialize(x[0], v[0], t[0])
    out = []
    for k in range(2, t.size, 2):
        sim.step(t[k] - t[k - 2], x[k], v[k])
        out.append(model.diagnostics(sim.y, sim.x1, sim.v1)["damping_rate"])
    return np.array(out)


def test_c_damping_abscissae_beyond_the_reached_rate_are_extrapolated():
    known = truth()
    tests = rig_tests(known, "slow", 7, (10.0,), noise_n=25.0, slow_amp=0.004)
    _, _, _, iv, _ = fitted(known, tests)
    t, x, v = stroke("slow", 700, 10.0, slow_amp=0.004)
    rates = element_rates(known, t, x, v)[int(0.5 * FS / 2):]  # after the warm-up, as the fit counts
    lo, hi = rates.min(), rates.max()
    expected = {p.name for p in fc_ordinates(iv) if not lo <= p.abscissa <= hi}
    # these strokes stay well inside the table: several points lie beyond, several inside
    assert 2 <= len(expected) <= 10, (lo, hi)
    assert {p.name for p in fc_ordinates(iv) if p.extrapolated} == expected
    # beyond the first point past the reach, a segment the strokes never enter: no finite interval
    for side in (1, -1):
        beyond = sorted((abs(p.abscissa), p) for p in fc_ordinates(iv)
                        if p.extrapolated and math.copysign(1, p.abscissa) == side)
        for _, p in beyond[1:]:
            assert p.low is None and p.status == "not determined", p


def test_the_offset_points_from_a_displaced_fit_back_to_the_truth():
    """Intervals taken at a point displaced from the truth along one damping ordinate (no refinement): the
    force is linear in the ordinates, so the Gauss-Newton offset recovers the displacement (the standard
    error grows too: the sandwich counts the misfit the displacement leaves), and the reason says so when it
    exceeds one standard error."""
    known = truth()
    tests = rig_tests(known, "multisine", 3, (10.0,), noise_n=25.0)
    displaced = {**known, "Fc_10": known["Fc_10"] + 150.0}
    _, _, _, iv, _ = fitted(displaced, tests, jacobians=0)
    p = iv.get("Fc_10")
    assert p.offset == pytest.approx(-150.0, abs=0.2 * 150.0), p.offset
    assert ("standard errors from the local optimum" in p.reason) == (abs(p.offset) > p.std)
    # at the truth itself the offsets stay within the noise
    _, _, _, at_truth, _ = fitted(known, tests, jacobians=0)
    assert abs(at_truth.get("Fc_10").offset) < 3 * at_truth.get("Fc_10").std


def widths(iv, names):
    return np.array([iv.get(n).high - iv.get(n).low for n in names])


def test_d_widths_scale_with_the_noise_and_one_over_the_root_of_the_length():
    known = truth()
    _, _, _, quiet, _ = fitted(known, rig_tests(known, "multisine", 9, (10.0,), noise_n=10.0))
    _, _, _, loud, _ = fitted(known, rig_tests(known, "multisine", 9, (10.0,), noise_n=40.0))
    _, _, _, long, _ = fitted(known, rig_tests(known, "multisine", 9, (40.0,), noise_n=10.0))
    names = [p.name for p in reached_ordinates(quiet)]
    assert len(names) >= 6
    noise_ratio = np.median(widths(loud, names) / widths(quiet, names))
    length_ratio = np.median(widths(quiet, names) / widths(long, names))
    assert 3.4 < noise_ratio < 4.6, noise_ratio      # sigma: 40 N / 10 N
    assert 1.6 < length_ratio < 2.5, length_ratio     # sqrt(N): 40 s / 10 s of the same stroke statistics


def test_e_undoing_the_resampling_restores_a_sine_stroke_to_second_order():
    """A 6 Hz, 1 mm stroke at 1 kHz through the fit band's resampler to 200 Hz (as the data reach the fit):
    its amplitude is off by the filter's passband gain |H(6 Hz)| - 1 (scipy.signal.freqz, about 1.4e-4); the
    compensated stroke is off by (|H| - 1)^2, far below."""
    rs = Resampler.design(1000.0, 200.0)
    t1 = np.arange(0.0, 4.0 + 1e-9, 1e-3)
    f, a = 6.0, 1e-3
    x = rs.apply(a * np.sin(2 * np.pi * f * t1))
    v = rs.apply(a * 2 * np.pi * f * np.cos(2 * np.pi * f * t1))
    t = t1[0] + (rs.first_index() + np.arange(x.size)) / 200.0
    s = Signals("sine", t, x, v, np.zeros_like(t), np.ones_like(t, dtype=bool), oversample=5)
    gain = abs(signal.freqz(rs.taps, worN=[f], fs=1000.0)[1][0]) - 1.0
    assert 5e-5 < abs(gain) < 1e-3, gain
    k0, n = s.band_limited_span()
    inner = slice(k0, k0 + n)
    exact = a * np.sin(2 * np.pi * f * t)[inner]
    before = np.max(np.abs(x[inner] - exact)) / a
    after = np.max(np.abs(resampling_compensated(s).stroke[inner] - exact)) / a
    assert before == pytest.approx(abs(gain), rel=0.05)
    assert after < 0.05 * abs(gain), (before, after)
    assert np.array_equal(resampling_compensated(s).stroke[:k0], x[:k0])  # outside the filter's reach: as is


def test_e_the_representation_shift_predicts_the_step_bias_of_fast_strokes():
    known = truth()
    _, par, est, iv, _ = fitted(known, rig_tests(known, "fast", 5, (10.0, 10.0), noise_n=25.0))
    exact = par.to_params(par.from_params(known))
    for name in ("M_P", "M_O"):
        p = iv.get(name)
        err = p.value - exact[name]
        # the 1 ms steps bias the mass by several standard errors: the statistical interval alone misses it
        assert abs(err) > 3 * p.std, (name, err, p.std)
        # the shift is what the better representation would move the fit by: back towards the truth
        assert abs(err + p.systematic) < 2 * p.std, (name, err, p.systematic, p.std)
        assert p.low <= exact[name] <= p.high and p.determined, p
        assert p.high - p.low == pytest.approx(2 * 1.959964 * math.hypot(p.std, p.systematic), rel=1e-6)


def test_flags_from_value_and_standard_error():
    """classify: the flag rules on numbers whose answer is known."""
    d = classify("M_P", "kg", 12.0, 0.2, (1.0, 20.0), False)
    assert d.status == "determined" and d.low == pytest.approx(12.0 - 1.96 * 0.2, rel=1e-3)
    wide = classify("M_P", "kg", 12.0, 6.0, (1.0, 20.0), False)
    assert wide.status == "not determined" and (wide.low, wide.high) == (1.0, 20.0) and wide.beyond_bounds
    top = classify("M_C", "kg", 20.0, 0.1, (1.0, 20.0), False)
    assert top.status == "at a bound" and top.at_bound
    flat = classify("M_C", "kg", 20.0, math.inf, (1.0, 20.0), False)
    assert flat.status == "not determined" and flat.low is None and flat.flags == ["not determined", "at a bound"]
    # log-scaled: symmetric in decades, always positive
    k = classify("k_B", "N/m", 1e6, 2e6, (1e2, 1e9), True)
    assert k.low > 0 and k.high / 1e6 == pytest.approx(1e6 / k.low, rel=1e-9)
    # a standard error 3e5 times the value (a two-chamber L_C at its bound): the whole range, not an overflow
    huge = classify("L_C", "m", 100.0, 2.96e7, (0.05, 100.0), True)
    assert huge.status == "not determined" and (huge.low, huge.high) == (0.05, 100.0) and huge.beyond_bounds
    # a systematic shift of known size and unknown sign widens in quadrature: 0.3 and 0.4 give 0.5
    sh = classify("M_P", "kg", 12.0, 0.3, (1.0, 20.0), False, systematic=-0.4)
    assert (sh.low, sh.high) == pytest.approx((12.0 - 1.959964 * 0.5, 12.0 + 1.959964 * 0.5), rel=1e-6)
    assert sh.std == 0.3 and sh.systematic == -0.4


def test_results_round_trip_through_strict_json():
    known = truth()
    _, _, _, iv, _ = fitted(known, rig_tests(known, "slow", 7, (10.0,), noise_n=25.0, slow_amp=0.004), jacobians=0)
    text = strict_json.dumps(iv.to_dict())
    assert "NaN" not in text and "Infinity" not in text and "non_finite_values" not in text
    back = ModelIntervals.from_dict("lumped", strict_json.loads(text))
    assert [p.flags for p in back.parameters] == [p.flags for p in iv.parameters]
    assert all(isinstance(p, ParameterInterval) for p in back.parameters)
    assert back.descriptions() == iv.descriptions()
    # the covariance in the identification's coordinates, for draws of parameter sets, comes back too, and
    # maps to the stored physical covariance by the coordinates' Jacobian (delta method)
    assert back.local.resolved == iv.local.resolved and np.allclose(back.local.matrix, iv.local.matrix)
    par = back.local.parametrization("lumped", known)
    space = par.local_space()
    assert list(space.names) == back.local.coordinates
    keep = [back.local.coordinates.index(c) for c in back.local.resolved]
    u0, h = back.local.u, 1e-7
    p0 = space.to_params(u0)
    G = np.column_stack([[(space.to_params(u0 + h * np.eye(u0.size)[i])[n] - p0[n]) / h
                          for n in back.covariance_names] for i in keep])
    cov = G @ back.local.matrix @ G.T
    assert np.allclose(np.sqrt(np.diag(cov)), np.sqrt(np.diag(back.covariance)), rtol=1e-3)
    # the representation shift in u (what the draws and the test design use) maps to each parameter's
    # systematic shift by the same Jacobian
    shift = G @ back.local.shift[keep]
    assert np.allclose(back.local.shift, iv.local.shift) and np.any(back.local.shift != 0.0)
    for n, s in zip(back.covariance_names, shift):
        p = back.get(n)
        assert abs(s - p.systematic) <= 1e-3 * abs(p.systematic) + 1e-6 * p.std, (n, s, p.systematic)


def test_fit_writes_the_intervals_and_the_report_shows_them(small_lumped, tmp_path):
    """fit() computes the intervals of every fitted model; parameters.json holds them as strict JSON; the
    report has their table (a row per identified parameter) and the characteristics figure; summary.json's
    part names the same flags."""
    import json
    import re

    from damper_fmu.parameters import tunable_names
    from tuner.cli.summary import interval_summary
    from tuner.identification.engine import fastest_engine
    from tuner.identification.fit import FitSettings, fit
    from tuner.job import export_fmus
    from tuner.results.report import make_report

    ident, valid = small_lumped
    out = tmp_path / "fit"
    result = fit(ident, valid, FitSettings(models=("lumped", "maxwell"), population=4, iterations=1, workers=0,
                                           engine=fastest_engine(), polish_jacobians=2), log=lambda m: None)
    result.write(out)
    text = (out / "parameters.json").read_text()
    params = json.loads(text, parse_constant=lambda c: pytest.fail(f"parameters.json holds {c}"))
    for model in ("lumped", "maxwell"):
        iv = ModelIntervals.from_dict(model, params[model]["intervals"])
        assert [p.name for p in iv.parameters] == tunable_names(model)
        assert all(p.status in ("determined", "at a bound", "not determined") for p in iv.parameters)
        assert all(p.low is None or p.bounds[0] <= p.low <= p.value <= p.high <= p.bounds[1] for p in iv.parameters)
    lumped = ModelIntervals.from_dict("lumped", params["lumped"]["intervals"])
    # M_C acts through the far silent block's deflection only: no stroke on a rig determines it
    assert lumped.get("M_C").status == "not determined"
    html = make_report(out).read_text(encoding="utf-8")
    section = html[html.index("id='intervals'"):]
    section = section[:section.index("</section>")]
    shown = dict(re.findall(r'<span class="flag" data-interval="([^"]+)">([^<]*)</span>', section))
    assert set(tunable_names("lumped")) | set(tunable_names("maxwell")) <= set(shown)
    assert "not determined" in shown["M_C"]
    assert (out / "figures" / "intervals_characteristics.png").is_file()
    summary = interval_summary(params)
    assert "M_C" in summary["lumped"]["not_determined"]
    assert summary["lumped"]["determined"] == lumped.names_with("determined")
    # the tuned FMU says in each identified parameter's description what the tests determine
    tuned = {p.name: p for p in export_fmus(result, out)}
    described = descriptions(tuned["DamperLumped_tuned.fmu"])
    for p in lumped.parameters:
        assert p.range_text() in described[p.name], (p.name, described[p.name])
    assert "NOT determined" in described["M_C"]
    # the design command on this fit: the best tests for what it leaves open, as a dataset the reader takes
    from tuner.__main__ import main
    from tuner.data.reading import load_dataset
    from tuner.results.design_report import design_section_html

    assert main(["design", "--from", str(out), "--duration", "3", "--top", "2", "--quiet", "--no-report"]) == 0
    design = json.loads((out / "design" / "design.json").read_text(),
                        parse_constant=lambda c: pytest.fail(f"design.json holds {c}"))
    assert "M_C" in design["models"]["lumped"]["targets"]
    lim = design["limits"]
    written = load_dataset(out / "design")
    assert {t.name + ".csv" for t in written} >= set(design["models"]["lumped"]["written"])
    assert all(float(np.max(np.abs(t.stroke))) <= lim["stroke_m"] * (1 + 1e-6) for t in written)
    ranked = design["models"]["lumped"]["ranked"]
    assert [g["score_nats"] for g in ranked] == sorted((g["score_nats"] for g in ranked), reverse=True)
    section = design_section_html(out)  # the report's section (the command rebuilds the report without --no-report)
    assert all(n.removesuffix(".csv") in section for n in design["models"]["lumped"]["written"])


def descriptions(fmu) -> dict:
    """name -> description of the variables of the FMU's modelDescription.xml (parsed: valid XML)."""
    with zipfile.ZipFile(fmu) as z:
        root = ElementTree.fromstring(z.read("modelDescription.xml"))
    found = {v.get("name"): v.get("description") for v in root.iter("ScalarVariable")}
    found.update({v.get("name"): v.get("description") for v in root.find("ModelVariables")
                  if v.tag != "ScalarVariable"})
    return found


@pytest.mark.parametrize("flavour,version", [("native", 2), ("native", 3), ("python", 2)])
def test_every_model_description_states_the_determined_ranges(tmp_path, flavour, version):
    """FMI 2.0 and 3.0, native and pythonfmu: the description of each identified parameter ends with its
    determined range; the others are unchanged; the FMU stays valid."""
    from damper_fmu.fmu import build, native_reason, validate

    if flavour == "native" and native_reason():
        pytest.skip(native_reason())
    known = truth()
    _, _, est, iv, _ = fitted(known, rig_tests(known, "slow", 7, (10.0,), noise_n=25.0, slow_amp=0.004), jacobians=0)
    path = build("lumped", tmp_path, start_values={k: est[k] for k in iv.descriptions()}, flavour=flavour,
                 fmi_version=version, parameter_notes=iv.descriptions())
    described = descriptions(path)
    for name, text in iv.descriptions().items():
        assert described[name].endswith("; " + text), (name, described[name])
    assert "determined" not in described["Fc_v01"] and "determined" not in described["stroke"]
    if version == 2:
        assert validate(path) == []
    with pytest.raises(ValueError, match="unknown parameter"):
        build("lumped", tmp_path, flavour=flavour, fmi_version=version, parameter_notes={"M_X": "?"})
