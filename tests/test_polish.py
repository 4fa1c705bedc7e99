"""The local refinement (tuner.identification.polish) against exact least-squares solutions.

A fake engine and parametrisation: the parameters are u itself (the local space is the identity on
[0, 1]^d), the residuals a known function of u. References: scipy's bounded linear least squares,
and the same problem with a rough term that no smooth solver can use.
"""
import math

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from tuner.identification.polish import STEP, polish


class IdentitySpace:
    def __init__(self, d):
        self.dimension = d

    def to_params(self, u):
        return {"u": np.clip(np.asarray(u, float), 0.0, 1.0)}

    def from_params(self, p):
        return np.asarray(p["u"], float)


class IdentityPar(IdentitySpace):
    def local_space(self):
        return IdentitySpace(self.dimension)


class FakeEngine:
    def __init__(self, residual, n):
        self.residual, self.n_samples = residual, n

    def residuals_batch(self, points):
        return [self.residual(p["u"]) for p in points]


def problem(seed=0, n=200, d=6):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, d)) * np.logspace(0, 2, d)  # columns of different scales
    u_true = rng.uniform(0.1, 0.9, d)
    b = A @ u_true + rng.normal(scale=0.5, size=n)
    b += A[:, 0] * 0.5  # the unconstrained optimum leaves the box in u_0: the bound must be found
    return A, b


def test_converges_to_the_bounded_least_squares_solution():
    A, b = problem()
    ref = lsq_linear(A, b, bounds=(0.0, 1.0), tol=1e-14)
    eng = FakeEngine(lambda u: A @ u - b, A.shape[0])
    res = polish(eng, IdentityPar(A.shape[1]), np.full(A.shape[1], 0.5), log=lambda m: None)
    assert res.converged, res.stop
    sse = A.shape[0] / res.fitness
    assert sse <= float(np.sum((A @ ref.x - b) ** 2)) * (1 + 1e-6)
    assert np.allclose(res.z, ref.x, atol=1e-4)


def rough_problem():
    """The seed-1 problem plus a discontinuous term on a 1e-7 grid of u: invisible to a secant over
    COARSE_STEP, dominant over STEP (as the two-chamber model's root switching at valve openings)."""
    A, b = problem(seed=1)
    ref = lsq_linear(A, b, bounds=(0.0, 1.0), tol=1e-14)
    rmse_ref = math.sqrt(float(np.sum((A @ ref.x - b) ** 2)) / b.size)
    amplitude = 3e-4 * rmse_ref
    weights, phases = np.arange(1, A.shape[1] + 1), 1.7 * np.arange(b.size)

    def residual(u):
        return A @ u - b + amplitude * np.sign(np.sin(1e7 * float(u @ weights) + phases))

    return FakeEngine(residual, b.size), A.shape[1], ref.x, rmse_ref


def test_a_rough_objective_is_finished_with_coarse_differences():
    eng, d, x_ref, rmse_ref = rough_problem()
    res = polish(eng, IdentityPar(d), np.full(d, 0.5), max_jacobians=60, log=lambda m: None)
    assert res.converged, res.stop
    assert math.sqrt(1.0 / res.fitness) <= rmse_ref * 1.001, (math.sqrt(1.0 / res.fitness), rmse_ref)
    assert np.allclose(res.z, x_ref, atol=5e-3)


def test_the_rough_objective_defeats_fine_differences_alone(monkeypatch):
    """The problem above is a real test of the fallback: without it the refinement ends far off."""
    import tuner.identification.polish as module

    monkeypatch.setattr(module, "COARSE_STEP", STEP)
    eng, d, x_ref, rmse_ref = rough_problem()
    res = module.polish(eng, IdentityPar(d), np.full(d, 0.5), max_jacobians=60, log=lambda m: None)
    assert math.sqrt(1.0 / res.fitness) > 1.5 * rmse_ref


