"""Detection limits (tuner.diagnosis.detection) against closed forms of the linear model."""
import math

import numpy as np
import pytest

from tuner.diagnosis.detection import absorbed_signature, limit_from_signature


def test_a_signature_the_base_can_make_is_absorbed_and_never_detected():
    rng = np.random.default_rng(0)
    J_id, J_val = rng.normal(size=(400, 5)), rng.normal(size=(300, 5))
    w = rng.normal(size=5)
    u = absorbed_signature(J_id @ w, J_val @ w, J_id, J_val)  # the effect is a base parameter change
    assert np.max(np.abs(u)) < 1e-9 * np.max(np.abs(J_val @ w))
    assert limit_from_signature(u, J_id @ w, 100.0, 1.0, 0.05, 0.02)["by_score"] > 1e6


def test_an_orthogonal_signature_gives_the_closed_form_limit():
    """u orthogonal to the base: a hidden effect of the limit's size raises the refitted base's held-out
    MSE by exactly the factor exp(accept + penalty), i.e. it scores just the acceptance threshold."""
    n = 1000
    t = np.linspace(0.0, 1.0, n)
    J = np.column_stack([np.ones(n), t])
    j = np.sin(2 * math.pi * 7 * t) * 50.0  # N per unit; orthogonal-ish to the affine base
    u = absorbed_signature(j, j, J, J)
    mse_ref, accept, penalty = 400.0, 0.05, 0.02
    row = limit_from_signature(u, j, mse_ref, noise_n=1.0, accept=accept, penalty=penalty)
    m = row["by_score"]
    mse_none = mse_ref + m ** 2 * float(u @ u) / n
    assert -math.log(mse_ref / mse_none) - penalty == pytest.approx(accept, rel=1e-12)
    assert row["by_noise"] == pytest.approx(1.0 / math.sqrt(np.mean(j ** 2)))
    assert row["limit"] == max(row["by_score"], row["by_noise"])


def test_the_force_rule_sets_the_limit_when_the_noise_is_large():
    n = 500
    j = np.ones(n) * 2.0
    u = j.copy()
    row = limit_from_signature(u, j, mse_ref=1e-6, noise_n=10.0, accept=0.05, penalty=0.02)
    assert row["limit"] == row["by_noise"] == pytest.approx(5.0)


@pytest.mark.full
def test_the_held_out_score_crosses_the_threshold_where_the_limit_says(tmp_path):
    """On lumped-model data, a friction hidden at half the score limit of the clean data scores below
    the acceptance threshold, one at twice the limit above it (measured 2026-11-25: limit 5.13 N; 2.57 N
    scored +0.004, 10.3 N +0.264 against the linear model's -0.002 and +0.235)."""
    from campaign.synthetic import write_model_dataset
    from damper_fmu import defaults
    from tuner.data.reading import load_dataset
    from tuner.diagnosis.bases import FittedBases
    from tuner.diagnosis.diagnose import ACCEPT_SCORE, DiagnosisSettings, diagnose
    from tuner.identification.fit import FitSettings, fit

    def run(tag, friction):
        path = write_model_dataset(tmp_path / f"d_{tag}", "lumped", {**defaults("lumped"), "friction_force": friction},
                                   seed=4, durations=(6.0, 6.0, 4.0, 4.0), noise_n=20.0,
                                   roles=("identification", "identification", "validation", "validation"))
        tests = load_dataset(path)
        ident = [t for t in tests if t.role == "identification"]
        valid = [t for t in tests if t.role == "validation"]
        fitted = fit(ident, valid, FitSettings(models=("lumped",), iterations=0, workers=2, engine="native"),
                     log=lambda m: None)
        return diagnose(ident, valid, DiagnosisSettings(engine="native", workers=2, candidates=("friction",)),
                        from_fit=FittedBases("lumped", fitted.params["lumped"]["values"]), log=lambda m: None)

    limit = run("clean", 0.0)["detection_limits"]["friction"]["by_score"]
    score = {f: next(r for r in run(f"x{f}", f * limit)["ranking"] if r["effect"] == "friction")["score"]
             for f in (0.5, 2.0)}
    assert score[0.5] < ACCEPT_SCORE < score[2.0], (limit, score)


def test_absorption_is_the_share_of_the_signature_the_base_can_make_and_names_its_columns():
    """Closed forms: a signature made by base columns 1 and 3 only is absorbed whole, credited to those columns in
    proportion to their parts; one orthogonal to every column is not absorbed; a mix absorbs |in-span|^2 / |j|^2."""
    from tuner.diagnosis.detection import absorption

    n = 2000
    t = np.linspace(0.0, 1.0, n)
    J = np.column_stack([np.sin(2 * math.pi * k * t) for k in (1, 2, 3, 4)])  # orthogonal columns
    share, parts = absorption(3.0 * J[:, 1] + 1.0 * J[:, 3], J)
    assert share == pytest.approx(1.0, abs=1e-9)
    assert parts == pytest.approx([0.0, 0.9, 0.0, 0.1], abs=1e-9)  # 9 : 1 of the absorbed power
    off = np.sin(2 * math.pi * 9 * t)  # orthogonal to the span
    assert absorption(off, J)[0] == pytest.approx(0.0, abs=1e-9)
    mix = J[:, 0] + off  # half its power in the span
    assert absorption(mix, J)[0] == pytest.approx(0.5, rel=1e-6)


def test_parameter_groups_name_the_physical_elements():
    from damper_fmu.parameters import parameter_group, tunable_names

    lumped = {parameter_group("lumped", n) for n in tunable_names("lumped")}
    assert {"the damping table", "the elastic table", "the series elasticity (k_B, c_B)", "the masses"} <= lumped
    two = {parameter_group("twochamber", n) for n in tunable_names("twochamber")}
    assert "the series elasticity (k_M, c_M)" in two and "the chambers' oil stiffness" in two
    assert parameter_group("lumped", "k_M") == "k_M"  # another model's element is not the lumped one's
