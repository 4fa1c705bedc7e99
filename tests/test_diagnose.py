"""Diagnosis: extended design space, decision on held-out gain, outputs and error paths.

The issue's full acceptance (every catalogue effect named with a >= 30 % MSE drop) is NOT met:
on virtual-rig data the base lumped model absorbs friction, preload, free play, inertia and valve
lag into its tables (see benchmarks/confusion_matrix.py and the closing note). These tests pin
down what the diagnosis does do.
"""
import json

import numpy as np
import pytest

from campaign.generate import generate_dataset
from damper_fmu import defaults
from tuner.__main__ import main
from tuner.data import load_dataset
from tuner.diagnose import CANDIDATES, DiagnosisSettings, ExtendedParametrization, diagnose
from tuner.parametrization import Parametrization


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


def run_diagnosis(tmp_path, effects, seed):
    data = generate_dataset(tmp_path / "data", seed=seed, effects=effects, t_end=6.0, log=lambda m: None)
    tests = load_dataset(data)
    return diagnose([t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"],
                    tmp_path / "out", DiagnosisSettings(engine="inprocess", base_iterations=0), log=lambda m: None)


@pytest.mark.slow
def test_clean_data_gives_no_false_cause_and_a_complete_diagnosis_json(tmp_path):
    res = run_diagnosis(tmp_path, {}, seed=5)
    assert res["cause"] == "none"
    saved = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert saved["cause"] == "none"
    assert {r["effect"] for r in saved["ranking"]} == set(CANDIDATES)
    assert all("score" in r and "validation_mse_change_pct" in r for r in saved["ranking"])
    assert set(saved["validation"]) == {"val1_straight_250", "val2_curve_R6000_306", "val3_curve_R500_86"}
    for v in saved["validation"].values():
        assert v["mse_after"] == v["mse_before"]  # no cause: the model is unchanged
    assert saved["figures"] and all((tmp_path / "out" / f).exists() for f in saved["figures"])


@pytest.mark.slow
def test_a_hidden_time_delay_is_named_with_its_magnitude(tmp_path):
    delay = float(np.random.default_rng(8).uniform(3e-3, 1e-2))  # upper part of the 1-10 ms range
    res = run_diagnosis(tmp_path, {"time_delay": delay}, seed=6)
    assert res["cause"] == "time_delay"
    fitted = res["effect_parameters"]["time_delay"]["value"]
    assert fitted == pytest.approx(delay, rel=0.3)
    # pooled held-out gain (the decision criterion); measured -22 % here, short of the issue's -30 %
    ext = next(r for r in res["ranking"] if r["effect"] == "time_delay")
    assert ext["validation_mse_change_pct"] < -10.0
    assert (tmp_path / "out" / "fmu" / "DamperLumped_time_delay_tuned.fmu").exists()


def test_diagnose_command_needs_validation_tests_and_a_real_fit_folder(tmp_path, capsys):
    data = generate_dataset(tmp_path / "d", seed=1, scenarios=["id1_straight_250"], t_end=3.0, log=lambda m: None)
    assert main(["diagnose", "--identification", str(next(data.glob("*.csv"))), "--out", str(tmp_path / "o")]) == 2
    assert "validation" in capsys.readouterr().err
    assert main(["diagnose", "--from", str(tmp_path), "--out", str(tmp_path / "o2")]) == 2
    assert "parameters.json" in capsys.readouterr().err
