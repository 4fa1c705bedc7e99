"""The best point is the result (``tuner.identification.best_point``): a fit that stopped short is continued from a
lower point a later stage found, and the fit's files and tuned FMUs are those of the final point."""
from __future__ import annotations

import json
import math
import zipfile
from xml.etree import ElementTree

import numpy as np
import pytest

from damper_fmu import defaults
from tuner import job
from tuner.diagnosis.result import Diagnosis
from tuner.identification.best_point import continue_fit, lower_points
from tuner.identification.engine import Engine, fastest_engine
from tuner.identification.fit import FitSettings, fit, validation_run
from tuner.identification.problem import DataSettings


@pytest.fixture
def short_fit(tmp_path):
    """A lumped fit stopped short (one Firefly iteration of four fireflies, no local refinement) on 4 s + 3 s of a
    lumped damper unlike the preset (silent blocks twice as stiff with half the damping; 20 N noise), the truth's
    point and its identification RMSE [N]."""
    from campaign.synthetic import write_model_dataset
    from tuner.data.reading import load_dataset

    damper = defaults("lumped")
    damper.update({"k_B": 2.0 * damper["k_B"], "c_B": 0.5 * damper["c_B"]})
    tests = load_dataset(write_model_dataset(tmp_path / "d", "lumped", damper, seed=4, durations=(4.0, 3.0),
                                             roles=("identification", "validation"), noise_n=20.0))
    ident, valid = [t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"]
    settings = FitSettings(models=("lumped",), population=4, iterations=1, workers=0, engine=fastest_engine(),
                           polish_jacobians=0, data=DataSettings(force_limit_n=31000.0))
    result = fit(ident, valid, settings, log=lambda m: None)
    par = result.problem.parametrization("lumped")
    # the truth as the fit's design space holds it (its table abscissae are the data's)
    start = par.to_params(par.from_params({**result.params["lumped"]["values"],
                                           **{k: v for k, v in damper.items() if k in par.names}}))
    truth = {k: start[k] for k in par.names}
    with Engine("lumped", result.problem.sig_id, engine=settings.engine, workers=0) as eng:
        r = eng.residuals_batch([{**result.params["lumped"]["values"], **truth}])[0]
    return result, settings, truth, math.sqrt(float(r @ r) / r.size)


def _record(result, truth: dict, truth_rmse: float, converged: bool) -> dict:
    return {"lumped": {"fit_rmse_n": result.identification_rmse_n("lumped"), "refit_rmse_n": truth_rmse,
                       "standard_error_n": 1.0, "fit_converged": converged, "found_by": "a stage of this test",
                       "refit_values": truth}}


def test_a_lower_point_is_continued_and_becomes_the_fit(short_fit):
    result, settings, truth, truth_rmse = short_fit
    before = result.identification_rmse_n("lumped")
    assert truth_rmse < before - 1.0  # the fit stopped short: the truth fits better by far
    assert lower_points(_record(result, truth, truth_rmse, True), result.params) == []  # a converged fit stays
    (point,) = lower_points(_record(result, truth, truth_rmse, False), result.params)
    continue_fit(result, point, FitSettings(**{**settings.__dict__, "polish_jacobians": 3}), log=lambda m: None)
    after = result.identification_rmse_n("lumped")
    assert after <= truth_rmse * (1 + 1e-9)  # the refinement never ends above its start, the truth's point
    hist = result.histories["lumped"]["best_point"]
    assert hist["found_by"] == "a stage of this test" and hist["kept"] and hist["final_rmse_n"] == after
    values = result.params["lumped"]["values"]
    assert values != {} and result.params["lumped"]["intervals"] is not None
    # the validation figures are those of the final point, through the FMU
    for sig in result.problem.sig_val:
        direct = validation_run("lumped", values, sig)[1]
        assert np.isclose(result.metrics["tests"][sig.name]["models"]["lumped"]["mse"], direct["mse"])


def test_the_job_rewrites_the_fit_and_its_fmu_at_the_best_point(short_fit, tmp_path):
    result, settings, truth, truth_rmse = short_fit
    out = tmp_path / "out"
    result.write(out)
    job.export_fmus(result, out)
    old = json.loads((out / "parameters.json").read_text())["lumped"]["values"]
    diagnosis = Diagnosis({"base_refits": _record(result, truth, truth_rmse, False)})
    job._at_the_best_point(result, diagnosis, out, FitSettings(**{**settings.__dict__, "polish_jacobians": 2}),
                           lambda m: None)
    new = json.loads((out / "parameters.json").read_text())["lumped"]["values"]
    assert new != old and new == pytest.approx(result.params["lumped"]["values"])
    history = json.loads((out / "history_lumped.json").read_text())
    assert history["best_point"]["found_by"] == "a stage of this test"
    with zipfile.ZipFile(out / "fmu" / "DamperLumped_tuned.fmu") as z:  # the FMU's start values: the new point
        root = ElementTree.fromstring(z.read("modelDescription.xml"))
    starts = {v.get("name"): float(child.get("start")) for v in root.iter("ScalarVariable") for child in v
              if child.get("start") is not None and v.get("causality") == "parameter"}
    for name in ("k_B", "c_B", "M_P"):
        assert starts[name] == pytest.approx(new[name], rel=1e-9)
