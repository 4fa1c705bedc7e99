"""Shooting for limit cycles (campaign.periodic_orbits) on the normal form of a subcritical Hopf bifurcation, whose
stable and unstable cycles, fold and Floquet multipliers are known in closed form:

    r' = k r (mu + 2 r^2 - r^4),  theta' = omega,  mu = (V - V_H) / V_S   (in x = r cos theta, y = r sin theta):

a cycle of radius A exists at mu = A^4 - 2 A^2, i.e. V = V_H + V_S (A^4 - 2 A^2) (the fold at A = 1), with period
2 pi / omega and non-trivial multiplier exp(4 k A^2 (1 - A^2) T): unstable for A < 1, stable for A > 1."""
import math

import numpy as np
import pytest

from campaign.periodic_orbits import (PeriodicOrbit, ShootingProblem, continue_in_amplitude, floquet_multipliers,
                                      solve_orbit)

V_H, V_S, K, OMEGA = 100.0, 20.0, 0.5, 2.0 * math.pi * 5.0


def rhs(v, s):
    x, y = s
    r2 = x * x + y * y
    g = K * ((v - V_H) / V_S + 2.0 * r2 - r2 * r2)
    return np.array([g * x - OMEGA * y, g * y + OMEGA * x])


PROBLEM = ShootingProblem(rhs, 0, 1, np.array([1.0, 1.0]), steps_per_second=4000.0)


def speed_of(a):
    return V_H + V_S * (a ** 4 - 2.0 * a ** 2)


def test_an_unstable_cycle_is_found_with_its_speed_period_and_multiplier():
    a, T = 0.6, 2.0 * math.pi / OMEGA
    guess = PeriodicOrbit(a, speed_of(a) + 2.0, 1.05 * T, np.array([a, 0.0]))
    o = solve_orbit(PROBLEM, a, guess)
    assert o.speed == pytest.approx(speed_of(a), abs=1e-6)
    assert o.period == pytest.approx(T, rel=1e-8)
    floquet_multipliers(PROBLEM, o)
    assert o.stable is False
    mu = np.sort(np.abs(o.multipliers))
    assert mu[0] == pytest.approx(1.0, abs=1e-5)  # the phase
    assert mu[1] == pytest.approx(math.exp(4.0 * K * a * a * (1.0 - a * a) * T), rel=1e-4)


def test_continuation_in_amplitude_passes_the_fold_from_the_stable_to_the_unstable_branch():
    a0 = 1.3
    start = PeriodicOrbit(a0, speed_of(a0) - 1.0, 2.0 * math.pi / OMEGA, np.array([a0, 0.0]))
    branch = continue_in_amplitude(PROBLEM, start, np.arange(1.3, 0.45, -0.1))
    assert len(branch) == 9
    for o in branch:
        assert o.speed == pytest.approx(speed_of(o.amplitude), abs=1e-5)
        if abs(o.amplitude - 1.0) > 1e-6:  # at the fold itself the multiplier is 1
            assert o.stable is (o.amplitude > 1.0)
    assert min(o.speed for o in branch) == pytest.approx(V_H - V_S, abs=1e-5)  # the fold, at A = 1
    with pytest.raises(ValueError, match="amplitude"):
        solve_orbit(PROBLEM, -1.0, start)
