"""The job (``tuner.job``): fit -> choose base -> diagnose -> export -> report, one problem, one
settings walk from the command line to the diagnosis."""
import dataclasses
import json

import pytest

from campaign.synthetic import write_model_dataset
from damper_fmu import defaults
from tuner import job, strict_json
from tuner.__main__ import main as cli_main
from tuner.identification.engine import fastest_engine
from tuner.diagnosis.settings import DiagnosisSettings
from tuner.identification.fit import FitSettings
from tuner.identification.problem import DataSettings


def test_the_diagnosis_gets_the_fits_problem_definition_field_by_field():
    """Every field of the problem definition given to the fit reaches the diagnosis (its
    parametrization excepted: the local solver needs monotone tables)."""
    fs = FitSettings(data=DataSettings(fit_rate_hz=150.0, warmup_s=0.3, diff_band_hz=33.0, force_limit_n=12345.0,
                                       damping_abscissae_m_s=tuple(0.01 * (i + 1) for i in range(14)),
                                       elastic_abscissae_m=tuple(0.001 * (i + 1) for i in range(10)),
                                       spring_reference_n_per_m=2.0e7, parametrization="paper"),
                     engine="native", seed=7, workers=0)
    ds = job.diagnosis_settings(fs)
    a, b = dataclasses.asdict(fs.data), dataclasses.asdict(ds.data)
    assert a.pop("parametrization") == "paper" and b.pop("parametrization") == "improved"
    assert a == b
    assert (ds.engine, ds.seed, ds.workers) == ("native", 7, 0)


def test_fit_settings_are_read_back_from_their_flat_record():
    """A run's settings record (metrics.json "settings", a fleet row) is one flat dict: read back, it gives
    the same settings, the problem definition included; a key that is no setting is refused by name."""
    fs = FitSettings(models=("lumped",), population=4, seed=3,
                     data=DataSettings(fit_rate_hz=150.0, warmup_s=0.3, force_limit_n=2e4,
                                       damping_abscissae_m_s=tuple(0.01 * (i + 1) for i in range(14))))
    record = json.loads(json.dumps(fs.to_dict()))  # as written to a file and read again
    assert record["fit_rate_hz"] == 150.0 and record["population"] == 4
    assert FitSettings.from_dict(record) == fs
    with pytest.raises(ValueError, match="'fit_rate'"):
        FitSettings.from_dict({**record, "fit_rate": 100.0})


def test_the_diagnosis_refuses_the_paper_parametrization():
    with pytest.raises(ValueError, match="parametrization must be 'improved'"):
        DiagnosisSettings(data=DataSettings(parametrization="paper"))


def test_the_job_prepares_once_writes_each_stage_and_reports_last(tmp_path, monkeypatch, small_lumped, prepared_names):
    """One run of the job: each test prepared once for fit and diagnosis, the diagnosis on the fit's
    force limit, full-rate check in metrics.json, tuned FMUs, and a report holding the diagnosis."""
    ident, valid = small_lumped
    real_settings = job.diagnosis_settings  # the real mapping, with a small candidate set to keep this quick
    monkeypatch.setattr(job, "diagnosis_settings", lambda s: dataclasses.replace(
        real_settings(s), candidates=("friction",), polish_jacobians=1, final_jacobians=1))
    settings = FitSettings(models=("lumped", "maxwell"), population=4, iterations=1, workers=0,
                           engine=fastest_engine(), polish_jacobians=1, data=DataSettings(force_limit_n=31000.0))
    out = tmp_path / "out"
    out.mkdir()
    res = job.run(ident, valid, out, settings, log=lambda m: None)
    fit_rate = settings.data.fit_rate_hz  # each test prepared once for the fit and the diagnosis; the full-rate
    assert sorted(n for n, rate in prepared_names if rate == fit_rate) == sorted(t.name for t in ident + valid)
    full_rate = [(n, rate) for n, rate in prepared_names if rate != fit_rate]  # check's own, at its rate, once each
    assert full_rate and len(set(full_rate)) == len(full_rate) and all(rate > fit_rate for _, rate in full_rate)
    metrics = json.loads((out / "metrics.json").read_text())
    diagnosis = json.loads((out / "diagnosis.json").read_text())
    assert set(metrics["full_rate"]) == {"lumped", "maxwell"}
    assert metrics["settings"]["force_limit_n_used"] == diagnosis["settings"]["problem"]["force_limit_n_used"] == 31000.0
    assert json.loads((out / "parameters.json").read_text()) == json.loads(json.dumps(res.fit.params))
    assert {p.name for p in res.fmus} >= {"DamperLumped_tuned.fmu", "DamperMaxwell_tuned.fmu"}
    assert json.loads(strict_json.dumps(res.diagnosis.to_dict())) == diagnosis  # the job wrote its record, figures
    assert diagnosis["figures"] and all((out / f).is_file() for f in diagnosis["figures"])
    assert "id='diagnosis'" in res.report.read_text(encoding="utf-8")
    sheet = json.loads((out / "datasheet" / "datasheet.json").read_text())  # every tuned FMU's datasheet
    assert set(sheet["fmus"]) == {p.name.removesuffix(".fmu") for p in res.fmus if p.name.endswith("_tuned.fmu")}
    assert "id='datasheet'" in res.report.read_text(encoding="utf-8")
    assert res.report.stat().st_mtime >= (out / "diagnosis.json").stat().st_mtime
    budget = json.loads((out / "time_budget.json").read_text())  # where the minutes went, up to the report
    stages = [st["stage"] for st in budget["stages"]]
    assert {"fit lumped", "fit maxwell", "diagnosis", "report"} <= set(stages) and stages[0] == "prepare"
    assert sum(st["seconds"] for st in budget["stages"]) == pytest.approx(budget["total_s"])
    assert "Where the time went" in res.report.read_text(encoding="utf-8")
    written = sorted(out.rglob("*.json"))
    assert {"metrics.json", "diagnosis.json", "parameters.json"} <= {p.name for p in written}
    for path in written:  # strict JSON, as jq or JavaScript read it: no Infinity, no NaN
        json.loads(path.read_text(), parse_constant=lambda c: pytest.fail(f"{path.name} holds {c}"))


