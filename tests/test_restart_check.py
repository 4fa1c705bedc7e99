"""The restart check (tuner.identification.restart_check) and the Firefly stop that knows a seeded start stands
still (tuner.identification.fit.search_stop_now), on problems whose minima are known."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from tuner.identification.polish import polish
from tuner.identification.restart_check import restart_check


class NamedPar:
    """A design space of named coordinates in [0, 1], its own local space; ``holding`` as Parametrization's."""

    def __init__(self, names, fixed=None):
        self.names, self.fixed = list(names), dict(fixed or {})
        self.dimension = len(self.names)
        self.bounds = {n: (1e-3, 1.0) for n in self.names}  # search limits, none the absence of an element

    def to_params(self, z):
        return {**self.fixed, **{n: float(v) for n, v in zip(self.names, np.clip(np.asarray(z, float), 0.0, 1.0))}}

    def from_params(self, p):
        return np.array([p[n] for n in self.names], dtype=float)

    def local_space(self):
        return self

    def holding(self, values):
        return NamedPar([n for n in self.names if n not in values], {**self.fixed, **values})


class Engine:
    def __init__(self, residual, n):
        self.residual, self.n_samples = residual, n

    def residuals_batch(self, points):
        return [self.residual(p) for p in points]


N = 4000
NOISE = np.random.default_rng(0).normal(scale=5.0, size=N)
T = np.linspace(0.0, 40.0, N)
S1, S2 = np.sin(0.37 * T), np.sin(1.3 * T + 1.0)


def two_basins(dip: float):
    """Residual [N] of coordinates a, b: a force h(a) = 1 + a - dip exp(-((a - 0.7) / 0.12)^2) on one signal and
    b - 0.4 on another, over white noise of 5 N. With dip = 2.2, h rises from a = 0 (a refinement there is held on
    the bound: a local minimum with h = 1) and crosses zero near a = 0.6 (the global one); with dip = 0 the bound
    is the only minimum."""
    def residual(p):
        h = 1.0 + p["a"] - dip * math.exp(-((p["a"] - 0.7) / 0.12) ** 2)
        return NOISE + 30.0 * h * S1 + 30.0 * (p["b"] - 0.4) * S2
    return residual


def test_a_fit_held_on_a_bound_in_the_wrong_basin_is_moved_by_the_restart_check():
    """The refinement from a = 0 converges on the bound (its own rule says so); the check restarts with a held at
    the middle of its range, then released, ends in the other basin (h = 0 there: noise alone left), more than one
    standard error lower, and a second round from there finds nothing lower: it survives at the global minimum."""
    par, eng = NamedPar(["a", "b"]), Engine(two_basins(2.2), N)
    first = polish(eng, par, np.array([0.0, 0.9]), log=lambda m: None)
    assert first.converged and first.z[0] == 0.0, first.stop
    check = restart_check(eng, par, first.z, first.fitness, None, 50, log=lambda m: None)
    assert check.polished is not None and check.survived and check.rounds == 2
    h = 1.0 + check.z[0] - 2.2 * math.exp(-((check.z[0] - 0.7) / 0.12) ** 2)
    assert abs(h) < 0.01 and abs(check.z[1] - 0.4) < 0.01, check.z
    noise_rmse = math.sqrt(float(NOISE @ NOISE) / N)
    assert check.g ** -0.5 < 1.01 * noise_rmse < first.fitness ** -0.5 - check.standard_error_n
    assert check.runs[0]["start"].startswith("a held at 0.5")


def test_a_fit_at_its_only_minimum_survives_the_restart_check_unchanged():
    par, eng = NamedPar(["a", "b"]), Engine(two_basins(0.0), N)
    first = polish(eng, par, np.array([0.3, 0.9]), log=lambda m: None)
    assert first.converged and first.z[0] == 0.0, first.stop
    population = np.array([[0.9, 0.9], [0.05, 0.41]])  # the brightest one elsewhere is restarted from, the near one not
    check = restart_check(eng, par, first.z, first.fitness, population, 50, log=lambda m: None)
    assert check.survived and check.polished is None and check.rounds == 1
    assert [r["start"] for r in check.runs] == ["a held at 0.5 (mid-range; it ended on its bound), then released",
                                                 "the brightest firefly elsewhere"]
    assert all(r["rmse_n"] >= first.fitness ** -0.5 - check.standard_error_n for r in check.runs)


