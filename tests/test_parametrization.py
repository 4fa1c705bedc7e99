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


def test_holding_a_scalar_removes_its_coordinate_and_keeps_its_value():
    """A held parameter is no coordinate and comes back at its held value; the others map as before; a table
    ordinate or a name outside the space cannot be held."""
    par = Parametrization("twochamber", force_limit=4e4)
    p = par.to_params(np.full(par.dimension, 0.4))
    held = par.holding({"k_M": 3.0e8, "c_M": 5.1e4})
    assert held.dimension == par.dimension - 2 and "k_M" not in held.names
    q = held.to_params(held.from_params(p))
    assert q["k_M"] == 3.0e8 and q["c_M"] == 5.1e4
    for n in par.names:
        if n not in ("k_M", "c_M"):
            assert q[n] == pytest.approx(p[n], rel=1e-9)
    assert par.dimension == len(par.names)  # the original is untouched
    with pytest.raises(ValueError, match="Fc_01"):
        par.holding({"Fc_01": -1e3})
    with pytest.raises(ValueError, match="k_B"):
        par.holding({"k_B": 1e8})
