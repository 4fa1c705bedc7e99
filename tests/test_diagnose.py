"""Diagnosis: extended design space, blind detection of hidden effects, outputs and error paths.

Hidden-effect tests (the issue's acceptance): for every catalogue effect a dataset is generated
on the virtual rig with the effect switched on at a magnitude drawn inside its documented
realistic range by a seeded generator (never passed to the diagnosis); the diagnosis must name
it, fit its magnitude within 30 % and cut the pooled validation MSE by at least 30 %.

Two dampers on the rig: the ``lumped`` damper (its hydraulics are the paper's Table 2 lumped
model), where the base model has no model-form error and what is tested is the diagnosis itself,
and the physical twin-tube damper, which no model here generated: the diagnosis must choose the
two-chamber base form (the lumped model keeps ~3 % of the peak force of form error there) and name
the effect on it. Friction (twin-tube), clean data (both) and two effects together (lumped) run in
CI; every other single effect is marked ``full`` and runs with DAMPER_FULL_TESTS=1, and benchmarks/confusion_matrix.py
measures the rates over many seeds (docs/diagnosis.md, "What it can and cannot see").
Every manoeuvre runs at its own oil temperature (a climatic-chamber campaign, the same design for
every test, clean data included), so temperature dependence is observable.
"""
import json
import math
import zlib

import numpy as np
import pytest

from campaign.effects import EFFECTS
from campaign.generate import CHAMBER_TEMPERATURES_C, CampaignPlan, generate_dataset
from damper_fmu import defaults
from tuner.__main__ import main
from tuner.data.reading import load_dataset
from tuner.diagnosis.bases import FittedBases
from tuner.diagnosis.diagnose import CANDIDATES, DiagnosisSettings, ExtendedParametrization, cross_check, decide, diagnose
from tuner.identification.engine import fastest_engine
from tuner.job import write_diagnosis
from tuner.identification.parametrization import Parametrization


def test_extended_parametrization_round_trips_base_and_effect():
    base = Parametrization("lumped", force_limit=4e4)
    for effect in CANDIDATES:
        ext = ExtendedParametrization(base, effect, peak_force=2e4)
        p = defaults("lumped")
        name = ext.extra[0]
        lo, hi = ext.extra_bounds[0]
        p[name] = lo + 0.3 * (hi - lo)
        back = ext.to_params(ext.from_params(p))
        assert back[name] == pytest.approx(p[name])
        assert back["Fc_10"] == pytest.approx(p["Fc_10"])
        assert ext.dimension == base.dimension + 1


def test_every_rig_effect_has_a_model_element_the_diagnosis_fits():
    assert set(EFFECTS) == set(CANDIDATES)
    for name, spec in EFFECTS.items():
        ext = ExtendedParametrization(Parametrization("lumped", force_limit=4e4), name, peak_force=2e4)
        assert spec.model_parameter in ext.extra
        lo, hi = ext.extra_bounds[ext.extra.index(spec.model_parameter)]
        # the refit can reach every realistic magnitude (force bounds from a 20 kN peak)
        assert lo <= spec.model_sign * spec.low <= hi and lo <= spec.model_sign * spec.high <= hi


def test_search_bounds_scale_with_the_data():
    """Force effects search at least 10 % of the peak force (a 200 kN damper may have a 15 kN
    preload); a free play never wider than the stroke range; the catalogue range otherwise."""
    from tuner.diagnosis.diagnose import search_bounds

    assert search_bounds("preload_force", 2e5) == (-2e4, 2e4)
    assert search_bounds("friction_force", 2e4)[1] == pytest.approx(2e3)
    assert search_bounds("free_play", 2e4) == (0.0, 2e-3)
    assert search_bounds("free_play", 2e4, stroke_range_m=0.6e-3) == (0.0, 0.6e-3)
    assert search_bounds("free_play", 2e4, stroke_range_m=0.1) == (0.0, 2e-3)


