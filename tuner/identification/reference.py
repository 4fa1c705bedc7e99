"""Converged reference solutions for accuracy checks: the lumped model as an ODE integrated by
scipy's LSODA (error-controlled, switching to a stiff BDF method where the silent blocks make the
system stiff) under a continuous stroke function.

Why LSODA and not Radau: on a 5 s, 500 Hz multi-sine of the preset damper at rtol 1e-8, Radau took
23 s (38,000 steps of scipy's Python collocation solver) and LSODA 4.9 s, and LSODA came closer to a
Radau solution at rtol 1e-10 (2.7e-7 against 6.6e-7 of the peak force).

An independent formulation of ``damper_fmu.models.LumpedModel`` (right-hand side instead of the
implicit stage solver), used by tests and benchmarks to judge the FMUs at co-simulation step
sizes. Units SI; stroke positive in extension, force positive in tension.
"""
from __future__ import annotations

import numpy as np

from damper_fmu import make_model

__all__ = ["lumped_reference"]


def lumped_reference(params: dict, stroke, velocity, t_eval, *, rtol: float = 1e-9) -> np.ndarray:
    """Output force [N] of the lumped model at ``t_eval`` [s] under the stroke ``stroke(t)`` [m]
    with derivative ``velocity(t)`` [m/s] (callables), from the force-free state at t_eval[0]."""
    from scipy.integrate import solve_ivp

    m = make_model("lumped", params)
    kB, cB, mP, mO, mC = m.kB, m.cB, m.mP, m.mO, m.mC
    fc, fk = m.fc, m.fk

    def rhs(t, y):
        x2, x3, x4, v2, v3, v4 = y
        x1, v1 = stroke(t), velocity(t)
        fa = kB * (x1 - x2) + cB * (v1 - v2)
        f_c = fc(v2 - v3)
        f_k = fk(x3 - x4)
        fb = kB * x4 + cB * v4
        return [v2, v3, v4, (fa - f_c) / mP, (f_c - f_k) / mO, (f_k - fb) / mC]

    t_eval = np.asarray(t_eval, dtype=float)
    t0 = float(t_eval[0])
    y0 = m.initial_state(float(stroke(t0)), float(velocity(t0)))
    scale = max(1e-3, float(np.max(np.abs(stroke(t_eval)))))
    atol = np.array([1e-10 * scale] * 3 + [1e-9 * scale] * 3)
    sol = solve_ivp(rhs, (t0, float(t_eval[-1])), y0, method="LSODA", t_eval=t_eval, rtol=rtol, atol=atol,
                    max_step=1e-3)
    if not sol.success:
        raise RuntimeError(f"reference solution failed: {sol.message}")
    x2, v2 = sol.y[0], sol.y[3]
    return kB * (stroke(t_eval) - x2) + cB * (velocity(t_eval) - v2)
