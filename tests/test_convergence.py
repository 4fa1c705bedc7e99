"""Identification converges on random dampers of the model's class, not only near the preset.

The CI-sized version of ``benchmarks/convergence.py`` (README, "Convergence over the model's
class"), through the same per-damper routine: random dampers from the class priors of
``campaign.damper_class`` (the first seeds, not chosen), short rig-like tests (four of 6 s at
500 Hz), fitted blind with the default settings. The reference is the RMSE that the TRUE
parameters score through the same objective (the reachable floor: load-cell noise plus what the
stroke channel's noise does through the model), not a number from an earlier run.
"""
import pytest

from benchmarks.convergence import RATIO, run_one

QUICK = [6.0, 6.0, 6.0, 6.0]


@pytest.mark.slow
@pytest.mark.parametrize("model,seed", [("lumped", 0), ("lumped", 1), ("twochamber", 0)])
def test_a_random_damper_of_the_class_is_fitted_to_the_floor_and_said_converged(tmp_path, model, seed):
    row = run_one(model, seed, tmp_path, "fmu", QUICK)
    assert row["truth_on_the_tuner_abscissae"]  # the truth is a member of the fitted model's class
    assert row["rmse_n"] <= RATIO * row["truth_rmse_n"], row
    assert row["tuner_converged"], row["polish_stop"]
