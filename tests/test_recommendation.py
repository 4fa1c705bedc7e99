"""The one recommendation (issue 38, item 5): which model and FMU to use, decided in one place
(``tuner.results.recommendation``) and shown alike by the report's summary box, the printed end summary and
summary.json. Each rule on a small output folder written here (metrics from error_metrics on synthetic
forces, the quality gate by tuner.identification.fit.quality_gate, a diagnosis.json as the diagnosis writes
it); no fit is run."""
import html
import json
import math
import re

import numpy as np
import pytest

from damper_fmu.fmu import SLAVES
from damper_fmu.parameters import MODEL_PARAMETERS, defaults
from tuner import strict_json
from tuner.cli.summary import end_summary
from tuner.data.reading import load_files
from tuner.formatting import eng
from tuner.identification.fit import quality_gate
from tuner.metrics import error_metrics
from tuner.results.diagnosis_report import make_diagnosis_report
from tuner.results.recommendation import railway_damper, recommend
from tuner.results.report import make_report

RATE = 100.0      # [Hz]
N = 400           # samples per test
PEAK = 10_000.0   # [N] peak measured force
ROLES = {"id1": "identification", "val1": "validation", "val2": "validation"}
SCENARIOS = {"id1": "43 km/h switch", "val1": "86 km/h, R 500 m", "val2": "250 km/h straight"}
RAILWAY_WORDS = ("curving", "stability", "vehicle-dynamics", "hunting", "railway")


def _signals(name: str):
    t = np.arange(N) / RATE
    j = list(ROLES).index(name)
    x = 2e-3 * np.sin(2 * np.pi * 1.3 * t + j)
    return t, x, PEAK * np.sin(2 * np.pi * 1.3 * t + j + 0.3)


def _simulated(force, t, ame_pct: float, gain: float = 1.0):
    """A model's force whose error against ``force`` has an AME of ``ame_pct`` % of PEAK (a 7 Hz sine: AME =
    2/pi x its amplitude) on top of a gain error ``gain``."""
    err = (gain - 1.0) * force
    amp = max(ame_pct / 100 * PEAK - np.mean(np.abs(err)), 0.0) * np.pi / 2
    return gain * force + amp * np.sin(2 * np.pi * 7.0 * t)


def write_run(out, ame_pct: dict, *, gains=None, scenarios=True, damper_class="yaw", diagnosis=None):
    """A fit output folder: ``ame_pct`` {model: held-out AME [% of peak]} (the identification test at half of
    it), ``gains`` {model: force gain}, simulations.npz, the quality gate, empty FMU files where the job writes
    them; ``diagnosis``: a diagnosis.json document (``diagnosis_json``)."""
    out.mkdir(parents=True)
    gains = gains or {}
    params = {m: {"values": defaults(m), "units": {p.name: p.unit for p in MODEL_PARAMETERS[m]},
                  "bounds": {p.name: [p.low, p.high] for p in MODEL_PARAMETERS[m] if p.tunable},
                  "parametrization": "improved"} for m in ame_pct}
    tests, arrays = {}, {}
    for name, role in ROLES.items():
        t, x, f = _signals(name)
        arrays.update({f"{name}__time": t, f"{name}__stroke": x, f"{name}__force": f})
        models = {}
        for m, pct in ame_pct.items():
            sim = _simulated(f, t, pct / (1 if role == "validation" else 2), gains.get(m, 1.0))
            arrays[f"{name}__{m}"] = sim
            models[m] = error_metrics(f, sim).to_dict()
        tests[name] = {"role": role, "scenario": SCENARIOS[name] if scenarios else "", "models": models,
                       "damper_class": damper_class}
    table3 = {}
    if "lumped" in ame_pct and "maxwell" in ame_pct:
        for name in (n for n, r in ROLES.items() if r == "validation"):
            mx, lp = tests[name]["models"]["maxwell"], tests[name]["models"]["lumped"]
            table3[name] = {"mse_maxwell": mx["mse"], "mse_lumped": lp["mse"], "ame_maxwell": mx["ame"],
                            "ame_lumped": lp["ame"], "mse_variation_pct": 100 * (lp["mse"] / mx["mse"] - 1),
                            "ame_variation_pct": 100 * (lp["ame"] / mx["ame"] - 1)}
    metrics = {"settings": {"warmup_s": 0.0, "fit_rate_hz": RATE}, "tests": tests, "table3": table3,
               "quality": quality_gate(tests, list(ame_pct))}
    (out / "parameters.json").write_text(strict_json.dumps(params))
    (out / "metrics.json").write_text(strict_json.dumps(metrics))
    np.savez_compressed(out / "simulations.npz", **arrays)
    (out / "fmu").mkdir()
    for m in ame_pct:
        (out / "fmu" / f"{SLAVES[m]}_tuned.fmu").write_bytes(b"")
    if diagnosis is not None:
        (out / "diagnosis.json").write_text(strict_json.dumps(diagnosis(metrics)))
        if diagnosis(metrics).get("causes") and not diagnosis(metrics).get("failed_stage"):
            d = diagnosis(metrics)
            (out / "fmu" / f"{SLAVES[d['base_model']]}_{'_'.join(d['causes'])}_tuned.fmu").write_bytes(b"")
    return metrics