def test_a_seeded_start_that_no_firefly_has_passed_is_a_stall_not_convergence():
    """search_stop_now: a best that has not moved since the first generation (the paper's brightest firefly stands
    still) ends the search as a 'stall', never as convergence; once a firefly has passed it, the data-resolution
    rule counts only the iterations after that move."""
    from tuner.identification.firefly import FireflyOptions
    from tuner.identification.fit import first_improvement, search_stop_now

    opts = FireflyOptions(population=6, max_iterations=150)
    r = np.random.default_rng(1).normal(scale=10.0, size=20000)  # the residual at the best: 10 N white
    eng = SimpleNamespace(residuals_batch=lambda points: [r])
    par = SimpleNamespace(to_params=lambda z: {"z": z})

    def state(history_rmse):
        history = [rmse ** -2 for rmse in history_rmse]
        return SimpleNamespace(iteration=len(history) - 1, best_fitness=history[-1], history_best=history,
                               best_x=np.zeros(2))

    flat = state([10.0] * (opts.stop_window + 1))
    assert first_improvement(flat.history_best) is None
    stall = search_stop_now(flat, opts, eng, par, None)
    assert stall["reason"] == "stall" and "no firefly improved on the start" in stall["text"]
    assert "converged" not in stall["text"]
    moved = state([12.0] * 31 + [10.0] * 15)  # passed at iteration 31, flat since: 14 iterations after the move
    assert first_improvement(moved.history_best) == 31
    assert search_stop_now(moved, opts, eng, par, None) == {}
    settled = state([12.0] * 31 + [10.0] * 21)  # 20 flat iterations after the move
    assert search_stop_now(settled, opts, eng, par, None)["reason"] == "data resolution"


def test_a_fit_is_converged_by_its_rule_or_by_a_restart_check_that_a_stall_survived():
    """Refinement.converged_by: a refinement's rule counts only when no restart of the check ended lower; a stall
    counts only through a check it survived or at the residual floor (where the check is not run); a check whose
    last round still moved the fit, a spent budget, or a stall of the wrong form (no check) is no convergence."""
    from tuner.identification.fit import Refinement
    from tuner.identification.polish import PolishResult
    from tuner.identification.restart_check import RestartCheck

    def refinement(rule, converged, survived, at_floor=False):
        pol = PolishResult(np.zeros(2), 1.0, 10, stop=rule, converged=converged, rule=rule, jacobians=3,
                           predicted=0.1, budget_spent=rule == "budget")
        check = None if survived is None else RestartCheck(np.zeros(2), 1.0, 0.5, survived=survived)
        floor_stop = {"rmse_n": 1.0, "residual_floor_n": 1.0, "skipped": ["the restart check"]} if at_floor else None
        return Refinement(np.zeros(2), 1.0, 10, pol, [], None, check=check, floor_stop=floor_stop)

    assert refinement("data resolution", True, True).converged_by == "data resolution"
    assert refinement("data resolution", True, None).converged_by == "data resolution"
    assert refinement("data resolution", True, False).converged_by is None
    assert refinement("stalled", False, True).converged_by == "restart check"
    assert refinement("stalled", False, None).converged_by is None
    assert refinement("stalled", False, None, at_floor=True).converged_by == "residual floor"
    assert refinement("stalled", False, False).converged_by is None
    assert refinement("budget", False, True).converged_by is None
    assert not refinement("budget", False, True).converged


def test_the_series_element_on_a_bound_is_held_at_the_decades_the_diagnosis_holds():
    """A two-chamber fit whose mount stiffness ended on its lower bound: the check holds it at the data-driven
    guess's stiffness one and two decades up (the diagnosis's ladder's first values, ``series_decades``), not at the
    middle of its range, and every other coordinate on a bound still at its middle."""
    from tuner.identification.parametrization import Parametrization
    from tuner.identification.restart_check import SeriesHold, restart_starts, series_decades

    par = Parametrization("twochamber", "improved")
    z = np.full(par.dimension, 0.4)
    k = par.names.index("k_M")
    z[k] = 0.0  # on its lower bound
    other = next(i for i, n in enumerate(par.names) if n != "k_M" and not n.startswith(("Fc_", "Fk_")))
    z[other] = 1.0
    held = series_decades(par.bounds["k_M"], 3e7, softest=1e5)
    assert held[:2] == pytest.approx([3e8, 3e9])
    starts = restart_starts(par, z, None, SeriesHold("k_M", tuple(held[:2])))
    mounts = [s for s in starts if s[2] == "k_M"]
    assert [par.to_params(s[1])["k_M"] for s in mounts] == pytest.approx([3e8, 3e9])
    (mid,) = [s for s in starts if s[2] == par.names[other]]
    assert mid[1][other] == 0.5


def test_a_coordinate_on_a_zero_lower_bound_is_not_restarted_but_one_on_its_upper_bound_is():
    """The entrained air at 0 (no air: the element absent, a value the model takes exactly) is no search limit to
    restart from; the same coordinate on its upper bound, and a coordinate on a non-zero lower bound, are."""
    from tuner.identification.parametrization import Parametrization
    from tuner.identification.restart_check import restart_starts

    par = Parametrization("twochamber", "improved")
    assert par.bounds["air"][0] == 0.0 and par.bounds["L_R"][0] > 0.0
    z = np.full(par.dimension, 0.4)
    a, lr = par.names.index("air"), par.names.index("L_R")
    z[a], z[lr] = 0.0, 0.0
    held = {s[2] for s in restart_starts(par, z, None)}
    assert "air" not in held and "L_R" in held
    z[a] = 1.0
    assert "air" in {s[2] for s in restart_starts(par, z, None)}
