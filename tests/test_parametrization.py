"""Design-variable mappings: bounds, monotone tables, round trips, log scaling."""
import math

import numpy as np
import pytest

from damper_fmu import defaults, make_model
from tuner.identification.parametrization import Parametrization


@pytest.mark.parametrize("model", ["lumped", "maxwell", "maxwell_table"])
@pytest.mark.parametrize("scheme", ["paper", "improved"])
def test_preset_round_trips_through_the_scaled_space(model, scheme):
    par = Parametrization(model, scheme, force_limit=4e4)
    p = defaults(model)
    back = par.to_params(par.from_params(p))
    for n in par.names:
        assert back[n] == pytest.approx(p[n], rel=1e-12, abs=1e-9)


def test_paper_scheme_is_linear_between_the_bounds():
    par = Parametrization("lumped", "paper")
    lo = par.to_params(np.zeros(par.dimension))
    hi = par.to_params(np.ones(par.dimension))
    mid = par.to_params(np.full(par.dimension, 0.5))
    for n in par.names:
        assert (lo[n], hi[n]) == pytest.approx(par.bounds[n])
        assert mid[n] == pytest.approx(0.5 * (lo[n] + hi[n]))
    assert mid["k_B"] == pytest.approx(0.5 * (1e2 + 1e9))  # linear over seven decades


def test_improved_scheme_searches_stiffness_and_damping_in_log_space():
    par = Parametrization("lumped", "improved")
    z = np.full(par.dimension, 0.5)
    mid = par.to_params(z)
    assert mid["k_B"] == pytest.approx(math.sqrt(1e2 * 1e9))
    assert mid["c_B"] == pytest.approx(math.sqrt(1e2 * 1e7))


def test_improved_scheme_gives_monotone_tables_within_bounds_for_any_point():
    par = Parametrization("lumped", "improved", force_limit=3e4)
    rng = np.random.default_rng(0)
    for _ in range(300):
        p = par.to_params(rng.random(par.dimension))
        model = make_model("lumped", p)
        assert model.fc.is_monotonic and model.fk.is_monotonic
        assert max(abs(f) for f in model.fc.fs) <= 3e4 + 1e-6
        for n in par.names:
            if n.startswith("Fk_"):
                lo, hi = par.bounds[n]
                assert lo - 1e-6 <= p[n] <= hi + 1e-6


def test_paper_scheme_draws_non_monotone_tables_which_the_model_rejects():
    """The weakness the improved scheme removes: independent ordinates give tables whose force
    falls somewhere (not a passive element); the model refuses them by name."""
    par = Parametrization("lumped", "paper")
    rng = np.random.default_rng(1)
    rejected = 0
    for _ in range(100):
        try:
            make_model("lumped", par.to_params(rng.random(par.dimension)))
        except ValueError as err:
            assert "not monotone" in str(err)
            rejected += 1
    assert rejected > 90