def diagnosis_json(base: str, causes=(), after_pct: float | None = None, unexplained=None):
    """A diagnosis.json maker: on ``base`` (its fit's figures as 'before'), ``causes`` named with the final
    model's held-out AME ``after_pct`` [% of peak] (or {test: AME}), ``unexplained``: (ratio, rmse [N],
    fit_converged)."""
    def make(metrics):
        validation = {}
        for name, t in metrics["tests"].items():
            if t["role"] != "validation":
                continue
            before = t["models"][base]
            _, _, f = _signals(name)
            tt = np.arange(N) / RATE
            pct = after_pct.get(name) if isinstance(after_pct, dict) else after_pct
            after = error_metrics(f, _simulated(f, tt, pct)).to_dict() if causes else before
            validation[name] = {"mse_before": before["mse"], "ame_before": before["ame"], "mse_after": after["mse"],
                                "ame_after": after["ame"], "mse_change_pct": 100 * (after["mse"] / before["mse"] - 1)}
        left = None
        if unexplained:
            ratio, rmse, converged = unexplained
            left = {"identification_rmse_n": rmse, "ratio": ratio, "floor_n": rmse / ratio, "noise_std_n": 10.0,
                    "stroke_noise_force_n": 5.0, "fit_converged": converged, "dominant_band": None,
                    "best_signature": None}
        cause = causes[0] if causes else ("unexplained" if left else "none")
        return {"cause": cause, "causes": list(causes), "verdict": f"cause: {cause} (a verdict)", "form": None,
                "unexplained": left, "base_model": base,
                "base_choice": {"chosen": base, "by": "held-out MSE of the fitted models (Table 3 definition)"},
                "ranking": [{"effect": "none", "parameters": {}, "units": {}, "validation_mse_change_pct": 0.0,
                             "score": 0.0}],
                "effect_parameters": {}, "validation": validation, "note": "",
                "settings": {"penalty_per_parameter": 0.02, "accept_score": 0.05, "unexplained_ratio": 2.0},
                "noise_std_n": 10.0}
    return make


def failed_diagnosis(metrics):
    return {"failed_stage": "forms beyond the catalogue on the lumped base", "error": "RuntimeError: boom",
            "traceback": ["..."], "finished_stages": ["base identification"], "cause": None, "causes": [],
            "verdict": "no verdict: the diagnosis failed", "base_model": "lumped", "base_choice": None,
            "ranking": [], "selection": [], "forms_tried": None, "settings": {}}


def shown(out, capsys):
    """(the report's box, summary.json's recommendation, the printed recommendation lines) of ``out``."""
    text = make_report(out, figures=False).read_text(encoding="utf-8")
    box = re.search(r"<div class='verdict' id='recommendation'.*?</div>", text, re.S).group(0)
    end_summary(out, 1.0)
    printed = capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text(),
                         parse_constant=lambda c: pytest.fail(f"summary.json holds {c}"))["recommendation"]
    lines = printed[printed.index("  recommendation: "):printed.index("  summary for scripts")]
    return text, box, summary, lines


def _attr(box, name):
    return html.unescape(re.search(rf"data-{name}='([^']*)'", box).group(1))