def test_the_rmse_standard_error_matches_its_spread_over_many_realisations():
    """tuner.metrics.rmse_standard_error against Monte Carlo: the spread of the RMSE of 300 independent
    residuals, white and strongly correlated (AR(1), phi 0.9: N_eff ~ N / 19)."""
    from tuner.metrics import rmse_standard_error

    rng = np.random.default_rng(5)
    for phi in (0.0, 0.9):
        rmses, predicted = [], []
        for _ in range(300):
            e = rng.normal(size=4000)
            r = np.empty_like(e)
            r[0] = e[0]
            for k in range(1, e.size):
                r[k] = phi * r[k - 1] + e[k]
            rmses.append(math.sqrt(float(r @ r) / r.size))
            predicted.append(rmse_standard_error(r))
        assert np.mean(predicted) == pytest.approx(np.std(rmses), rel=0.2), phi


def test_a_refinement_whose_gain_the_data_cannot_show_stops_at_the_data_resolution():
    """The rule's two conditions on a white residual of known RMSE (standard error sigma / sqrt(2 N)): a
    fall of the RMSE over the last RESOLUTION_WINDOW Jacobians below RESOLUTION_FRACTION of it (and below
    FTOL of the SSE) stops; a fall above either does not."""
    from tuner.identification.polish import RESOLUTION_FRACTION, RESOLUTION_WINDOW, resolution_stop

    rng = np.random.default_rng(1)
    r = rng.normal(scale=10.0, size=20000)
    rmse = math.sqrt(float(r @ r) / r.size)
    se = rmse / math.sqrt(2 * r.size)

    def history(fall):  # fitness N / SSE = 1 / RMSE^2, RMSE falling linearly by ``fall`` over the window
        return [1.0, *[(rmse + fall * (1 - k / RESOLUTION_WINDOW)) ** -2 for k in range(RESOLUTION_WINDOW + 1)]]

    assert resolution_stop(history(0.5 * RESOLUTION_FRACTION * se), r).startswith("converged to the data's resolution")
    assert resolution_stop(history(2.0 * RESOLUTION_FRACTION * se), r) is None
    assert resolution_stop(history(0.0)[-RESOLUTION_WINDOW:], r) is None  # too few Jacobians to judge


def test_a_slow_valley_where_no_model_reaches_the_noise_ends_on_the_resolution_rule(monkeypatch):
    """A residual dominated by a fixed, correlated model-form error that no parameter reaches, plus a narrow
    curved valley the refinement creeps along: with the rule it ends in fewer Jacobians than without it
    (the rule switched off), and the RMSE it leaves is within a quarter of the RMSE's standard error of what
    the longer refinement reaches."""
    import tuner.identification.polish as polish_module
    from tuner.metrics import rmse_standard_error

    n, d = 4000, 4
    t = np.linspace(0.0, 40.0, n)
    form_error = 30.0 * np.sin(2.1 * t) + 12.0 * np.sin(5.3 * t + 1.0)
    basis = np.column_stack([np.sin((k + 1) * 0.37 * t + k) for k in range(d)])
    target = np.array([0.3, 0.6, 0.4, 0.5])

    def residual(u):  # each coordinate's optimum depends on the previous one's square: a curved valley
        shifted = np.asarray(u) - target
        return form_error + basis @ (3.0 * (shifted + 20.0 * np.roll(shifted, 1) ** 2))

    eng, start = FakeEngine(residual, n), np.full(d, 0.95)
    res = polish(eng, IdentityPar(d), start, max_jacobians=100, log=lambda m: None)
    monkeypatch.setattr(polish_module, "RESOLUTION_FRACTION", 0.0)  # the rule never holds
    off = polish(eng, IdentityPar(d), start, max_jacobians=100, log=lambda m: None)
    assert res.rule == "data resolution" and res.jacobians < off.jacobians, (res.stop, off.stop)
    g, g_off = res.fitness, off.fitness
    assert g ** -0.5 - g_off ** -0.5 <= 0.25 * rmse_standard_error(form_error), (g ** -0.5, g_off ** -0.5)


def test_a_gain_is_resolvable_when_it_lowers_the_rmse_by_one_standard_error():
    """``resolvable_gain`` on a white residual of known RMSE sigma (standard error sigma / sqrt(2 N)): a share p of
    the SSE lowers the RMSE by sigma (1 - sqrt(1 - p)); just above one standard error it is resolvable, just
    below it is not."""
    from tuner.identification.polish import resolvable_gain

    rng = np.random.default_rng(3)
    r = rng.normal(scale=10.0, size=20000)
    rmse = math.sqrt(float(r @ r) / r.size)
    se = rmse / math.sqrt(2 * r.size)
    share = lambda drop: 1.0 - (1.0 - drop / rmse) ** 2  # noqa: E731 - the share of the SSE a fall ``drop`` [N] is
    assert resolvable_gain(share(1.2 * se), r)
    assert not resolvable_gain(share(0.8 * se), r)


