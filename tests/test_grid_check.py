"""The diagnosis checks that the grid it simulated on is fine enough for the model it ended with
(``tuner.diagnosis.grid_check``) and runs again on a finer grid when it is not.

The check's estimate is tested against the integration error itself: the same model error-controlled on a grid 20
times finer than the finest compared (converged at the scale asserted, ``tests/test_sim_step.py``)."""
import math

import numpy as np
import pytest

from campaign.damper_class import write_class_dataset
from damper_fmu import defaults
from tuner.data.reading import load_dataset, read_manifest
from tuner.diagnosis import grid_check as grid_module
from tuner.diagnosis.bases import FittedBases
from tuner.diagnosis.diagnose import DiagnosisSettings, diagnose
from tuner.diagnosis.grid_check import grid_check
from tuner.identification.engine import fastest_engine, simulate_signals
from tuner.identification.problem import DataSettings, Problem


def _problem(tmp_path, hidden: dict, noise_n: float) -> tuple[Problem, dict]:
    d = write_class_dataset(tmp_path / "data", "lumped", 7, noise_n=noise_n, sample_rate=500.0, hidden=hidden,
                            durations=(4.0, 4.0, 4.0, 4.0))
    tests = load_dataset(d, check_plausible=False)
    problem = Problem.build([t for t in tests if t.role == "identification"],
                            [t for t in tests if t.role == "validation"], DataSettings())
    return problem, read_manifest(d)["generator"]["parameters"]


def _error_at_1_ms(problem: Problem, truth: dict) -> float:
    """rms [N] of the identification's force on its 1 ms grid against the converged force (error-controlled on a
    0.05 ms grid), over the counted samples of the identification tests."""
    reference = problem.on_grid(5e-5)
    d = [(simulate_signals("lumped", truth, s, engine=fastest_engine(), tolerance=0.0)
          - simulate_signals("lumped", truth, r, engine=fastest_engine(), max_internal_step=5e-5, tolerance=1e-6))[s.mask]
         for s, r in zip(problem.sig_id, reference.sig_id)]
    return float(np.sqrt(np.mean(np.concatenate(d) ** 2)))


def test_a_gap_in_impact_like_blocks_is_too_coarse_at_1_ms_and_the_check_measures_its_error(tmp_path):
    """A 0.3 mm free play closing on 1e9 N/m blocks damped at 2e4 N s/m, 20 N noise: the force moves by more than
    half the noise between 1 ms and 0.25 ms, and that change is the 1 ms grid's error within the factor a method
    of order 0.5-1 gives (|e(h) - e(h/4)| is 0.5-0.75 |e(h)| when the errors point alike)."""
    problem, truth = _problem(tmp_path, {"k_B": 1e9, "c_B": 2e4, "free_play": 0.3e-3}, 20.0)
    check = grid_check("lumped", truth, problem, fastest_engine())
    error = _error_at_1_ms(problem, truth)
    assert check.too_coarse and check.finer_step_s == pytest.approx(0.25e-3)
    assert 0.4 * error < check.change_n < 1.1 * error, (check.change_n, error)


def test_the_same_blocks_without_the_gap_are_fine_at_1_ms(tmp_path):
    problem, truth = _problem(tmp_path, {"k_B": 1e9, "c_B": 2e4}, 20.0)
    check = grid_check("lumped", truth, problem, fastest_engine())
    assert not check.too_coarse, check.to_dict()  # 5 N on 16 N of noise


def test_a_problem_on_another_grid_keeps_its_tests_and_oversamples_to_the_step(tmp_path):
    problem, _ = _problem(tmp_path, {}, 20.0)
    finer = problem.on_grid(0.25e-3)
    assert {s.oversample for s in problem.sig_id} == {5} and {s.oversample for s in finer.sig_id} == {20}
    assert len(problem.sig_id) == 2 and len(finer.sig_val) == len(problem.sig_val) == 2
    assert finer.settings.sim_step_s == 0.25e-3 and finer.noise_n == problem.noise_n
    assert all(np.array_equal(a.force, b.force) and np.array_equal(a.mask, b.mask)
               for a, b in zip(problem.sig_id, finer.sig_id))