def agree(out, capsys, model, fmu, status="recommended"):
    """The box, summary.json and the printed summary name the same model and FMU (None: none); returns them."""
    text, box, summary, lines = shown(out, capsys)
    assert (summary["status"], summary["model"], summary["fmu_in_folder"]) == (status, model, fmu)
    assert (_attr(box, "status"), _attr(box, "model") or None, _attr(box, "fmu") or None) == (status, model, fmu)
    headline = summary["headline"]
    first = html.unescape(re.sub(r"<[^>]+>", "", re.search(r"<p>(.*?)</p>", box, re.S).group(1)))
    assert first == "Recommendation: " + headline[0].upper() + headline[1:]
    assert lines.startswith(f"  recommendation: {headline}\n")
    for part in (summary["reason"], summary["action"]):
        assert part in lines and html.escape(part) in box
    if fmu:
        assert summary["fmu"] == str(out / fmu) and summary["fmu_exists"]
    return text, box, summary, lines


def test_the_diagnosis_base_that_passes_the_gate_is_recommended_over_a_passing_lumped_model(tmp_path, capsys):
    """The issue's case: the lumped model passes the gate (3.1 %) but the diagnosis kept the two-chamber form
    (0.13 %) and named nothing: its plain tuned FMU is the one to use."""
    out = tmp_path / "run"
    metrics = write_run(out, {"lumped": 3.1, "maxwell": 12.0, "twochamber": 0.13}, diagnosis=diagnosis_json("twochamber"))
    _, _, summary, _ = agree(out, capsys, "twochamber", "fmu/DamperTwoChamber_tuned.fmu")
    assert "the diagnosis's base form, no cause named" in summary["reason"]
    val = [t["models"]["twochamber"] for t in metrics["tests"].values() if t["role"] == "validation"]
    rmse = math.sqrt(sum(m["mse"] * m["n"] for m in val) / sum(m["n"] for m in val))
    q = metrics["quality"]["twochamber"]
    assert (f"held-out error {eng(rmse, 'N')} rms, worst held-out AME {q['worst_ame_pct_of_peak']:.3g} % of peak force "
            f"on {q['worst_test']} (gate 10 %)") in summary["reason"]
    assert summary["action"] == ""
    assert {c["model"]: c["passes_gate"] for c in summary["facts"]["candidates"]} == {
        "twochamber": True, "lumped": True, "maxwell": False}


def test_named_causes_recommend_the_extended_fmu(tmp_path, capsys):
    out = tmp_path / "run"
    write_run(out, {"lumped": 6.0, "maxwell": 12.0, "twochamber": 1.5},
              diagnosis=diagnosis_json("twochamber", ("friction", "inertia"), after_pct=0.4))
    _, _, summary, _ = agree(out, capsys, "twochamber", "fmu/DamperTwoChamber_friction_inertia_tuned.fmu")
    assert summary["causes"] == ["friction", "inertia"]
    assert "with friction + inertia named" in summary["reason"]
    assert "worst held-out AME 0.4 % of peak force" in summary["reason"]  # the final model's, not the base's


def test_a_diagnosis_model_that_fails_the_gate_gives_way_to_one_that_passes(tmp_path, capsys):
    """The diagnosis's final model validates best pooled over the held-out tests but fails the gate on one
    of them; the lumped model passes: it is the one to use, and the text says why the diagnosis's is not."""
    out = tmp_path / "run"
    write_run(out, {"lumped": 8.0, "maxwell": 12.0, "twochamber": 11.0},
              diagnosis=diagnosis_json("twochamber", ("friction",), after_pct={"val1": 10.5, "val2": 1.0}))
    _, _, summary, _ = agree(out, capsys, "lumped", "fmu/DamperLumped_tuned.fmu")
    final, lumped = summary["facts"]["candidates"][:2]
    assert final["from_diagnosis"] and final["error_rms_n"] < lumped["error_rms_n"] and not final["passes_gate"]
    assert ("the diagnosis's two-chamber model with friction does NOT pass the quality gate (worst held-out AME "
            "10.5 % of peak force on val1)") in summary["reason"]


def test_a_time_delay_recommends_the_plain_fmu_and_says_to_fix_the_acquisition(tmp_path, capsys):
    """time_delay belongs to the acquisition: the exported co-simulation model should not contain it."""
    out = tmp_path / "run"
    write_run(out, {"lumped": 4.0, "maxwell": 12.0},
              diagnosis=diagnosis_json("lumped", ("friction", "time_delay"), after_pct=0.5))
    _, box, summary, _ = agree(out, capsys, "lumped", "fmu/DamperLumped_tuned.fmu")
    assert summary["causes"] == []
    assert "fix the acquisition" in summary["action"] and "should not contain" in summary["action"]
    assert "fmu/DamperLumped_friction_time_delay_tuned.fmu" in summary["action"]  # friction is there, with the delay
    assert summary["facts"]["diagnosis"]["acquisition_causes"] == ["time_delay"]


