"""The injection check of a detection limit (benchmarks/limit_injection.py) against linear least squares in closed
form: a fake engine whose simulated force is c v + Ff sign(v) (the base: the damping c; the effect: a Coulomb
friction), data c0 v + e with e orthogonal to both, so the base refit on the injected data is the projection of the
friction's force onto v."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from benchmarks.limit_injection import injection_check
from tuner.diagnosis.rules import PENALTY_PER_PARAMETER
from tuner.identification.parametrization import Parametrization

C0 = 1e5  # [N s/m]


class LinearEngine:
    """Residuals [N] of measured c0 v + e against c v + Ff sign(v) on one test (velocity ``v`` [m/s])."""

    def __init__(self, v: np.ndarray, e: np.ndarray):
        self.v, self.e, self.n_samples, self.tests = v, e, len(v), []

    def residuals_batch(self, points):
        return [C0 * self.v + self.e - p["c"] * self.v - p.get("friction_force", 0.0) * np.sign(self.v)
                for p in points]


def test_the_injected_friction_is_refitted_as_its_projection_and_scored_in_closed_form():
    t = np.linspace(0.0, 4.0, 4000, endpoint=False)
    v_id, v_val = 0.1 * np.sin(2 * np.pi * t), 0.05 * np.sin(4 * np.pi * t)
    e_id, e_val = 20.0 * np.cos(2 * np.pi * t), 15.0 * np.cos(4 * np.pi * t)  # orthogonal to v and sign(v)
    par = Parametrization("maxwell", force_limit=4e4)
    s = SimpleNamespace(par=par, z_none=par.from_params({"k_s": 1e7, "c": C0}), eid=LinearEngine(v_id, e_id),
                        ev=LinearEngine(v_val, e_val))
    m = 300.0  # [N]
    check = injection_check(s, "friction_force", m, jacobians=20)
    sgn = np.sign(v_id)
    shift = m * float(sgn @ v_id) / float(v_id @ v_id)  # the damping the refit takes on [N s/m]
    left = m * sgn - shift * v_id  # what it cannot absorb [N]
    sse, sse0 = float((e_id + left) @ (e_id + left)), float(e_id @ e_id)
    assert check.screen_share == pytest.approx((sse - sse0) / sse, rel=1e-3)
    r_val = e_val + m * np.sign(v_val) - shift * v_val
    assert check.score == pytest.approx(math.log(float(r_val @ r_val) / float(e_val @ e_val)) - PENALTY_PER_PARAMETER,
                                        rel=1e-3)
    assert check.force_n == pytest.approx(m * math.sqrt(float(np.mean(sgn ** 2))), rel=1e-9)
    assert check.named(noise_n=10.0) and not check.named(noise_n=2 * m)