def run_diagnosis(tmp_path, effects, seed, damper="lumped", base_model="auto", candidates=CANDIDATES):
    """A blind diagnosis of virtual-rig data; base_model 'lumped' skips identifying the two-chamber
    base on lumped-damper data (the clean tests check that 'auto' keeps the right one)."""
    data = generate_dataset(tmp_path / "data", seed=seed, effects=effects, damper=damper,
                            plan=CampaignPlan(t_end=6.0, oil_temperatures=CHAMBER_TEMPERATURES_C), overview=False,
                            log=lambda m: None)
    tests = load_dataset(data)
    res = diagnose([t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"],
                   DiagnosisSettings(engine=fastest_engine(), base_iterations=0, base_model=base_model,
                                     candidates=candidates), log=lambda m: None)
    write_diagnosis(res, tmp_path / "out", log=lambda m: None)  # the job's files: diagnosis.json, figures, FMU
    return res


@pytest.mark.slow
def test_friction_hidden_in_the_twin_tube_damper_is_named_on_the_two_chamber_base(tmp_path):
    """The physical twin-tube damper (not a model) with a seal friction drawn inside its typical
    range: the two-chamber base is chosen and the friction named within 20 %. A faithful smaller
    version of the confusion benchmark's twin-tube row (3/3 there with all seven candidates): two
    candidates here, friction and preload (both shift the force by a constant in each direction)."""
    value = float(np.random.default_rng(31).uniform(EFFECTS["friction"].low, EFFECTS["friction"].high))
    res = run_diagnosis(tmp_path, {"friction": value}, seed=31, damper="twin-tube", candidates=("friction", "preload"))
    assert res["base_model"] == "twochamber", res["base_choice"]
    assert res["causes"] == ["friction"], res["verdict"]
    assert res["effect_parameters"]["friction_force"]["value"] == pytest.approx(value, rel=0.2)
    assert (tmp_path / "out" / "fmu" / "DamperTwoChamber_friction_tuned.fmu").exists()
    # the two-chamber base's refinement converged on these tests: it is its own refit ('none') and is not
    # continued beside the friction's refit either (its rule says more Jacobians would not move it)
    none = next(r for r in res["ranking"] if r["effect"] == "none")
    assert none["evaluations"] == 0, none


@pytest.mark.slow
@pytest.mark.full  # about 5 min (benchmarks/confusion_matrix.py --damper twin-tube --effects free_play measures it)
def test_free_play_in_the_twin_tube_damper_is_named_after_the_base_is_chosen_again(tmp_path):
    """The physical twin-tube damper with a free play drawn in its typical range: a gap makes both bare
    bases fit badly and the base chosen first may be the wrong form; its diagnosis leaves a residual
    above the floor, so the diagnosis is repeated on the other base and the final models compared. The
    gap is named on the two-chamber base (a dead band in its mount) within 20 %."""
    value = float(np.random.default_rng(77).uniform(EFFECTS["free_play"].low, EFFECTS["free_play"].high))
    res = run_diagnosis(tmp_path, {"free_play": value}, seed=77, damper="twin-tube", candidates=("free_play",))
    assert res["base_model"] == "twochamber", res["base_choice"]
    assert res["causes"] == ["free_play"], res["verdict"]
    assert res["effect_parameters"]["free_play"]["value"] == pytest.approx(value, rel=0.2)


#: twin-tube single-effect blind tests beyond CI's friction, all seven candidates (1-1.5 min each since the
#: screen, 2026-11-25; free play above). Valve lag is not among them: the rig's valve lag acts
#: on its blow-off valves, which open only in the switch manoeuvre, an identification test; the
#: held-out tests, on which every verdict rests, see 0.1-3.3 N rms of it against 10 N of noise
#: (benchmarks/confusion_matrix.py prints that force), so no verdict can be earned for it with this
#: campaign (docs/diagnosis.md, "What it can and cannot see").
TWIN_TUBE_FULL = ("preload", "thermal_drift", "time_delay", "inertia")
#: relative magnitude tolerance: inertia's force on railway strokes is of the order of the noise on
#: this damper (10-19 N against 10 N), and its fitted mass scatters by up to 67 % in the benchmark
TWIN_TUBE_REL = {"inertia": 0.7}


@pytest.mark.slow
@pytest.mark.full  # 1-1.5 min each
@pytest.mark.parametrize("effect", TWIN_TUBE_FULL)
def test_an_effect_hidden_in_the_twin_tube_damper_is_named_blind_on_the_two_chamber_base(tmp_path, effect):
    spec = EFFECTS[effect]
    seed = zlib.crc32(f"twin-tube {effect}".encode()) % 1000
    value = float(np.random.default_rng(seed).uniform(spec.low, spec.high))
    res = run_diagnosis(tmp_path, {effect: value}, seed=seed, damper="twin-tube")
    assert res["base_model"] == "twochamber", res["base_choice"]
    assert res["causes"] == [effect], (res["verdict"], [(r["effect"], round(r["score"], 3)) for r in res["ranking"]])
    fitted = res["effect_parameters"][spec.model_parameter]["value"]
    assert fitted == pytest.approx(spec.model_sign * value, rel=TWIN_TUBE_REL.get(effect, 0.3))


#: the CI suite (10 min on 2 cores) runs the blind detection as friction and inertia hidden together
#: in the lumped damper (below) and friction in the twin-tube damper (above); the single effects on
#: the lumped damper run with DAMPER_FULL_TESTS=1 (all seven, 3.7 min of test time on 2026-11-25) and in
#: benchmarks/confusion_matrix.py (5/5 each with five seeds, 2026-11-23); a preload's residual
#: signature is also checked analytically in tests/test_residuals.py


@pytest.mark.slow
@pytest.mark.full
@pytest.mark.parametrize("effect", list(EFFECTS))
def test_a_hidden_effect_is_named_blind_with_its_magnitude_and_a_30_percent_gain(tmp_path, effect):
    spec = EFFECTS[effect]
    value = float(np.random.default_rng(zlib.crc32(effect.encode())).uniform(spec.low, spec.high))
    res = run_diagnosis(tmp_path, {effect: value}, seed=zlib.crc32(effect.encode()) % 1000, base_model="lumped")
    assert res["cause"] == effect, [(r["effect"], round(r["score"], 3)) for r in res["ranking"]]
    fitted = res["effect_parameters"][spec.model_parameter]["value"]
    assert fitted == pytest.approx(spec.model_sign * value, rel=0.3)
    winner = next(r for r in res["ranking"] if r["effect"] == effect)
    assert winner["validation_mse_change_pct"] <= -30.0  # pooled over the validation tests
    saved = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert saved["cause"] == effect
    # the reported before/after (Table 3 definition, through the FMU) agrees with the ranking's gain;
    # per test it may not: the valve-lag element is a linearisation of the rig's lagging valve and
    # its refit is worse on the slowest manoeuvre (val3: +47 % MSE, -92 % on the fastest)
    val = saved["validation"].values()
    assert sum(v["mse_after"] for v in val) <= 0.7 * sum(v["mse_before"] for v in val)
    assert (tmp_path / "out" / "fmu" / f"DamperLumped_{effect}_tuned.fmu").exists()


@pytest.mark.slow
@pytest.mark.parametrize("damper", ["lumped", "twin-tube"])
def test_clean_data_gives_no_false_cause_and_a_complete_diagnosis_json(tmp_path, damper):
    res = run_diagnosis(tmp_path, {}, seed=5, damper=damper)
    # the base form that represents the damper is kept: the lumped model for the lumped damper, the
    # two-chamber form for the twin-tube one (the lumped model leaves 30-60x the noise there)
    saved = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert saved["base_model"] == ("lumped" if damper == "lumped" else "twochamber"), saved["base_choice"]
    # no catalogue effect is named and, on the base that represents the damper, nothing is unexplained
    assert res["cause"] == "none" and not res["causes"], [(r["effect"], round(r["score"], 3)) for r in res["ranking"]]
    assert saved["cause"] == res["cause"]
    assert {r["effect"] for r in saved["ranking"]} == set(CANDIDATES) | {"none"}  # none: the base refitted alike
    assert saved["noise_std_n"] > 0
    # each detection limit carries the physical range's top it is weighed against (rules.untold)
    limits = saved["detection_limits"]
    assert limits and all(0 < r["plausible_top"] < math.inf and r["within_plausible"] == (
        r["reachable"] and r["limit"] <= r["plausible_top"]) for r in limits.values()), limits
    if damper == "lumped":   # a model that can represent the data: no signature carries force above the noise
        assert saved["evidence"]["joint_screen"]["kept"] == [], saved["evidence"]["joint_screen"]
    assert all("score" in r and "validation_mse_change_pct" in r for r in saved["ranking"])
    # one best model: no candidate's refit fits the identification data better with its effect off
    # than 'none' does (such a point becomes 'none'), so no effect of size zero can win
    none_rmse = next(r for r in saved["ranking"] if r["effect"] == "none")["identification_rmse_n"]
    assert all(none_rmse <= r["identification_rmse_effect_off_n"] * (1 + 1e-12)
               for r in saved["ranking"] if r["effect"] != "none")
    assert set(saved["validation"]) == {"val1_straight_250", "val2_curve_R6000_306", "val3_curve_R500_86"}
    for v in saved["validation"].values():
        assert v["mse_after"] == v["mse_before"]  # no cause: the model is unchanged
    assert saved["figures"] and all((tmp_path / "out" / f).exists() for f in saved["figures"])
    assert not (tmp_path / "out" / "fmu").exists()


def test_diagnose_command_needs_validation_tests_and_a_real_fit_folder(tmp_path, capsys):
    data = generate_dataset(tmp_path / "d", seed=1, plan=CampaignPlan(scenarios=["id1_straight_250"], t_end=3.0),
                            overview=False, log=lambda m: None)
    assert main(["diagnose", "--identification", str(next(data.glob("*.csv"))), "--out", str(tmp_path / "o")]) == 2
    assert "validation" in capsys.readouterr().err
    assert main(["diagnose", "--from", str(tmp_path), "--out", str(tmp_path / "o2")]) == 2
    assert "parameters.json" in capsys.readouterr().err


def _row(effect, score, effect_rms, noise=10.0, significant=True):
    return {"effect": effect, "score": score, "effect_rms_n": effect_rms,
            "resolved": effect == "none" or effect_rms >= noise, "parameters": {}, "significant": significant}


def test_a_free_play_no_screen_passed_is_refitted_before_a_residual_above_the_floor_is_left_without_a_cause(
        monkeypatch):
    """The profile screen re-balances the base linearly, which cannot give back a gap the base absorbed (a 0.54 mm
    gap in stiff two-chamber mounts screened at 1.3 %: 'unexplained' at 24 x the floor; refitted, named at the
    floor): with the base refit above UNEXPLAINED_RATIO x the floor, every nonsmooth candidate not refitted yet is
    laddered (the series element held) and, only when that leaves a residual above the floor or no cause's score
    and its profile found a gap that fits better, refitted in full, the better fit kept; a smooth one screened out, or any candidate once the base is near the
    floor, is not. ``benchmarks/blind_class.py --cases free_play_stiff`` runs the whole diagnosis on such dampers."""
    from tuner.diagnosis.cost_model import DiagnosisCost
    from tuner.diagnosis.rules import UNEXPLAINED_RATIO
    from tuner.diagnosis.search import nonsmooth
    from tuner.diagnosis.search.state import Fit, SearchState

    search = SearchState.__new__(SearchState)
    search.credible, search.floor, search.log = True, 20.0, lambda m: None
    search.kind, search.record, search.resolvable_n = "lumped", {}, 1.5
    search.par, search.settings = Parametrization("lumped", force_limit=4e4), DiagnosisSettings()
    search.cost = DiagnosisCost(reference=0.0, screen=0.0, refits=0.0, forms=0.0, detection=0.0)
    search.forecast = lambda: None
    calls, ladder_rmse, profile_better = [], [0.0], [True]

    def refit_candidate(s, effect, ext):
        calls.append(("refit", effect))
        search.refits[effect] = Fit(None, np.ones(1), 100)
        return {**_row(effect, 0.9, 300.0), "validation_mse_change_pct": -60.0, "identification_rmse_n": 50.0}

    def series_ladder(s, effect, ext, row, gain_n=0.0):
        assert gain_n == s.resolvable_n  # released only for a gap the data can show
        calls.append(("ladder", effect))
        search.refits[effect] = Fit(None, np.full(1, 2.0), 50)
        return {**_row(effect, 1.2, 300.0), "validation_mse_change_pct": -70.0, "identification_rmse_n": ladder_rmse[0],
                **({} if profile_better[0] else {"gap_fits_better": False})}

    monkeypatch.setattr(nonsmooth, "refit_candidate", refit_candidate)
    monkeypatch.setattr(nonsmooth, "series_ladder", series_ladder)
    above = UNEXPLAINED_RATIO * 20.0 * 1.5
    for rmse_none, rmse_ladder, expected, steps, kept, better in (
            (above, 35.0, ["free_play"], ("ladder",), 2.0, True),  # the ladder within 2 x the floor: no full refit
            (above, 45.0, ["free_play"], ("ladder", "refit"), 2.0, True),  # above: refitted, the ladder's fit better
            (above, 90.0, ["free_play"], ("ladder", "refit"), 1.0, True),  # ... the full refit's better
            (above, 90.0, ["free_play"], ("ladder",), 2.0, False),  # the ladder's profile found no better gap
            (UNEXPLAINED_RATIO * 20.0 * 0.9, 19.0, [], (), 0.0, True)):  # the base near the floor: nothing
        calls.clear()
        ladder_rmse[0], profile_better[0] = rmse_ladder, better
        search.none_row = {**_row("none", 0.0, 0.0), "identification_rmse_n": rmse_none}
        search.ranking = [{**_row(e, -0.02, 0.0), "refitted": refitted, "screen": None} for e, refitted in
                          (("friction", False), ("free_play", False), ("inertia", True))] + [search.none_row]
        search.refits = {r["effect"]: Fit(None, np.zeros(1), 1) for r in search.ranking}
        assert nonsmooth.refit_unseen_nonsmooth(search) == expected
        assert calls == [(kind, e) for e in expected for kind in steps]
        free_play = next(r for r in search.ranking if r["effect"] == "free_play")
        assert free_play["refitted"] == bool(expected)
        assert free_play.get("identification_rmse_n") == (min(rmse_ladder, 50.0 if "refit" in steps else 99.0)
                                                          if expected else None)
        assert float(search.refits["free_play"].z[0]) == kept
        if "refit" in steps:
            assert search.refits["free_play"].evaluations == free_play["evaluations"] == 150


def test_an_effect_whose_interval_includes_zero_is_not_named():
    ranking = [_row("friction", 0.5, 80.0, significant=False), _row("inertia", 0.2, 60.0), _row("none", 0.0, 0.0)]
    cause, best, rejected = decide(ranking)
    assert cause == "inertia" and [r["effect"] for r in rejected] == ["friction"]
    without = [{k: v for k, v in _row("friction", 0.5, 80.0).items() if k != "significant"}, _row("none", 0.0, 0.0)]
    assert decide(without)[0] == "none"  # no interval computed: not significant
    tiny = {**_row("valve_lag", 0.3, 40.0), "meaningful": False}
    assert decide([tiny, _row("none", 0.0, 0.0)])[0] == "none"  # a 0.2 ms valve lag is no cause


def test_a_zero_size_effect_is_never_named_however_well_it_scores():
    """The issue's case: a 1 N friction on a 20 kN damper scoring +5.8 is no cause."""
    ranking = [_row("friction", 5.8, 1.06), _row("preload", 5.8, 0.4), _row("free_play", 3.4, 1e-6),
               _row("none", 0.0, 0.0)]
    cause, best, unresolved = decide(ranking)
    assert cause == "none" and best["effect"] == "none"
    assert {r["effect"] for r in unresolved} == {"friction", "preload", "free_play"}


def test_a_magnitude_at_its_search_bound_or_beyond_its_plausible_range_is_never_named():
    """The form-gap case of the blind benchmark: a bypass groove hidden, an inertia of 400 kg named at its
    search bound (twice the top of its typical range), held-out MSE -8.7 %, interval 31-769 kg. A refit
    stopped by its bound patches another error; so does one whose interval lies wholly above what a damper
    of this size has. Both rules act on the fitted values (``_within_bounds``, ``_attach_interval``)."""
    from tuner.diagnosis.rules import within_bounds as _within_bounds

    bounds = {"inertia_mass": (0.0, 400.0), "preload_force": (-2e3, 2e3)}
    assert not _within_bounds({"inertia_mass": 400.0}, bounds)
    assert not _within_bounds({"inertia_mass": 395.0}, bounds)  # within 2 % of the bound
    assert _within_bounds({"inertia_mass": 120.0}, bounds)
    assert not _within_bounds({"preload_force": -1990.0}, bounds)  # the lower bound of a two-sided range
    assert _within_bounds({"preload_force": 0.0}, bounds)
    at_bound = {**_row("inertia", 0.09, 80.0), "within_bounds": False}
    implausible = {**_row("friction", 0.5, 300.0), "plausible": False}
    cause, _, rejected = decide([implausible, at_bound, _row("none", 0.0, 0.0)])
    assert cause == "none" and {r["effect"] for r in rejected} == {"inertia", "friction"}


def test_a_magnitude_just_above_its_typical_range_is_plausible_one_far_above_it_is_not():
    """Blind seed 992: a 231 N rod-seal friction on a 15.4 kN damper, whose typical range (the catalogue's
    50-300 N scaled) ends at 232 N, fitted at 245 N beside a free play with an interval wholly above 232 N, was
    refused as a patch. A typical range is not a limit: up to twice its top the interval is plausible; a friction
    of 1.4 kN (a form gap patched, blind seed 959's friction refitted alone) is not."""
    from types import SimpleNamespace

    from tuner.diagnosis.search.rows import attach_interval

    ext = SimpleNamespace(peak_force=15.4e3, stroke_range_m=0.08, extra=["friction_force"])

    def row_with(low, high):
        row = {"effect": "friction"}
        ci = {"friction_force": {"low": low, "high": high, "excludes_zero": True}, "_blocks": 100}
        attach_interval(row, ci, ext, ["friction_force"])
        return row

    top = 300.0 * 15.4e3 / 20e3
    assert row_with(238.0, 251.0)["plausible"]  # 3-9 % above the top: a large friction, not a patch
    assert row_with(1.3e3, 1.5e3)["plausible"] is False
    assert row_with(2.05 * top, 2.3 * top)["plausible"] is False
    assert row_with(1.9 * top, 2.3 * top)["plausible"]  # reaches into the plausible range


def test_the_best_resolved_effect_above_the_threshold_is_named():
    ranking = [_row("time_delay", 0.9, 3.0), _row("valve_lag", 0.6, 40.0), _row("inertia", 0.04, 80.0),
               _row("none", 0.0, 0.0)]
    cause, best, unresolved = decide(ranking)
    assert cause == "valve_lag" and [r["effect"] for r in unresolved] == ["time_delay"]
    assert decide([_row("inertia", 0.04, 80.0), _row("none", 0.0, 0.0)])[0] == "none"


def test_a_delay_the_residual_does_not_show_is_not_a_cause():
    """The real-data case: a fitted 2.7 ms delay where the residual's regression says 0.15 ms."""
    row = {**_row("time_delay", 0.3, 200.0), "parameters": {"time_delay": 2.7e-3}}
    ranking = [row, _row("none", 0.0, 0.0)]
    assert cross_check(ranking, {"effects": {"time_delay": {"value": 0.15e-3}}}) == [row]
    assert decide(ranking)[0] == "none"
    row2 = {**_row("time_delay", 0.3, 200.0), "parameters": {"time_delay": 2.7e-3}}
    assert cross_check([row2], {"effects": {"time_delay": {"value": 2.2e-3}}}) == []
    assert decide([row2, _row("none", 0.0, 0.0)])[0] == "time_delay"


def test_a_delay_that_removes_most_of_the_held_out_error_is_its_own_evidence():
    """The blind pair friction + delay (seed 1240): an 8.5 ms delay the base absorbed into its series compliance,
    fitted at 8.14 ms with the held-out MSE -94.7 %, while the base residual's first-order regression showed far
    less. Refusing it left the damper 'unexplained' at 32 x the floor. A delay that removes most of the held-out
    error needs no agreement with that regression; the real-data delay of the test above (-27 %) still does."""
    def row(change_pct):
        return {**_row("time_delay", 2.9, 1040.0), "parameters": {"time_delay": 8.14e-3},
                "validation_mse_change_pct": change_pct}
    seen = {"effects": {"time_delay": {"value": 0.9e-3}}}
    assert cross_check([row(-94.7)], seen) == []
    assert cross_check([row(-94.7)], {"effects": {}}) == []  # no regression at all
    refused = row(-27.0)
    assert cross_check([refused], seen) == [refused] and not refused["resolved"]


def test_a_delay_named_before_is_not_judged_again_when_another_effect_is_added_on_top():
    """The blind pair friction + delay (seed 1262): a 2.2 ms delay named for its -98 % (the residual's regression
    disagrees), then a 64 N friction on top of it winning 60 % more was refused for that same delay. Only the row
    that adds the delay is checked."""
    seen = {"effects": {"time_delay": {"value": 0.2e-3}}}
    friction_on_delay = {**_row("time_delay+friction", 0.9, 63.0), "added": "friction",
                         "parameters": {"time_delay": 2.2e-3, "friction_force": 63.6},
                         "validation_mse_change_pct": -60.2}
    assert cross_check([friction_on_delay], seen) == [] and friction_on_delay["resolved"]
    delay_on_friction = {**_row("friction+time_delay", 0.9, 63.0), "added": "time_delay",
                         "parameters": {"time_delay": 2.2e-3, "friction_force": 63.6},
                         "validation_mse_change_pct": -60.2}
    assert cross_check([delay_on_friction], seen) == [delay_on_friction] and not delay_on_friction["resolved"]


def test_a_delay_the_base_absorbs_is_weighed_against_what_it_would_leave_in_the_residual():
    """Blind pair seed 1339 (a 3.35 ms delay, a 38 N friction): the lumped base absorbed 99 % of a delay's
    signature, so its residual showed 0.021 ms against 1.95 ms fitted (held-out MSE -71 %), and the delay was
    refused, 'unexplained'. A real delay d leaves d (1 - share) in the residual: weighed against that it agrees.
    A share below CONFOUNDED_SHARE keeps the plain check (the real-data delay of the test above, -27 %)."""
    from tuner.diagnosis.rules import CONFOUNDED_SHARE, expected_residual_delay

    def row(share):
        return {**_row("time_delay", 1.2, 190.0), "parameters": {"time_delay": 1.95e-3},
                "validation_mse_change_pct": -71.1, "delay_absorbed_share": share}
    seen = {"effects": {"time_delay": {"value": 0.0213e-3}}}
    absorbed = row(0.99)
    assert expected_residual_delay(absorbed) == pytest.approx(1.95e-5)
    assert cross_check([absorbed], seen) == [] and absorbed["resolved"]
    plain = row(CONFOUNDED_SHARE - 0.01)
    assert expected_residual_delay(plain) == 1.95e-3
    assert cross_check([plain], seen) == [plain] and not plain["resolved"]
    too_much = row(0.999)   # 0.00195 ms expected: the residual shows 11 x that
    assert cross_check([too_much], seen) == [too_much]


def test_a_named_delay_the_base_absorbs_is_said_to_trade_with_the_base():
    """Seed 1339 named: 2.06 ms (95 %: 2.03-2.08) for a 3.35 ms delay, the base absorbing 99 % of its signature;
    the verdict says the size trades with the base's elements beyond the interval. The share comes from the row
    that added the delay (a forward step's here); below CONFOUNDED_SHARE nothing is said."""
    from tuner.diagnosis.rules import CONFOUNDED_SHARE
    from tuner.diagnosis.search.conclusion import delay_share
    from tuner.diagnosis.verdict import traded_delay_text

    ranking = [{**_row("time_delay", 1.2, 190.0), "delay_absorbed_share": 0.5}, _row("none", 0.0, 0.0)]
    step = {"cause": "time_delay", "tried": [{**_row("friction+time_delay", 0.9, 60.0), "added": "time_delay",
                                              "delay_absorbed_share": 0.989},
                                             {**_row("friction+preload", 0.1, 20.0), "added": "preload"}]}
    assert delay_share(ranking, [step]) == 0.989
    assert delay_share([_row("friction", 1.0, 50.0)], []) == 0.0
    text = traded_delay_text({"delay_absorbed_share": 0.989})
    assert "99 % of the delay's signature" in text and "trades" in text
    assert traded_delay_text({"delay_absorbed_share": CONFOUNDED_SHARE - 0.01}) == traded_delay_text({}) == ""


def test_a_delay_the_base_absorbs_is_restarted_held_at_larger_values_then_released():
    """Seed 1339: the delay's refit stopped at 1.95 ms of 3.35 ms (the series compliance took the rest) and restarts
    with the delay free came back there; held at 1.5 and 2.25 x while the rest is refitted, then released, both
    reached 3.35 ms. Those starts are tried only for a delay the base absorbs (CONFOUNDED_SHARE)."""
    from types import SimpleNamespace

    from tuner.diagnosis.rules import CONFOUNDED_SHARE
    from tuner.diagnosis.search.selection import DELAY_RESTARTS, restart_points

    s = SimpleNamespace(guess={"k_B": 1e8, "time_delay": 0.0}, coarser=None)
    fit = SimpleNamespace(params=lambda: {"k_B": 3e7, "time_delay": 1.95e-3},
                          ext=SimpleNamespace(extra=["time_delay"]))
    points = restart_points(s, fit, {"delay_absorbed_share": 0.989})
    held = [(start, h) for _, start, h in points if h]
    assert [h["time_delay"] for _, h in held] == pytest.approx([f * 1.95e-3 for f in DELAY_RESTARTS])
    assert all(start["time_delay"] == h["time_delay"] and start["k_B"] == 1e8 for start, h in held)
    assert points[0][1] == {"k_B": 1e8, "time_delay": 1.95e-3} and points[0][2] is None   # the guess, as before
    assert all(h is None for *_, h in restart_points(s, fit, {"delay_absorbed_share": CONFOUNDED_SHARE - 0.01}))


def test_a_real_delay_leaves_its_unabsorbed_share_in_a_least_squares_residual():
    """The identity behind ``expected_residual_delay``: the base's residual after a least-squares refit of a
    delay's first-order signature d g (g = -dF/dt) is d (I - P) g, P the projection on the base Jacobian's
    columns, and its regression on g is d (1 - share), share = |P g|^2 / |g|^2 as ``detection.absorption``
    computes it."""
    from tuner.diagnosis.detection import absorption

    rng = np.random.default_rng(3)
    jacobian = rng.normal(size=(400, 6))
    g = jacobian @ rng.normal(size=6) + 0.1 * rng.normal(size=400)   # mostly in the base's span
    d = 2.0e-3
    data = d * g
    step, *_ = np.linalg.lstsq(jacobian, data, rcond=None)
    residual = data - jacobian @ step
    share, _ = absorption(g, jacobian)
    assert 0.9 < share < 1.0
    assert float(residual @ g) / float(g @ g) == pytest.approx(d * (1.0 - share), rel=1e-9)


def test_delay_agreement_allows_for_what_the_base_refit_absorbed():
    """The lumped blind case: 2.20 ms fitted (2.22 ms hidden) while the base residual showed 0.71 ms
    (the base refit had absorbed two thirds); a residual showing more than three times the fitted
    delay, or a fitted delay more than five times the residual's, is disagreement."""
    def agrees(fitted, seen):
        row = {**_row("time_delay", 0.3, 200.0), "parameters": {"time_delay": fitted}}
        return cross_check([row], {"effects": {"time_delay": {"value": seen}}}) == []
    assert agrees(2.20e-3, 0.71e-3)
    assert not agrees(2.20e-3, 0.40e-3)      # ratio 5.5
    assert not agrees(0.50e-3, 1.60e-3)      # the residual shows more than three times the fit
    assert not agrees(1.0e-3, -1.0e-3)       # opposite sign


@pytest.mark.slow
def test_a_free_play_in_a_damper_unlike_the_preset_is_named_on_the_base_that_made_it(tmp_path):
    """A 0.6 mm free play hidden in a random lumped damper of the class (six 8 s tests at 500 Hz, 25 N noise;
    the held-out benchmark's case at a third of its length): a free play's force has no gradient at zero
    gap, so a local refit from zero cannot find it; the screen profiles it over its magnitude and the
    refit starts where the gap shows. The fitted base has absorbed part of the dead band into a soft elastic
    table, so the profile re-fits the model at each gap (re-balanced on the base's Jacobian alone it ended at
    0.28 mm). Named on the lumped base (the form that made the data) within 10 %.
    ``benchmarks/blind_class.py`` runs free plays of 0.05-1 mm, soft and impact-like, on many dampers."""
    from campaign.damper_class import write_class_dataset

    data = write_class_dataset(tmp_path / "data", "lumped", 4, noise_n=25.0, hidden={"free_play": 0.6e-3},
                               sample_rate=500.0, durations=(8.0,) * 6)
    tests = load_dataset(data)
    res = diagnose([t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"],
                   DiagnosisSettings(engine=fastest_engine(), base_model="lumped", base_iterations=0,
                                     candidates=("friction", "free_play"), forms=()),
                   log=lambda m: None)
    assert res["base_model"] == "lumped" and res["causes"] == ["free_play"], res["verdict"]
    assert res["effect_parameters"]["free_play"]["value"] == pytest.approx(0.6e-3, rel=0.1)


@pytest.mark.slow
@pytest.mark.full  # about 6 min on 2 cores (benchmarks/blind_class.py --model twochamber runs this damper, seed 500)
def test_a_gap_the_two_chamber_base_absorbed_is_found_from_the_data_driven_guess(tmp_path):
    """A 0.516 mm free play in the soft mounts of a random two-chamber damper (six 12-16 s tests at 500 Hz,
    25 N noise), diagnosed blind. The two-chamber base fitted without the gap absorbs it as entrained air
    and a small area ratio, where no refit from it gives the gap back (it ended 'unexplained'); the held
    profile also started from the data-driven guess names it on the two-chamber base within 2 %."""
    from campaign.damper_class import write_class_dataset

    data = write_class_dataset(tmp_path / "data", "twochamber", 500, noise_n=25.0, sample_rate=500.0,
                               hidden={"free_play": 0.5157e-3})
    tests = load_dataset(data)
    res = diagnose([t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"],
                   DiagnosisSettings(engine=fastest_engine()), log=lambda m: None)
    assert res["base_model"] == "twochamber" and res["causes"] == ["free_play"], res["verdict"]
    assert res["effect_parameters"]["free_play"]["value"] == pytest.approx(0.5157e-3, rel=0.02)


@pytest.mark.slow
def test_two_effects_hidden_together_are_both_named(tmp_path):
    rng = np.random.default_rng(2024)
    hidden = {e: float(rng.uniform(EFFECTS[e].low, EFFECTS[e].high)) for e in ("friction", "inertia")}
    res = run_diagnosis(tmp_path, hidden, seed=17, base_model="lumped")
    assert sorted(res["causes"]) == ["friction", "inertia"], (res["verdict"], res["selection"])
    for e, value in hidden.items():
        p = res["effect_parameters"][EFFECTS[e].model_parameter]
        assert p["value"] == pytest.approx(EFFECTS[e].model_sign * value, rel=0.3)
        assert p["interval_95"][0] > 0.0  # significant
    assert (tmp_path / "out" / "fmu" / f"DamperLumped_{'_'.join(res['causes'])}_tuned.fmu").exists()


@pytest.mark.slow
def test_a_free_play_and_a_rod_seal_friction_together_are_both_named(tmp_path):
    """A worn damper: a 0.41 mm free play and a 216 N rod-seal friction hidden together in a random lumped damper
    with soft, lightly damped silent blocks (``benchmarks/blind_class.py --broad --cases free_play+friction``'s
    first pair, seed 915, four tests instead of six). Beside the unexplained free play the friction's refit on the
    base does not earn its score; screened again on top of the free play it is refitted and named."""
    from campaign.damper_class import write_class_dataset

    hidden = {"k_B": 4.31e7, "c_B": 5.99e4, "free_play": 0.413e-3, "friction_force": 216.0}
    data = write_class_dataset(tmp_path / "data", "lumped", 915, noise_n=34.0, hidden=hidden,
                               durations=[14.0, 13.0, 12.0, 13.0])
    tests = load_dataset(data)
    res = diagnose([t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"],
                   DiagnosisSettings(engine=fastest_engine(), base_model="lumped"), log=lambda m: None)
    assert sorted(res["causes"]) == ["free_play", "friction"], (res["verdict"], res["selection"])
    for name in ("free_play", "friction_force"):
        assert res["effect_parameters"][name]["value"] == pytest.approx(hidden[name], rel=0.3)


@pytest.mark.slow
def test_a_delay_and_a_friction_get_no_false_preload_from_a_model_stuck_where_the_first_cause_left_it(tmp_path):
    """An 8.8 ms channel delay and a 268 N rod-seal friction, no preload (``benchmarks/blind_class.py --broad --cases
    friction+time_delay``, seed 1273, 1 kHz, 18 N noise). The base absorbs the delay into its tables; refitted from
    there the delay + friction model stops at 30 N rms (converged), and a preload of -310 N on top then wins 17 % of
    the held-out MSE and was named. The model of the causes found is refitted from the data-driven guess before each
    forward step (``selection.restarted``), which reaches 13 N (the true parameters leave 13.4 N): no preload."""
    from campaign.damper_class import write_class_dataset

    hidden = {"k_B": 7.54e7, "c_B": 2.92e3, "friction_force": 268.0, "time_delay": 8.83e-3}
    data = write_class_dataset(tmp_path / "data", "lumped", 1273, noise_n=18.3, sample_rate=1000.0, hidden=hidden)
    tests = load_dataset(data, check_plausible=False)
    res = diagnose([t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"],
                   DiagnosisSettings(engine=fastest_engine(), base_model="lumped", forms=(),
                                     candidates=("friction", "preload", "time_delay", "free_play")), log=lambda m: None)
    assert sorted(res["causes"]) == ["friction", "time_delay"], (res["verdict"], res["selection"])
    for name in ("friction_force", "time_delay"):
        assert res["effect_parameters"][name]["value"] == pytest.approx(hidden[name], rel=0.05)


@pytest.mark.slow
def test_a_delay_refused_for_the_residual_s_delay_is_refitted_from_the_guess_before_it_is_refused(tmp_path):
    """A 4.4 ms channel delay and a 340 N rod-seal friction (``benchmarks/blind_class.py --broad --cases
    friction+time_delay``, seed 1306, 1 kHz, 30 N noise). The delay's refit from the base, whose series compliance
    had absorbed part of it, stopped at 2.8 ms with -62 % held-out MSE; the residual's first-order delay (0.32 ms,
    the friction beside it dominates that residual) disagreed, the delay was refused, and with nothing named the
    friction was never tried on top: 'unexplained' at 15 x the floor. A delay that scored and is refused so is
    refitted from the data-driven guess first (as the model of the causes found is before each forward step):
    4.1 ms, -84 % against the base, self-evident; the friction on top, both at their truth."""
    from campaign.damper_class import write_class_dataset

    hidden = {"k_B": 9.27e7, "c_B": 8.46e6, "friction_force": 340.4, "time_delay": 4.411e-3}
    data = write_class_dataset(tmp_path / "data", "lumped", 1306, noise_n=30.2, sample_rate=1000.0, hidden=hidden)
    tests = load_dataset(data, check_plausible=False)
    res = diagnose([t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"],
                   DiagnosisSettings(engine=fastest_engine(), base_model="lumped", forms=(),
                                     candidates=("friction", "time_delay")), log=lambda m: None)
    assert sorted(res["causes"]) == ["friction", "time_delay"], (res["verdict"], res["selection"])
    for name in ("friction_force", "time_delay"):
        assert res["effect_parameters"][name]["value"] == pytest.approx(hidden[name], rel=0.05)


def test_the_diagnosis_base_is_the_fitted_form_with_the_lower_pooled_held_out_mse():
    """choose_base pools the validation tests sample-weighted (a long test counts more) and ignores
    models without the effect catalogue (Maxwell) and the identification tests."""
    from tuner.diagnosis.diagnose import choose_base

    def row(mse, n):
        return {"mse": mse, "n": n}

    params = {m: {"values": {"tag": m}} for m in ("lumped", "maxwell", "twochamber")}
    metrics = {"tests": {
        "id": {"role": "identification", "models": {"lumped": row(1.0, 100), "maxwell": row(0.1, 100),
                                                    "twochamber": row(900.0, 100)}},
        "short": {"role": "validation", "models": {"lumped": row(100.0, 10), "maxwell": row(1.0, 10),
                                                   "twochamber": row(10.0, 10)}},
        "long": {"role": "validation", "models": {"lumped": row(20.0, 1000), "maxwell": row(1.0, 1000),
                                                  "twochamber": row(30.0, 1000)}}}}
    kind, values, choice, others = choose_base(params, metrics)
    assert kind == "lumped" and values == {"tag": "lumped"}
    assert others == {"twochamber": {"tag": "twochamber"}}  # the fallback of a diagnosis left unexplained
    assert choice["validation_mse"]["lumped"] == pytest.approx((100.0 * 10 + 20.0 * 1000) / 1010)
    assert "maxwell" not in choice["validation_mse"]
    with pytest.raises(ValueError, match="lumped"):
        choose_base({"maxwell": params["maxwell"]}, metrics)


def _two_chamber_data(tmp_path):
    from campaign.synthetic import write_model_dataset
    from damper_fmu import defaults

    path = write_model_dataset(tmp_path / "data", "twochamber", defaults("twochamber"), seed=9,
                               durations=(6.0, 6.0, 4.0), roles=("identification", "identification", "validation"),
                               noise_n=20.0)
    tests = load_dataset(path)
    return [t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"]


def test_the_diagnosis_is_not_repeated_on_a_base_that_cannot_plausibly_win(tmp_path):
    """Two-chamber-model data, the lumped base first (it leaves ~70 x the floor), the other base given with
    its damping tables 8 x too strong: its bare fit validates ~70 x worse than the lumped one, so it cannot
    plausibly win: no repeat, and the result says why. (The repeat where the other base can win, and wins,
    is ``tests/test_forms.py``'s failing-and-resumed diagnosis: lumped first, then the two-chamber base.)"""
    from damper_fmu import defaults

    ident, val = _two_chamber_data(tmp_path)
    tc = defaults("twochamber")
    tc = {**tc, **{k: 8 * v for k, v in tc.items() if k.startswith("Fc_") and not k.startswith("Fc_v")}}
    res = diagnose(ident, val, DiagnosisSettings(engine=fastest_engine(), candidates=("preload",)),
                   from_fit=FittedBases("lumped", defaults("lumped"), others={"twochamber": tc}),
                   log=lambda m: None)
    assert res["base_model"] == "lumped" and res["cause"] == "unexplained", res["verdict"]
    assert "cannot plausibly win" in res["base_choice"]["not_repeated_on"]["twochamber"]
    assert list(res.residuals) == ["figures"]  # the lumped base's figures only: no figures/base_twochamber


def test_an_unfinished_fit_is_not_called_a_form_error_nor_a_reason_to_switch_base(tmp_path):
    """Lumped-model data (no form error on the lumped base) diagnosed from a base far off (tables at
    half) with a refit budget of one Jacobian: the residual stays far above the floor, but the refit
    has not converged, so the verdict must not claim a model-form error and the diagnosis must not
    move to the two-chamber base because of it."""
    from campaign.synthetic import write_model_dataset
    from damper_fmu import defaults

    path = write_model_dataset(tmp_path / "data", "lumped", defaults("lumped"), seed=4,
                               durations=(6.0, 6.0, 4.0), roles=("identification", "identification", "validation"),
                               noise_n=20.0)
    tests = load_dataset(path)
    start = defaults("lumped")
    start.update({k: 0.5 * v for k, v in start.items() if k.startswith("Fc_") and not k.startswith("Fc_v")})
    res = diagnose([t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"],
                   DiagnosisSettings(engine=fastest_engine(), candidates=("preload",),
                                     polish_jacobians=2, final_jacobians=1, guess_start=False),
                   from_fit=FittedBases("lumped", start, others={"twochamber": defaults("twochamber")}),
                   log=lambda m: None)
    u = res["unexplained"]
    assert u is not None and u["fit_converged"] is False, res["verdict"]
    assert "NOT shown to be a model-form error" in res["verdict"]
    assert "model-form error that no catalogue" not in res["verdict"]
    assert res["base_model"] == "lumped"
    assert "did not converge" in res["base_choice"]["not_repeated_on"]["twochamber"]


def test_a_residual_is_not_judged_against_a_floor_that_is_not_credible(tmp_path):
    """Lumped-model data whose force and stroke were low-pass filtered (at 0.1 x the 1 kHz rate, as a
    rig's software may) and whose strokes repeat nothing: no noise estimate is credible (the spectrum
    collapses, there are no cycles). Diagnosed from a base far off with a budget that cannot close
    the gap, the residual is far above the collapsed floor -- the same setting reports 'unexplained'
    on unfiltered data -- but here the verdict must not call it "N x the floor" nor a form error, and
    must say that the noise estimate is not credible."""
    from scipy import signal

    from campaign.synthetic import model_tests
    from tuner.data.reading import RigTest

    sos = signal.butter(4, 0.2, output="sos")
    tests = [RigTest(name=c["name"], role=c["role"], scenario=c["scenario"], time=c["frame"]["time"].to_numpy(),
                     stroke=signal.sosfiltfilt(sos, c["frame"]["stroke"].to_numpy()),
                     force=signal.sosfiltfilt(sos, c["frame"]["force"].to_numpy()), sample_rate=1000.0)
             for c in model_tests("lumped", defaults("lumped"), seed=4, durations=(6.0, 6.0, 4.0),
                                  roles=("identification", "identification", "validation"), noise_n=20.0)]
    start = defaults("lumped")
    start.update({k: 0.5 * v for k, v in start.items() if k.startswith("Fc_") and not k.startswith("Fc_v")})
    res = diagnose([t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"],
                   DiagnosisSettings(engine=fastest_engine(), candidates=("preload",),
                                     polish_jacobians=2, final_jacobians=1, guess_start=False),
                   from_fit=FittedBases("lumped", start), log=lambda m: None)
    write_diagnosis(res, tmp_path / "out", log=lambda m: None)
    assert res["residual_floor_credible"] is False and res["noise"]["credible"] is False
    assert res["unexplained"] is None and res["cause"] != "unexplained", res["verdict"]
    assert "x the residual floor" not in res["verdict"] and "noise estimate not credible" in res["verdict"]
    saved = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert saved["noise"]["tests"]["lumped_ide1"]["all"]["quiet_band"]["credible"] is False


def test_typical_effect_sizes_scale_with_the_damper():
    """tuner.diagnosis.effect_sizes: forces and the equivalent mass with the peak force, lengths with the
    stroke range (never above the catalogue's), times unchanged; the reference damper keeps the catalogue."""
    from damper_fmu.effect_catalogue import effect_of
    from tuner.diagnosis.effect_sizes import REFERENCE, DamperSize, meaningful_floor, typical_range

    assert typical_range("friction_force", REFERENCE) == effect_of("friction_force").typical["friction_force"]
    small = DamperSize(peak_force_n=REFERENCE.peak_force_n / 30, stroke_range_m=REFERENCE.stroke_range_m / 4)
    assert typical_range("friction_force", small) == pytest.approx((50 / 30, 300 / 30))
    assert typical_range("inertia_mass", small) == pytest.approx((20 / 30, 200 / 30))
    assert typical_range("free_play", small) == pytest.approx((1e-4 / 4, 1e-3 / 4))
    assert typical_range("valve_tau", small) == effect_of("valve_tau").typical["valve_tau"]
    big = DamperSize(peak_force_n=REFERENCE.peak_force_n, stroke_range_m=10 * REFERENCE.stroke_range_m)
    assert typical_range("free_play", big) == effect_of("free_play").typical["free_play"]  # a clearance does not grow with the stroke
    assert meaningful_floor("inertia_mass", small) == pytest.approx(0.5 * 20 / 30)


def test_a_cause_on_a_damper_30_times_smaller_is_named_at_its_own_scale(tmp_path):
    """The preset lumped damper with its damping characteristic scaled by 1/30 (peaks of ~0.8 kN; the
    series chain, inside the model's bounds, stays as stiff), 0.3 N of noise and a 6 N friction hidden: on
    the catalogue's railway sizes a 6 N friction is below the 25 N 'meaningful' floor and would be refused;
    scaled to the damper (floor ~1 N) it is named, near the truth."""
    from campaign.synthetic import write_model_dataset
    from damper_fmu import defaults

    small = {k: (v / 30 if k.startswith("Fc_") and not k.startswith("Fc_v") else v)
             for k, v in defaults("lumped").items()}
    path = write_model_dataset(tmp_path / "data", "lumped", {**small, "friction_force": 6.0}, seed=4,
                               durations=(6.0, 6.0, 4.0), roles=("identification", "identification", "validation"),
                               noise_n=0.3)
    tests = load_dataset(path, check_plausible=False)
    res = diagnose([t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"],
                   DiagnosisSettings(engine=fastest_engine(), base_iterations=0, base_model="lumped",
                                     candidates=("friction",)),
                   from_fit=FittedBases("lumped", small), log=lambda m: None)
    assert res["causes"] == ["friction"], res["verdict"]
    p = res["effect_parameters"]["friction_force"]
    assert p["value"] == pytest.approx(6.0, rel=0.2)
    lo, hi = p["typical_range"]  # the catalogue's 50-300 N at this damper's peak force (~0.8 kN of 20 kN)
    assert 0.5 < lo < 3.0 and 8.0 < hi < 20.0 and p["plausible"], p
    assert p["plausible_range"] == pytest.approx([lo / 2, 2 * hi]), p


def test_a_conclusion_a_rescue_replaces_is_kept_with_the_forms_it_tried(monkeypatch):
    """When nothing is named and a free play no screen passed is refitted and scores
    (``refit_unseen_nonsmooth``), the diagnosis concludes again; the first conclusion's forms (tried on the base,
    none named) stay in diagnosis.json under ``before_rescue``; without a rescue that field is null."""
    from tuner.diagnosis.search import conclusion
    from tuner.diagnosis.search.conclusion import Conclusion, before_rescue, concluded
    from tuner.diagnosis.search.state import SearchState

    tried = [{"effect": "bypass", "score": -0.02}]
    first = Conclusion("unexplained", [], {}, [], [], {"tried": tried, "form": None}, None)
    second = Conclusion("free_play", ["free_play"], {}, [], [], None, None)
    search = SearchState.__new__(SearchState)
    for rescued_scores, expected in ((0.9, (second, first)), (-0.02, (first, None))):
        ends = iter([first, second])
        search.ranking = [{"effect": "free_play", "refitted": False, "score": 0.0}]
        monkeypatch.setattr(conclusion, "conclude", lambda s, refitted: next(ends))

        def rescue(_, s=rescued_scores):
            search.ranking[0] = {"effect": "free_play", "refitted": True, "score": s, "effect_rms_n": 900.0,
                                 "resolved": True, "significant": True, "meaningful": True}
            return ["free_play"]

        monkeypatch.setattr(conclusion, "refit_unseen_nonsmooth", rescue)
        assert concluded(search) == expected
    assert before_rescue(first) == {"cause": "unexplained", "forms_tried": tried, "forms_weighed": None}
    assert before_rescue(None) is None


def test_an_interval_whose_steps_cannot_be_simulated_is_not_significant_and_says_why():
    """Blind seed 1396: a two-chamber refit whose stepped points the stage's Newton could not solve ended the whole
    diagnosis with a KeyError in the intervals. The interval is then unbounded, its row not significant (nothing is
    named on it), and the log and the verdict's reason say what failed."""
    from tuner.diagnosis.extended_parametrization import ExtendedParametrization
    from tuner.diagnosis.refit import effect_intervals
    from tuner.diagnosis.rules import earned
    from tuner.diagnosis.search.rows import attach_interval
    from tuner.diagnosis.verdict import why_not
    from tuner.identification.parametrization import Parametrization

    ext = ExtendedParametrization(Parametrization("lumped"), "inertia", 20e3, 0.04)

    class Failing:  # the fitted point simulates, one of its steps does not
        last_failure = "two-chamber stage: Newton stalled"

        def residuals_batch(self, points):
            return [np.zeros(10)] + [None] * (len(points) - 1)

    ci = effect_intervals(Failing(), ext, np.full(ext.dimension, 0.5))
    assert ci["_blocks"] == 0 and "Newton stalled" in ci["_not_computed"]
    assert ci["inertia_mass"]["excludes_zero"] is False
    row = {"effect": "inertia", "score": 0.12, "resolved": True, "parameters": {"inertia_mass": 200.0}}
    attach_interval(row, ci, ext, ["inertia_mass"])
    assert row["significant"] is False and not earned(row)
    assert "could not be computed" in why_not(row, 20.0) and "Newton stalled" in why_not(row, 20.0)


def test_the_causes_one_base_named_travel_to_the_repeat_on_the_other():
    """``named_effects``: a repeat on another base form gets the catalogue causes the first named, each at the
    first's final values (its identified parameters only), never a form beyond the catalogue nor a non-candidate."""
    from tuner.diagnosis.diagnose import named_effects

    run = {"causes": ["free_play", "preload", "hysteresis"],
           "after_params": {"free_play": 3.4e-4, "preload_force": 295.0, "k_B": 1e8, "friction_force": 0.0}}
    found = named_effects(run, DiagnosisSettings())
    assert found == {"free_play": {"free_play": 3.4e-4}, "preload": {"preload_force": 295.0}}
    assert named_effects({"causes": [], "after_params": {}}, DiagnosisSettings()) == {}
    only_friction = DiagnosisSettings(candidates=("friction",))
    assert named_effects(run, only_friction) == {}


def test_the_series_ladder_releases_only_a_gap_the_data_can_show(monkeypatch):
    """``series_ladder`` releases the series element (a joint polish from the profile's best) only when the profile's
    best fits better than the base refit by more than ``gain_n`` [N of RMSE]; ``refit_unseen`` asks one standard
    error of the RMSE (a profile 0.2 N better on the 0.25 A MR current was released and refitted in full, 157 s,
    for a 2.2 N gap force below the noise). With ``gain_n`` 0 any better point releases, as before."""
    from types import SimpleNamespace

    from tuner.diagnosis.cost_model import DiagnosisCost
    from tuner.diagnosis.search import nonsmooth
    from tuner.diagnosis.search.state import Fit

    n, sse_none = 1000, 1000 * 20.0 ** 2  # the base refit at 20 N rms
    released, beat = [], []

    def series_profiles(eid, ext, z0, i, values, held, targets):
        assert targets.coarse is None  # no windows: the coarse passes judged on every sample
        beat.append(targets.sse_off)  # the profile releases and sweeps a held value only below this SSE [N^2]
        best = n * 19.5 ** 2  # its best 0.5 N better than the base refit
        return SimpleNamespace(sse=[best, n * 25.0 ** 2], points=[np.zeros(2), np.ones(2)], evaluations=7,
                               coarse_best=best, released=best < targets.coarse_sse_off)

    monkeypatch.setattr(nonsmooth, "series_profiles", series_profiles)
    monkeypatch.setattr(nonsmooth, "grid", lambda lo, hi, points, floor: [lo, hi])

    def polish_quietly(par, z, jacobians):
        released.append(z)
        return SimpleNamespace(fitness=1.0 / 21.0 ** 2, z=z, evaluations=3)  # no better: the row stays the base refit's

    ext = SimpleNamespace(extra=["free_play"], extra_bounds=[(0.0, 1e-3)], floors=[1e-6],
                          from_params=lambda p: np.zeros(2))
    s = SimpleNamespace(
        kind="lumped", credible=True, floor=1.0, coarser=None, settings=DiagnosisSettings(), log=lambda m: None,
        par=Parametrization("lumped", force_limit=4e4), guess={"k_B": 1e7, "c_B": 1e4}, peak=1e3, stroke_range=0.05,
        cost=DiagnosisCost(reference=0.0, screen=0.0, refits=0.0, forms=0.0, detection=0.0), forecast=lambda: None,
        base={}, z_none=np.zeros(1), eid=SimpleNamespace(n_samples=n), ew=None, g_none=n / sse_none, share=2,
        resolvable_n=1.0, sweep_gain_n=0.25,
        refits={"free_play": Fit(ext, np.zeros(2), 10)}, polish_quietly=polish_quietly)
    s.par.to_params = lambda z: {}
    s.above_floor = lambda rmse, floor=None: rmse > 2.0
    row = {"effect": "free_play", "identification_rmse_n": 20.0}
    held = nonsmooth.series_ladder(s, "free_play", ext, row, gain_n=1.0)  # 0.5 N better, one standard error 1 N
    assert held["gap_fits_better"] is False and held["series_element_released"] is False and not released
    released_row = nonsmooth.series_ladder(s, "free_play", ext, row, gain_n=0.0)
    assert len(released) == 1 and "gap_fits_better" not in released_row
    assert np.allclose(beat, [n * 19.0 ** 2, sse_none])


def test_the_ladders_gate_on_the_windows_is_the_base_refitted_there_not_the_base_point():
    """On the search's windows the base point fitted on every sample is not a minimum: a coarse pass that only
    re-fits the base there would beat it by its whole misfit. ``coarse_gate`` re-fits the base on the windows (the
    gap held at zero) and asks a gap to beat that by one standard error of its RMSE (``gain_n`` > 0; none with
    ``gain_n`` 0); without windows it asks the base refit's RMSE less ``gain_n`` on every sample."""
    from types import SimpleNamespace

    from tuner.diagnosis.search.nonsmooth import CoarseGate, coarse_gate
    from tuner.metrics import rmse_standard_error

    ext = ExtendedParametrization(Parametrization("maxwell", force_limit=4e4), "free_play", peak_force=2e4)
    noise = np.random.default_rng(3).normal(scale=4.0, size=600)

    class Windows:  # the windows' residual [N]: noise and a misfit of the first base coordinate (best at 0.7)
        n_samples = noise.size

        def residuals_batch(self, points):
            return [noise + 60.0 * (float(ext.base.from_params(p)[0]) - 0.7) for p in points]

    none = np.full(ext.dimension, 0.5)
    none[-1] = 0.0  # the gap off
    at_none = Windows().residuals_batch([ext.to_params(none)])[0]
    s = SimpleNamespace(ew=Windows(), eid=SimpleNamespace(n_samples=2000), g_none=1.0 / 10.0 ** 2)

    def whole(gain_n):  # the gate on every sample: the base refit at 10 N rms on 2000 samples
        return CoarseGate.of(None, 2000, 10.0, gain_n)

    gate = coarse_gate(s, ext, none, "free_play", whole(1.0))
    assert gate.engine is s.ew and gate.n_samples == noise.size
    assert gate.rmse_n == pytest.approx(math.sqrt(np.mean((noise - noise.mean()) ** 2)), rel=0.01)
    assert gate.rmse_n < 0.5 * math.sqrt(np.mean(at_none ** 2))  # the base point's misfit is not a gap's gain
    assert gate.gain_n == pytest.approx(rmse_standard_error(noise - noise.mean()), rel=0.05)
    assert gate.sse_beat == pytest.approx(noise.size * (gate.rmse_n - gate.gain_n) ** 2)
    assert coarse_gate(s, ext, none, "free_play", whole(0.0)).gain_n == 0.0
    uncut = coarse_gate(SimpleNamespace(ew=s.eid, eid=s.eid, g_none=s.g_none), ext, none, "free_play", whole(1.0))
    assert uncut.engine is None and uncut.sse_beat == pytest.approx(2000 * 9.0 ** 2)


def test_a_refit_whose_held_out_tests_cannot_be_simulated_says_why_and_is_no_cause():
    """A refit point at which the held-out engine fails (None, its reason in ``last_failure``): the row's held-out
    MSE is infinite (no score: it cannot be named), it keeps the engine's reason, and the log says the held-out
    tests cannot be simulated with that reason instead of a change of '+inf %'."""
    from types import SimpleNamespace

    from tuner.diagnosis.effect_sizes import REFERENCE
    from tuner.diagnosis.search.rows import held_out, log_row

    class Eng:
        def __init__(self, residuals, failure=""):
            self.residuals, self.last_failure = residuals, failure

        def residuals_batch(self, points):
            return [self.residuals(p) for p in points]

    said = []
    s = SimpleNamespace(ev=Eng(lambda p: None, "stage Newton did not converge at t = 1.2 s"),
                        eid=Eng(lambda p: np.full(20, 3.0 + 1e3 * p["free_play"])), lengths=[10, 10], noise=0.5,
                        size=REFERENCE, peak=2e4, stroke_range=0.05, stroke_limits=None,
                        data=SimpleNamespace(sig_val=[SimpleNamespace(name="a"), SimpleNamespace(name="b")]),
                        log=said.append)
    row = held_out(s, "free_play", {"free_play": 2e-3}, ["free_play"], 1.0 / 9.0, 10, 100.0)
    row["refitted"] = True
    assert math.isinf(row["validation_mse"]) and row["score"] == -math.inf
    assert row["validation_failure"] == "stage Newton did not converge at t = 1.2 s"
    log_row(s, row)
    assert "cannot be simulated" in said[0] and "stage Newton did not converge" in said[0] and "inf" not in said[0]