def test_a_force_limit_on_the_command_line_reaches_the_diagnosis(tmp_path):
    """The command line's --force-limit walks through the job to the diagnosis (before, the
    diagnosis ignored it)."""
    path = write_model_dataset(tmp_path / "d", "lumped", defaults("lumped"), seed=4, durations=(3.0, 2.0),
                               roles=("identification", "validation"), noise_n=20.0)
    out = tmp_path / "o"
    code = cli_main(["diagnose", "--dataset", str(path), "--out", str(out), "--force-limit", "29000",
                     "--workers", "0", "--engine", fastest_engine(), "--quiet", "--seed", "1",
                     "--fit-rate", "100"])
    assert code == 0
    d = json.loads((out / "diagnosis.json").read_text(), parse_constant=lambda c: pytest.fail(f"diagnosis.json: {c}"))
    assert d["settings"]["problem"]["force_limit_n_used"] == pytest.approx(29000.0)
    assert d["settings"]["problem"]["data_settings"]["fit_rate_hz"] == 100.0
    # where the base model's error lives on the restoring-force plane: of the identification test, strict JSON
    where = d["evidence"]["residual_map"]
    assert where["tests"] == ["lumped_ide1"]
    assert set(where["regions"]) == {"near_reversal", "stroke_ends", "stroke_band", "above_knee"}


def test_a_failed_export_of_the_extended_fmu_is_recorded_as_the_diagnosis_failed_stage(tmp_path, monkeypatch):
    """The job writes the diagnosis's files (``write_diagnosis``); the extended model's export is the diagnosis's
    last stage: when it raises, diagnosis.json holds that failure (no verdict, the stages the diagnosis
    finished), an earlier diagnosis.json is kept as diagnosis.previous.json, and ``DiagnosisFailed`` names the
    file and chains the error (the command line then exits 1 and --resume exports again)."""
    from tuner.diagnosis.result import Diagnosis, DiagnosisFailed

    record = {"cause": "friction", "causes": ["friction"], "verdict": "causes: friction", "base_model": "lumped",
              "figures": [], "settings": {"elapsed_s": 1.0}}
    stages = {"finished": ["base identification", "diagnosis on the lumped base"], "partial": None,
              "base_choice": {"chosen": "lumped"}}
    diagnosis = Diagnosis(record, final_values=defaults("lumped"), stages=stages)

    def no_space(*args, **kwargs):
        raise OSError("no space left on device")

    monkeypatch.setattr(job, "build", no_space)
    out = tmp_path / "out"
    out.mkdir()
    (out / "diagnosis.json").write_text('{"cause": "none"}')
    with pytest.raises(DiagnosisFailed, match="export of the extended FMU") as failed:
        job.write_diagnosis(diagnosis, out, log=lambda m: None)
    assert failed.value.path == out / "diagnosis.json" and str(out / "diagnosis.json") in str(failed.value)
    assert isinstance(failed.value.__cause__, OSError)
    written = json.loads((out / "diagnosis.json").read_text(), parse_constant=lambda c: pytest.fail(c))
    assert written["failed_stage"] == "export of the extended FMU" and written["cause"] is None
    assert written["error"] == "OSError: no space left on device" and written["verdict"].startswith("no verdict")
    assert written["finished_stages"] == stages["finished"] and written["base_choice"] == {"chosen": "lumped"}
    assert json.loads((out / "diagnosis.previous.json").read_text()) == {"cause": "none"}
