"""The local refinement (tuner.identification.polish) against exact least-squares solutions.

A fake engine and parametrisation: the parameters are u itself (the local space is the identity on
[0, 1]^d), the residuals a known function of u. References: scipy's bounded linear least squares,
and the same problem with a rough term that no smooth solver can use.
"""
import math

import numpy as np
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
    z, g, evals, info = polish(eng, IdentityPar(A.shape[1]), np.full(A.shape[1], 0.5), log=lambda m: None)
    assert info["converged"], info["stop"]
    sse = A.shape[0] / g
    assert sse <= float(np.sum((A @ ref.x - b) ** 2)) * (1 + 1e-6)
    assert np.allclose(z, ref.x, atol=1e-4)


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
    z, g, evals, info = polish(eng, IdentityPar(d), np.full(d, 0.5), max_jacobians=60, log=lambda m: None)
    assert info["converged"], info["stop"]
    assert math.sqrt(1.0 / g) <= rmse_ref * 1.001, (math.sqrt(1.0 / g), rmse_ref)
    assert np.allclose(z, x_ref, atol=5e-3)


def test_the_rough_objective_defeats_fine_differences_alone(monkeypatch):
    """The problem above is a real test of the fallback: without it the refinement ends far off."""
    import tuner.identification.polish as module

    monkeypatch.setattr(module, "COARSE_STEP", STEP)
    eng, d, x_ref, rmse_ref = rough_problem()
    z, g, evals, info = module.polish(eng, IdentityPar(d), np.full(d, 0.5), max_jacobians=60, log=lambda m: None)
    assert math.sqrt(1.0 / g) > 1.5 * rmse_ref