def test_a_refinement_whose_steps_achieve_far_less_than_predicted_is_stalled_not_converged():
    """White noise plus a fine ripple in every coordinate (a rough objective, as the two-chamber model's root
    switching makes): the Gauss-Newton step keeps predicting most of the SSE while the steps achieve little. The
    refinement must not call that convergence: it ends 'stalled' (not converged), and whatever it ends on, it
    never says converged while its last step predicts a gain of more than one standard error of the RMSE."""
    from tuner.identification.polish import resolvable_gain

    n, d = 4000, 4
    noise = np.random.default_rng(0).normal(scale=5.0, size=n)
    t = np.linspace(0.0, 40.0, n)
    basis = np.column_stack([np.sin((k + 1) * 0.37 * t + k) for k in range(d)])
    target = np.array([0.3, 0.6, 0.4, 0.5])
    for ripple, amplitude in ((1e4, 0.3), (3e4, 1.0), (3e3, 0.5)):
        def residual(u, ripple=ripple, amplitude=amplitude):
            u = np.asarray(u)
            return noise + basis @ (30.0 * (u - target) + amplitude * np.sin(ripple * u))

        res = polish(FakeEngine(residual, n), IdentityPar(d), np.full(d, 0.95), max_jacobians=100, log=lambda m: None)
        assert not (res.converged and resolvable_gain(res.predicted, residual(res.z))), (ripple, res.stop)
        if ripple == 1e4:
            assert res.rule == "stalled" and not res.converged, res.stop



FLOOR = 0.02 * np.random.default_rng(5).normal(size=200)  # a residual part no parameter moves


def valley(u):
    """Rosenbrock's valley in x = 2 u with a third term, beside ``FLOOR``: two basins, the best at x = (1, 1)
    (SSE: FLOOR's alone) and a worse one on the bound x_1 = 0 (about 0.9 N^2 more)."""
    x = 2.0 * np.asarray(u, float)
    return np.concatenate([[10.0 * (x[1] - x[0] ** 2), 1.0 - x[0], 3.0 * (x[1] - 1.0) * x[0]], FLOOR])


def test_a_restart_in_a_worse_basin_stops_once_its_settled_prediction_cannot_beat_the_fit():
    """``beat``: a start in the worse basin stops as 'cannot beat' before it would converge there; a start in the
    better basin reaches below the same target."""
    eng = FakeEngine(valley, FLOOR.size + 3)
    worse = polish(eng, IdentityPar(2), np.array([0.05, 0.05]), log=lambda m: None)
    sse_worse = eng.n_samples / worse.fitness
    assert sse_worse > float(FLOOR @ FLOOR) + 0.5 and worse.converged  # the worse basin's minimum
    target = 0.9 * sse_worse
    short = polish(eng, IdentityPar(2), np.array([0.05, 0.05]), log=lambda m: None, beat=target)
    assert short.rule == "cannot beat" and not short.converged and short.jacobians < worse.jacobians
    better = polish(eng, IdentityPar(2), np.array([0.9, 0.05]), log=lambda m: None, beat=target)
    assert eng.n_samples / better.fitness < 1.001 * float(FLOOR @ FLOOR)


def test_a_prediction_that_still_moves_does_not_stop_a_refinement():
    """``cannot_beat`` with the ends a random lumped damper's data-driven start predicted (1141 N rms at the start;
    its refinement, unstopped, reached 8.8 N against a fit at 21.08 N): predictions still falling by far more
    than a standard error do not stop it; settled above the target, they do; below it, never."""
    from tuner.identification.polish import cannot_beat
    assert not cannot_beat([900.0, 639.0], 21.08, 5.0)
    assert cannot_beat([30.2, 30.0], 21.08, 0.5)
    assert not cannot_beat([30.0], 21.08, 0.5)  # one prediction is not enough
    assert not cannot_beat([21.5, 20.9], 21.08, 0.5)
