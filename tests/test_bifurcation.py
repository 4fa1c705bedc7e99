"""The ramp-down bifurcation diagram (campaign.bifurcation) on a system whose limit cycles are known in closed
form: the normal form of a subcritical Hopf bifurcation with a fold,

    r' = k r (mu + 2 r^2 - r^4),  theta' = omega,  mu = (v - v_H) / v_s,  y = a r cos(theta),

whose stable cycles have r^2 = 1 + sqrt(1 + mu) and which folds at mu = -1 (v = v_H - v_s, r = 1); its
linear critical speed is v_H. The ramp must find the branch's amplitudes and the fold as the nonlinear
critical speed; where the fold lies above the linear critical speed the nonlinear one is the linear one."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from campaign.bifurcation import BifurcationDiagram, LimitCycle, RampSettings, conicity_sweep, ramp_down, start_speed
from campaign.vehicle_nonlinear import LEADING_WHEELSET, NonlinearRun

V_H, V_S, K, OMEGA, SCALE = 100.0, 20.0, 2.0, 2.0 * math.pi * 5.0, 5e-3


def normal_form_runner(speed, x0, duration, v_h=V_H):
    """State (r, theta, 0, y): y = SCALE r cos(theta) [m] in the leading wheelset's column."""
    mu = (speed - v_h) / V_S
    t = np.arange(0.0, duration + 1e-12, 1e-3)
    sol = solve_ivp(lambda _t, r: K * r * (mu + 2.0 * r ** 2 - r ** 4), (0.0, t[-1]), [x0[0]], t_eval=t,
                    rtol=1e-10, atol=1e-12)
    X = np.zeros((t.size, 4))
    X[:, 0], X[:, 1] = sol.y[0], x0[1] + OMEGA * t
    X[:, LEADING_WHEELSET] = SCALE * X[:, 0] * np.cos(X[:, 1])
    return NonlinearRun(t, X, speed)


def test_ramp_down_follows_the_stable_branch_to_the_fold():
    s = RampSettings(dv=4.0, tol=0.25, settle=4.0, window=0.5, max_time=30.0, rel_tol=0.002, floor=1e-5)
    d = ramp_down(normal_form_runner, 110.0, 60.0, np.array([1.5, 0.0, 0.0, 0.0]), s, linear_critical_speed=V_H)
    v_fold = V_H - V_S
    assert d.bracket[1] - d.bracket[0] <= 0.25 + 1e-9
    assert d.fold_speed == pytest.approx(v_fold, abs=1.0)
    assert d.nonlinear_critical_speed == d.fold_speed
    v, a = d.branch()
    assert v.size >= 7 and np.all(v >= d.fold_speed)
    far = v > v_fold + 2.0  # away from the fold, where the motion settles slowly
    mu = (v[far] - V_H) / V_S
    np.testing.assert_allclose(a[far], SCALE * np.sqrt(1.0 + np.sqrt(1.0 + mu)), rtol=0.01)


def test_nonlinear_critical_speed_is_the_lower_of_fold_and_linear():
    c = [LimitCycle(50.0, 1e-3, True, True, 6.0)]
    assert BifurcationDiagram(c, 45.0, (44.0, 45.0), linear_critical_speed=48.0).nonlinear_critical_speed == 45.0
    assert BifurcationDiagram(c, 49.0, (48.5, 49.0), linear_critical_speed=48.0).nonlinear_critical_speed == 48.0
    assert BifurcationDiagram(c, 49.0, (48.5, 49.0)).nonlinear_critical_speed == 49.0
    # no cycle reached at the start: not found where straight running was unstable, above the top where stable
    none = [LimitCycle(60.0, 1e-6, False, True, 40.0)]
    assert math.isnan(BifurcationDiagram(none, math.inf, (60.0, math.inf), 50.0).nonlinear_critical_speed)
    assert math.isinf(BifurcationDiagram(none, math.inf, (60.0, math.inf), math.inf).nonlinear_critical_speed)


def test_no_cycle_at_the_start_and_bad_settings():
    d = ramp_down(normal_form_runner, 70.0, 60.0, np.array([0.5, 0.0, 0.0, 0.0]),
                  RampSettings(settle=2.0, window=0.5, max_time=6.0, floor=1e-5))
    assert math.isinf(d.fold_speed) and not d.cycles[0].exists
    with pytest.raises(ValueError, match="v_start"):
        ramp_down(normal_form_runner, 60.0, 70.0, np.zeros(4))
    with pytest.raises(ValueError, match="window"):
        RampSettings(window=-1.0)
    with pytest.raises(ValueError, match="max_time"):
        RampSettings(settle=10.0, max_time=5.0)


def test_conicity_sweep_finds_each_fold():
    """Linear critical speed v_H(lambda) = 100 sqrt(0.15 / lambda) m/s: the folds at v_H - 20 m/s."""
    def v_h(lam):
        return 100.0 * math.sqrt(0.15 / lam)

    s = RampSettings(dv=8.0, tol=1.0, settle=3.0, window=0.5, max_time=20.0, rel_tol=0.002, floor=1e-5)
    pts = conicity_sweep((0.1, 0.3), lambda lam: (lambda v, x, T: normal_form_runner(v, x, T, v_h(lam))), v_h,
                         np.array([1.5, 0.0, 0.0, 0.0]), v_max=200.0, v_min=20.0, settings=s)
    for p in pts:
        assert p.linear_critical_speed == v_h(p.conicity)
        assert p.nonlinear_critical_speed == pytest.approx(v_h(p.conicity) - V_S, abs=1.5)
    assert start_speed(150.0, 120.0) == 120.0 and start_speed(100.0, 400.0) == pytest.approx(115.0)
    with pytest.raises(ValueError, match="conicity"):
        conicity_sweep((0.0,), None, v_h, np.zeros(4), v_max=200.0, v_min=20.0)
