"""Identification converges on random dampers of the model's class, not only near the preset.

The CI-sized version of ``benchmarks/convergence.py`` (docs/identification.md, "Convergence
over the model's class"), through the same per-damper routine: random dampers from the class priors of
``campaign.damper_class`` (the first seeds, not chosen), short rig-like tests (four of 6 s at
500 Hz), fitted blind with the default settings: the first seed of each form in CI, a second lumped one with
DAMPER_FULL_TESTS=1, thirty of each in the benchmark. The reference is the RMSE that the TRUE
parameters score through the same objective (the reachable floor: load-cell noise plus what the
stroke channel's noise does through the model), not a number from an earlier run.
"""
import pytest

from benchmarks.convergence import RATIO, run_one

QUICK = [6.0, 6.0, 6.0, 6.0]


@pytest.mark.slow
@pytest.mark.parametrize("model,seed", [("lumped", 0), pytest.param("lumped", 1, marks=pytest.mark.full),
                                        ("twochamber", 0)])
def test_a_random_damper_of_the_class_is_fitted_to_the_floor_and_said_converged(tmp_path, model, seed):
    row = run_one(model, seed, tmp_path, "fmu", QUICK)
    assert row["truth_on_the_tuner_abscissae"]  # the truth is a member of the fitted model's class
    assert row["rmse_n"] <= RATIO * row["truth_rmse_n"], row
    assert row["tuner_converged"], row["polish_stop"]


@pytest.mark.slow
def test_a_clearly_wrong_base_form_gets_no_restart(tmp_path):
    """Lumped-class data fitted with both base forms: the two-chamber form, fitted second, is only
    refined again from the data-driven start when its first refinement is within RACE_RATIO of the
    lumped form's RMSE; the lumped form, fitted first, has no rival and gets every start."""
    from campaign.damper_class import write_class_dataset
    from tuner.data.reading import load_dataset
    from tuner.identification.engine import fastest_engine
    from tuner.identification.fit import RACE_RATIO, FitSettings, fit

    tests = load_dataset(write_class_dataset(tmp_path / "data", "lumped", 0, durations=QUICK))
    # random first population: the Firefly best is not the data-driven start, so both starts exist
    settings = FitSettings(models=("lumped", "twochamber"), population=6, iterations=3, polish_jacobians=6,
                           engine=fastest_engine(), init="random")
    hist = fit([t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"],
               settings, log=lambda m: None).histories
    runs = {m: h["local_refinements"] for m, h in hist.items()}
    assert [r["start"] for r in runs["lumped"]][:2] == ["Firefly best", "data-driven start"]
    assert len(runs["lumped"]) == 6  # and the k_B and c_B ladder (RESTART_LADDER)
    assert hist["lumped"]["race"] is None
    lumped = hist["lumped"]["identification_rmse_n"]
    wrong = runs["twochamber"][0]["rmse_n"] > RACE_RATIO * lumped
    assert wrong  # on this damper the two-chamber form is far off (no test of the rule otherwise)
    assert [r["start"] for r in runs["twochamber"]] == ["Firefly best"], (runs, lumped)
    assert hist["twochamber"]["race"]["skipped"] == ["data-driven start"]
    assert hist["twochamber"]["race"]["ratio"] > RACE_RATIO


def test_a_wrong_forms_search_stops_once_a_rival_at_the_floor_leaves_it_far_behind():
    """The search of a base form stops after ``stop_start`` iterations when another base form's refinement ended
    at the residual floor and this form's best stands more than RACE_RATIO x that form's RMSE behind (it cannot
    win: the rival explains all but the noise); not before ``stop_start``, not with the stop off, not when it is
    within RACE_RATIO, nor without a rival at the floor, while its best still moves."""
    from types import SimpleNamespace

    from tuner.identification.firefly import FireflyOptions
    from tuner.identification.fit import RACE_RATIO, search_stop_now

    opts = FireflyOptions(population=6, max_iterations=150)

    def state(iteration: int, rmse_n: float):  # a best that still improves by 10 % an iteration
        history = [1.0 / (rmse_n * 1.1 ** (iteration - k)) ** 2 for k in range(iteration + 1)]
        return SimpleNamespace(iteration=iteration, best_fitness=history[-1], history_best=history, best_x=None)

    rival = ("lumped", 20.0)
    far = 20.0 * RACE_RATIO * 1.5
    stop = search_stop_now(state(opts.stop_start, far), opts, None, None, rival)
    assert stop["reason"] == "clearly the wrong form" and "lumped form's RMSE" in stop["text"]
    assert search_stop_now(state(opts.stop_start - 1, far), opts, None, None, rival) == {}
    off = FireflyOptions(population=6, max_iterations=150, stop_tol=None)
    assert search_stop_now(state(opts.stop_start, far), off, None, None, rival) == {}
    assert search_stop_now(state(opts.stop_start, 20.0 * RACE_RATIO * 0.9), opts, None, None, rival) == {}
    assert search_stop_now(state(opts.stop_start, far), opts, None, None, None) == {}


@pytest.mark.slow
def test_a_refinement_at_the_residual_floor_is_not_restarted_and_one_above_it_is(tmp_path):
    """The preset lumped damper with 20 N of force noise (which dominates the floor, so the floor is well known),
    fitted with the lumped model (which represents it): the first refinement ends within FLOOR_REACHED x the
    residual floor, the four restarts are skipped and recorded, and nothing is lost (the RMSE within RATIO of
    what the TRUE parameters score). The same damper with a friction the fitted model has no element for
    (300 N, far above the noise) stays above the floor: every restart runs."""
    from benchmarks.convergence import truth_rmse
    from campaign.synthetic import write_model_dataset
    from damper_fmu import defaults
    from tuner.data.reading import load_dataset
    from tuner.identification.engine import fastest_engine
    from tuner.identification.fit import FitSettings, fit, refinement_starts
    from tuner.identification.floor import FLOOR_REACHED

    # no Firefly iterations (as the diagnosis's bases): the refinements from its seeded first population's best
    settings = FitSettings(models=("lumped",), engine=fastest_engine(), iterations=0)
    hists = {}
    for name, extra in (("clean", {}), ("friction", {"friction_force": 300.0})):
        data = write_model_dataset(tmp_path / name, "lumped", {**defaults("lumped"), **extra}, seed=4,
                                   durations=(6.0, 6.0, 6.0), roles=("identification",) * 3, noise_n=20.0)
        tests = load_dataset(data)
        hists[name] = fit(tests, [], settings, log=lambda m: None).histories["lumped"]
        if name == "clean":
            truth, _ = truth_rmse("lumped", data, settings, fastest_engine())
    clean, rubbed = hists["clean"], hists["friction"]
    stop = clean["floor_stop"]
    assert stop is not None, clean["local_refinements"]
    assert len(clean["local_refinements"]) == 1 and len(stop["skipped"]) >= refinement_starts("lumped") - 2
    assert stop["rmse_n"] <= FLOOR_REACHED * stop["residual_floor_n"]
    assert clean["identification_rmse_n"] <= RATIO * truth, (clean["identification_rmse_n"], truth)
    assert rubbed["floor_stop"] is None
    assert rubbed["identification_rmse_n"] > 2.0 * FLOOR_REACHED * stop["residual_floor_n"]  # far above the floor
    assert len(rubbed["local_refinements"]) >= refinement_starts("lumped") - 1, rubbed["local_refinements"]