def test_a_passing_model_with_a_model_form_error_says_both_and_what_to_do(tmp_path, capsys):
    """The issue's real-data case: the gate passes (9.4 % of peak) while the diagnosis finds a settled
    model-form error (26.3 x the floor): recommended, with the use it is fit for."""
    out = tmp_path / "run"
    write_run(out, {"lumped": 9.4, "maxwell": 14.0},
              diagnosis=diagnosis_json("lumped", unexplained=(26.3, 17.5, True)))
    _, _, summary, _ = agree(out, capsys, "lumped", "fmu/DamperLumped_tuned.fmu")
    action = summary["action"]
    assert "model-form error" in action and "26.3 x the residual floor" in action and "17.5 N rms" in action
    assert "comparative studies, not for stability margins" in action and "figures/diag_residual_" in action
    assert summary["facts"]["form_error"] is True


def test_an_unfinished_refit_is_not_called_a_model_form_error(tmp_path, capsys):
    out = tmp_path / "run"
    write_run(out, {"lumped": 9.4, "maxwell": 14.0},
              diagnosis=diagnosis_json("lumped", unexplained=(26.3, 17.5, False)))
    _, _, summary, _ = agree(out, capsys, "lumped", "fmu/DamperLumped_tuned.fmu")
    assert "NOT shown to be a model-form error" in summary["action"] and "larger budget" in summary["action"]
    assert summary["facts"]["form_error"] is False


def test_without_a_diagnosis_the_best_held_out_model_that_passes(tmp_path, capsys):
    """No diagnosis: the lowest held-out error among the models that pass the gate (the maxwell_table model
    fails it); the linear Maxwell model passes but validates worse, and that is said."""
    out = tmp_path / "run"
    write_run(out, {"lumped": 2.0, "maxwell": 8.0, "maxwell_table": 11.0})
    _, _, summary, _ = agree(out, capsys, "lumped", "fmu/DamperLumped_tuned.fmu")
    assert "no diagnosis ran" in summary["reason"]
    assert "The linear Maxwell model passes the gate too but validates worse" in summary["reason"]


def test_maxwell_is_never_recommended_over_a_better_nonlinear_model_and_said_when_as_good(tmp_path, capsys):
    out = tmp_path / "close"
    write_run(out, {"lumped": 3.0, "maxwell": 3.05})  # Maxwell within the acceptance score: as good
    _, _, summary, _ = agree(out, capsys, "lumped", "fmu/DamperLumped_tuned.fmu")
    assert "The linear Maxwell model passes the gate too and validates as well" in summary["reason"]
    assert summary["facts"]["maxwell_as_good"] is True
    out = tmp_path / "maxwell_better"
    write_run(out, {"lumped": 3.0, "maxwell": 2.0})
    _, _, summary, _ = agree(out, capsys, "maxwell", "fmu/DamperMaxwell_tuned.fmu")
    assert "The lumped model passes the gate too but does not validate better" in summary["reason"]
    assert "the linear Maxwell element is as good for this damper" in summary["reason"]


def test_when_nothing_passes_no_model_is_recommended_and_the_closest_is_named(tmp_path, capsys):
    out = tmp_path / "run"
    write_run(out, {"lumped": 12.0, "maxwell": 15.0}, diagnosis=diagnosis_json("lumped", unexplained=(40.0, 400.0, True)))
    text, box, summary, lines = agree(out, capsys, None, None, status="nothing_passes")
    assert "No model describes this data" in summary["reason"]
    assert summary["closest"]["model"] == "lumped" and summary["closest"]["fmu"] == "fmu/DamperLumped_tuned.fmu"
    assert "closest is the lumped model, fmu/DamperLumped_tuned.fmu" in lines
    assert "comparative studies" not in summary["action"]  # nothing to use, not even for comparisons
    assert "model-form error" in summary["action"]


