"""Shooting for limit cycles (campaign.periodic_orbits) on the normal form of a subcritical Hopf bifurcation, whose
stable and unstable cycles, fold and Floquet multipliers are known in closed form:

    r' = k r (mu + 2 r^2 - r^4),  theta' = omega,  mu = (V - V_H) / V_S   (in x = r cos theta, y = r sin theta):

a cycle of radius A exists at mu = A^4 - 2 A^2, i.e. V = V_H + V_S (A^4 - 2 A^2) (the fold at A = 1), with period
2 pi / omega and non-trivial multiplier exp(4 k A^2 (1 - A^2) T): unstable for A < 1, stable for A > 1."""
import dataclasses
import math

import numpy as np
import pytest

from campaign.periodic_orbits import (PeriodicOrbit, ShootingProblem, continue_in_amplitude, floquet_multipliers,
                                      solve_orbit, vehicle_shooting_problem)
from campaign.vehicle import VehicleModel, VehicleParams, critical_speed
from campaign.vehicle_nonlinear import LEADING_WHEELSET

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


def test_the_cars_smallest_cycle_sits_at_the_eigenvalue_critical_speed():
    """The nonlinear car (linear dashpot, conicity 0.25) shot at 1 micrometre of the leading wheelset from the
    linear hunting mode at a speed 2 % off: the cycle's speed is campaign.vehicle.critical_speed (to 0.1 %;
    measured 1.2e-4, the bisection's tolerance being 0.01 m/s) and its period that of the critical eigenvalue
    (to 0.1 %; measured 4.6e-5)."""
    p = dataclasses.replace(VehicleParams(), conicity=0.25, yaw_blowoff_velocity=math.inf)
    v_c = critical_speed(p, v_max=300.0, tol=0.01)
    lam, vec = np.linalg.eig(VehicleModel(p, v_c).A)
    k = int(np.argmax(np.where(lam.imag > 0, lam.real, -np.inf)))
    a = 1e-6
    x0 = (vec[:, k] / vec[LEADING_WHEELSET, k]).real * a
    T = 2.0 * math.pi / lam[k].imag
    scale = np.maximum(np.abs(vec[:, k] / vec[LEADING_WHEELSET, k]) * a, 1e-12)
    prob = vehicle_shooting_problem(p, None, scale, steps_per_second=500.0)  # RK4 at 2 ms: inside its stability
    o = solve_orbit(prob, a, PeriodicOrbit(a, 1.02 * v_c, T, x0), tol=1e-6)
    assert o.speed == pytest.approx(v_c, rel=1e-3)
    assert o.period == pytest.approx(T, rel=1e-3)
