"""Local refinement after the Firefly search: bounded least squares in the scaled design space.

The paper's Firefly algorithm finds the right region but, with rho = 0.9^(k-1) and a brightest
firefly that never moves, it stalls a few percent away from the optimum in narrow valleys (a
2-parameter Maxwell fit on noise-only data ends 4-7 % off; see tests/test_tuner_cli.py). The
objective is a sum of squares, so a trust-region reflective least-squares solver
(scipy.optimize.least_squares, bounds [0, 1]) started from the Firefly best converges in a few
Jacobians. Each forward-difference Jacobian (d + 1 simulations) is evaluated as one batch
through the same engine, i.e. in parallel through the FMU. The result is kept only if it
improves the fitness; the Firefly best is never lost.
"""
from __future__ import annotations

import math

import numpy as np

from tuner.progress import advance

__all__ = ["polish"]

#: Jacobians a refinement typically takes to converge (for the progress display only)
TYPICAL_JACOBIANS = 15


class _Done(Exception):
    """Budget spent or converged (raised from the Jacobian callback)."""


def polish(engine, par, z0: np.ndarray, *, max_jacobians: int = 15, step: float = 1e-4, log=print):
    """Refine the scaled point z0; return (z_best, fitness_best, evaluations_used, history).

    engine: tuner.identification.engine.Engine; par: tuner.identification.parametrization.Parametrization; step: forward
    difference step in scaled units; history: {"fitness": G after each Jacobian and at the end,
    "stop": why it stopped, "converged": bool}. It stops when converged (three Jacobians without a
    relative fitness gain of 1e-4, or the solver's own tolerances) or, still improving, at
    ``max_jacobians`` (a safety budget, reported as not converged).
    """
    from scipy.optimize import least_squares

    n = engine.n_samples
    cache: dict[bytes, np.ndarray] = {}
    used = {"evals": 0}
    big = None

    def residual_batch(points):
        todo = [p for p in points if p.tobytes() not in cache]
        if todo:
            res = engine.residuals_batch([par.to_params(p) for p in todo])
            used["evals"] += len(todo)
            for p, r in zip(todo, res):
                cache[p.tobytes()] = r
        return [cache[p.tobytes()] for p in points]

    r0 = residual_batch([np.asarray(z0, float)])[0]
    if r0 is None:
        return z0, 0.0, used["evals"], {"fitness": [], "stop": "start point cannot be simulated",
                                        "converged": False}
    big = np.full_like(r0, 10.0 * np.sqrt(np.mean(r0 * r0)) + 1.0)
    history = [n / float(r0 @ r0)]

    def fun(z):
        r = residual_batch([np.clip(z, 0.0, 1.0)])[0]
        return big if r is None else r

    stop = {"why": "", "converged": False}

    def jac(z):
        if len(history) > max_jacobians:
            stop.update(why=f"budget of {max_jacobians} Jacobians spent while still improving", converged=False)
            raise _Done
        if len(history) >= 4 and history[-1] <= history[-4] * (1.0 + 1e-4):
            stop.update(why="converged: three Jacobians without a relative gain of 1e-4", converged=True)
            raise _Done
        z = np.clip(z, 0.0, 1.0)
        steps = np.where(z + step <= 1.0, step, -step)
        pts = [z] + [z + np.eye(len(z))[i] * steps[i] for i in range(len(z))]
        res = residual_batch(pts)
        base = big if res[0] is None else res[0]
        cols = [((big if r is None else r) - base) / h for r, h in zip(res[1:], steps)]
        best = float(base @ base)
        if best > 0:
            history.append(n / best)
            log(f"    polish: Jacobian {len(history) - 1}/{max_jacobians}, RMSE {math.sqrt(best / n):.1f} N")
            advance(log, 0.85 + 0.15 * min(1.0, (len(history) - 1) / TYPICAL_JACOBIANS))
        return np.column_stack(cols)

    try:
        sol = least_squares(fun, np.clip(z0, 0.0, 1.0), jac=jac, bounds=(0.0, 1.0), method="trf",
                            x_scale="jac", max_nfev=max_jacobians * 3, xtol=1e-10, ftol=1e-10, gtol=1e-10)
        candidates = [np.clip(sol.x, 0.0, 1.0)]
        stop.update(why=f"solver: {sol.message}", converged=sol.status > 0)
    except _Done:
        candidates = []
    # best point seen (every evaluated point is cached)
    z, g = np.asarray(z0, float), 0.0
    for key, r in cache.items():
        if r is not None and n / float(r @ r) > g:
            z, g = np.frombuffer(key, dtype=float).copy(), n / float(r @ r)
    for c in candidates:
        r = residual_batch([c])[0]
        if r is not None and n / float(r @ r) > g:
            z, g = c, n / float(r @ r)
    g0 = n / float(r0 @ r0)
    info = {"fitness": history, "stop": stop["why"], "converged": stop["converged"]}
    if g <= g0:
        return np.asarray(z0, float), g0, used["evals"], info
    history.append(g)
    return z, g, used["evals"], info