def test_a_failed_diagnosis_gives_no_recommendation_and_says_how_to_continue(tmp_path, capsys):
    out = tmp_path / "run"
    write_run(out, {"lumped": 2.0, "maxwell": 8.0}, diagnosis=failed_diagnosis)
    text, box, summary, lines = agree(out, capsys, None, None, status="diagnosis_failed")
    assert "--resume" in summary["action"] and "forms beyond the catalogue on the lumped base" in summary["reason"]
    assert "Diagnosis: FAILED, no verdict" in text
    assert summary["facts"]["diagnosis"]["failed_stage"] == "forms beyond the catalogue on the lumped base"


def test_a_diagnosis_on_its_own_recommends_its_model_and_says_the_gate_was_not_checked(tmp_path):
    """``python -m tuner diagnose`` without --from: no metrics.json, so no peaks and no gate."""
    src = tmp_path / "fit"
    metrics = write_run(src, {"lumped": 2.0}, diagnosis=diagnosis_json("lumped", ("friction",), after_pct=1.0))
    out = tmp_path / "diag"
    out.mkdir()
    (out / "diagnosis.json").write_text((src / "diagnosis.json").read_text())
    rec = recommend(out)
    assert (rec.status, rec.model, rec.fmu) == ("recommended", "lumped", "fmu/DamperLumped_friction_tuned.fmu")
    assert "quality gate was not checked" in rec.action and "quality gate not evaluated" in rec.reason
    assert "id='recommendation'" in make_diagnosis_report(out).read_text(encoding="utf-8")
    assert metrics["quality"]["lumped"]["describes_data"]


def test_damper_class_any_without_scenarios_has_no_railway_wording_and_no_empty_brackets(tmp_path, capsys):
    """The same run read as a railway yaw damper speaks of curving and stability margins; read with
    --damper-class any and without scenario descriptions, neither, and no '()' after a test name."""
    kwargs = dict(ame_pct={"lumped": 9.0, "maxwell": 9.5}, gains={"maxwell": 0.8},
                  diagnosis=diagnosis_json("lumped", unexplained=(26.3, 17.5, True)))
    write_run(tmp_path / "yaw", **kwargs)
    railway = make_report(tmp_path / "yaw", figures=False).read_text(encoding="utf-8")
    assert "over-estimates the curving performance" in railway and "stability margins" in railway
    write_run(tmp_path / "any", scenarios=False, damper_class="any", **kwargs)
    text = make_report(tmp_path / "any", figures=False).read_text(encoding="utf-8")
    visible = html.unescape(re.sub(r"<[^>]+>", "", text)).lower()
    assert not [w for w in RAILWAY_WORDS if w in visible]
    assert "()" not in visible
    assert "The Maxwell element gives lower forces than the damper." in text
    assert "absolute force predictions" in text
    assert railway_damper(strict_json.loads((tmp_path / "any" / "metrics.json").read_text())) is False


def test_no_vehicle_or_diagnosis_section_nor_its_contents_entry_when_the_stage_did_not_run(tmp_path):
    out = tmp_path / "run"
    write_run(out, {"lumped": 2.0, "maxwell": 8.0})
    text = make_report(out, figures=False).read_text(encoding="utf-8")
    assert "id='vehicle'" not in text and "href='#vehicle'" not in text
    assert "id='diagnosis'" not in text and "href='#diagnosis'" not in text


def test_the_damper_class_is_recorded_as_read_and_unknown_counts_as_railway(tmp_path):
    t = np.arange(0, 3, 0.002)
    x = 0.01 * np.sin(2 * np.pi * t)
    path = tmp_path / "press.csv"
    path.write_text("time,stroke,force\n" + "".join(f"{a},{b},{c}\n" for a, b, c in zip(t, x, 2e5 * np.gradient(x, t))))
    assert load_files([path], "identification", damper_class="any")[0].metadata["read"]["damper_class"] == "any"
    assert load_files([path], "identification")[0].metadata["read"]["damper_class"] == "yaw"
    assert railway_damper({"tests": {"a": {"damper_class": "primary"}, "b": {}}}) is True
    assert railway_damper({"tests": {"a": {"damper_class": "yaw"}, "b": {"damper_class": "any"}}}) is False
    assert railway_damper(None) is True
    assert math.isfinite(recommend(tmp_path).facts["gate_pct"])  # a folder with nothing: no_results
    assert recommend(tmp_path).status == "no_results"