def _small_diagnosis(tests, checkpoints, log):
    return diagnose([t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"],
                    DiagnosisSettings(engine=fastest_engine(), candidates=("preload",), polish_jacobians=2,
                                      final_jacobians=1, guess_start=False, forms=()),
                    from_fit=FittedBases("lumped", defaults("lumped")), checkpoints=checkpoints, log=log)


def test_a_final_model_the_grid_cannot_resolve_is_diagnosed_again_on_a_finer_grid(tmp_path, monkeypatch):
    """The wiring, with the share allowed set to 0 (every model 'too coarse'): the diagnosis runs again on the 0.25 ms
    grid, checkpointed apart, with the 1 ms grid's final model as a start, says so in the verdict and the record, and
    is resumed from its checkpoints; set to infinity, nothing runs again."""
    from campaign.synthetic import model_tests
    from tuner.data.reading import RigTest

    tests = [RigTest(name=c["name"], role=c["role"], scenario=c["scenario"], time=c["frame"]["time"].to_numpy(),
                     stroke=c["frame"]["stroke"].to_numpy(), force=c["frame"]["force"].to_numpy(), sample_rate=1000.0)
             for c in model_tests("lumped", {**defaults("lumped"), "preload_force": 300.0}, seed=4,
                                  durations=(4.0, 4.0, 3.0), roles=("identification", "identification", "validation"),
                                  noise_n=20.0)]
    monkeypatch.setattr(grid_module, "GRID_ERROR_SHARE", math.inf)
    res = _small_diagnosis(tests, tmp_path / "plain", lambda m: None)
    assert res["grid"]["refined"] is False and not (tmp_path / "plain" / "grid_250us").exists()
    monkeypatch.setattr(grid_module, "GRID_ERROR_SHARE", 0.0)
    lines = []
    res = _small_diagnosis(tests, tmp_path / "fine", lines.append)
    grid = res["grid"]
    assert grid["refined"] is True and grid["check"]["finer_step_s"] == pytest.approx(0.25e-3)
    assert grid["first_grid"]["causes"] is not None and grid["after"]["step_s"] == pytest.approx(0.25e-3)
    assert "ran again on a 0.25 ms grid" in res["verdict"]
    # the finer grid's search also starts the model of its causes from the one the 1 ms grid found
    assert any("refitted from the model the coarser grid found" in m for m in lines), lines
    assert (tmp_path / "fine" / "grid_250us" / "diagnosis_lumped.json").exists()
    lines.clear()
    again = _small_diagnosis(tests, tmp_path / "fine", lines.append)
    assert sum("was finished before" in m for m in lines) == 2, lines
    assert again["causes"] == res["causes"] and again["grid"]["refined"] is True


def test_a_series_ladder_that_kept_nothing_on_the_coarser_grid_is_not_run_again_on_the_finer_one():
    """The ladder (a gap profiled with the mount held stiffer) looks for another basin of the fit, not for an
    integration error: when it kept nothing on the coarser grid, the finer grid's diagnosis does not run it again
    (it took 38 of the 83 s of the worn-damper case's rerun to end no better). A ladder whose refit was kept, or a
    record written before the flag, runs again."""
    from types import SimpleNamespace

    from tuner.diagnosis.bases import CoarserGrid
    from tuner.diagnosis.search.nonsmooth import series_ladder

    run = {"after_params": {"free_play": 4e-4},
           "ranking": [{"effect": "free_play", "series_element_released": False},
                       {"effect": "friction"},
                       {"effect": "valve_lag", "series_element_released": True}]}
    coarser = CoarserGrid.of(run)
    assert coarser.idle_ladders == ("free_play",) and coarser.found == {"free_play": 4e-4}
    lines = []
    # a state with no engine: running the ladder would fail on the first simulation
    s = SimpleNamespace(kind="lumped", coarser=coarser, log=lines.append, above_floor=lambda rmse: True)
    row = {"effect": "free_play", "identification_rmse_n": 176.0, "score": 3.3}
    out = series_ladder(s, "free_play", None, row)
    assert out == {**row, "series_element_released": False}
    assert "not profiled again" in lines[0], lines
    with pytest.raises(AttributeError):  # not idle: the ladder runs (and needs the state this stand-in lacks)
        series_ladder(SimpleNamespace(**{**vars(s), "coarser": CoarserGrid({}, ())}), "free_play", None, row)