def test_a_failed_diagnosis_still_ends_with_the_summary_and_keeps_its_checkpoints(tmp_path, capsys):
    """The command's end after a failed diagnosis (``tuner.cli.fit``): summary.json and the printed summary
    say there is no recommendation, the checkpoints stay for --resume, and the failure is raised on (exit 1)."""
    from argparse import Namespace

    from tuner.cli.fit import _end
    from tuner.diagnosis.diagnose import DiagnosisFailed

    out = tmp_path / "run"
    write_run(out, {"lumped": 2.0, "maxwell": 8.0}, diagnosis=failed_diagnosis)
    (out / "checkpoints").mkdir()
    (out / "checkpoints" / "diagnosis_lumped.json").write_text("{}")
    failed = DiagnosisFailed("forms beyond the catalogue on the lumped base", failed_diagnosis(None), RuntimeError("boom"))
    failed.path = out / "diagnosis.json"  # as the job's write_diagnosis_failure leaves it
    with pytest.raises(DiagnosisFailed):
        _end(out, Namespace(keep_checkpoints=False), 0.0, failed)
    assert (out / "checkpoints" / "diagnosis_lumped.json").exists()
    assert json.loads((out / "summary.json").read_text())["recommendation"]["status"] == "diagnosis_failed"
    assert "recommendation: none: the diagnosis failed" in capsys.readouterr().out


def test_vehicle_intervals_are_drawn_for_the_recommended_model_only_unless_all_are_asked(tmp_path):
    """``tuner.job.interval_models``: the recommended model (the diagnosis's base with its causes: the base's
    parameters are drawn), none when nothing passes the gate, every one with 'all'; a bad choice is an error
    naming the option."""
    from tuner.job import interval_models
    out = tmp_path / "run"
    write_run(out, {"lumped": 3.1, "maxwell": 12.0, "twochamber": 0.13}, diagnosis=diagnosis_json("twochamber"))
    lines = []
    assert interval_models(out, "recommended", lines.append) == ("twochamber",)
    assert interval_models(out, "all", lines.append) is None
    with pytest.raises(ValueError, match="--vehicle-intervals"):
        interval_models(out, "best", lines.append)
    named = tmp_path / "named"
    write_run(named, {"lumped": 6.0, "maxwell": 12.0, "twochamber": 1.5},
              diagnosis=diagnosis_json("twochamber", ("friction",), after_pct=0.4))
    assert interval_models(named, "recommended", lines.append) == ("twochamber",)
    assert "friction are not drawn" in lines[-1]
    failing = tmp_path / "failing"
    write_run(failing, {"lumped": 12.0, "maxwell": 15.0})
    assert interval_models(failing, "recommended", lines.append) == ()
    assert "no model is recommended" in lines[-1]


def test_the_end_summary_gives_every_fmus_critical_speed_with_or_without_its_interval(tmp_path, capsys):
    """Intervals drawn for the recommended FMU only: its line carries the interval, the other FMUs' critical
    speeds are still said (from vehicle/vehicle.json), marked as drawn without an interval."""
    out = tmp_path / "run"
    write_run(out, {"lumped": 3.1, "maxwell": 12.0, "twochamber": 0.13}, diagnosis=diagnosis_json("twochamber"))
    (out / "vehicle").mkdir()
    speeds = {"DamperLumped_tuned": 805.0, "DamperMaxwell_tuned": 647.0, "DamperTwoChamber_tuned": 801.0}
    (out / "vehicle" / "vehicle.json").write_text(strict_json.dumps(
        {"results": {k: {"critical_speed": {"critical_speed_kmh": v}} for k, v in speeds.items()}}))
    figure = {"nominal": 801 / 3.6, "low": 800 / 3.6, "high": 802 / 3.6, "mc_error": 0.1, "draws": 8,
              "method": "normal"}
    (out / "vehicle" / "intervals.json").write_text(strict_json.dumps({"results": {"DamperTwoChamber_tuned": {
        "model": "twochamber", "critical_speed": figure, "peak_curve_force": {**figure, "nominal": 9390.0},
        "critical_speed_text": "801 km/h (95 %: 800-802)", "peak_curve_force_text": "9.39 kN (95 %: 9.39-9.39)",
        "search_scatter_ms": None}}}))
    end_summary(out, 1.0)
    text = capsys.readouterr().out
    assert ("vehicle, hunting critical speed [km/h] (no interval drawn): DamperLumped_tuned 805, "
            "DamperMaxwell_tuned 647\n") in text
    assert "vehicle: critical speed 801 km/h (95 %: 800-802)" in text and "DamperTwoChamber_tuned 801" not in text
