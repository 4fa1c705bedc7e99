"""The lab's Bouc-Wen model of benchmarks/mr_bouc_wen.py against closed forms (no shared data needed).

* alpha = 0: the model is linear, F(s) = [c1 s (k0 + c0 s) / ((c0 + c1) s + k0) + k1] X(s) (the y-equation
  alone); its steady response to a sine stroke is that transfer function's amplitude and phase.
* a constant stroke rate: z reaches sqrt(A / (gamma + beta)) (n = 2, the relative rate positive), and the
  force's non-spring part c1 y' reaches c1 (alpha z_ss + c0 v) / (c0 + c1) when k0 = 0.
* the integrator: LSODA at the default tolerance agrees with Radau at a much tighter one on a hysteretic
  run with the lab's parameters.
"""
import math

import numpy as np
import pytest

from benchmarks.mr_bouc_wen import BoucWen, current_tag, pooled, sine_hz, simulate
from tuner.metrics import error_metrics


def test_linear_case_matches_the_transfer_function():
    m = BoucWen(k0=50.0, k1=1.2, x0=0.0, alpha=0.0, beta=0.3, gamma=0.3, c0=4.0, c1=6.0)  # y's time constant 0.2 s
    f, amp = 2.0, 3.0  # Hz, mm
    w = 2 * math.pi * f
    t = np.arange(0.0, 4.0, 1e-3)
    r = simulate(m, t, amp * np.sin(w * t), amp * w * np.cos(w * t))
    s = 1j * w
    h = m.c1 * s * (m.k0 + m.c0 * s) / ((m.c0 + m.c1) * s + m.k0) + m.k1
    late = t >= 3.0  # 15 time constants: the start has decayed to 3e-7
    exact = amp * np.abs(h) * np.sin(w * t[late] + np.angle(h))
    assert np.max(np.abs(r["force"][late] - exact)) < 1e-4 * amp * abs(h)


def test_constant_rate_reaches_the_analytic_steady_state():
    m = BoucWen(k0=0.0, k1=1.2, x0=0.0, alpha=20.0, beta=0.3, gamma=0.3, c0=5.0, c1=50.0)
    v = 40.0  # mm/s: c1 v = 2000 N > alpha z_ss = 447 N, so x' - y' stays positive
    t = np.arange(0.0, 0.5, 1e-3)
    r = simulate(m, t, v * t, np.full_like(t, v))
    z_ss = math.sqrt(m.A / (m.gamma + m.beta))
    assert r["z"][-1] == pytest.approx(z_ss, rel=1e-6)
    yd = (m.alpha * z_ss + m.c0 * v) / (m.c0 + m.c1)
    assert r["force"][-1] - m.k1 * v * t[-1] == pytest.approx(m.c1 * yd, rel=1e-6)
    # and for a negative rate the loop's other branch
    r = simulate(m, t, -v * t, np.full_like(t, -v))
    assert r["z"][-1] == pytest.approx(-z_ss, rel=1e-6)


def test_lab_parameters_and_integrator():
    m = BoucWen.at_current(0.5)
    # the README's values: alpha = p4/4 + p5/2 + p6, beta = gamma = p7 exp(p8/2), c0 = p9/2 + p10, c1 = p11/2 + p12
    assert (m.alpha, m.beta, m.c0, m.c1) == pytest.approx((26.4373, 0.304428, 4.737891, 49.03548), rel=1e-5)
    assert m.beta == m.gamma and (m.A, m.n) == (300.0, 2.0)
    t = np.arange(0.0, 1.2, 1e-3)
    x, v = 2.0 * np.sin(2 * math.pi * 5 * t), 2.0 * 2 * math.pi * 5 * np.cos(2 * math.pi * 5 * t)
    a = simulate(m, t, x, v)["force"]
    b = simulate(m, t, x, v, rtol=1e-11, method="Radau")["force"]
    assert np.max(np.abs(a - b)) < 1e-3  # N, on a loop of several hundred N
    assert np.ptp(a) > 500.0


def test_names():
    assert [current_tag(c) for c in (0.25, 0.5, 0.75)] == ["0x25A", "0x5A", "0x75A"]
    assert [sine_hz(n) for n in ("25mm0x25Hz0x5A", "10mm1Hz0x75A", "2mm5Hz0x25A")] == [0.25, 1.0, 5.0]


def test_pooled_is_sample_weighted_and_the_worst_ame_is_per_test():
    a = {"test": "a", **error_metrics([100.0, -100.0], [90.0, -90.0]).to_dict()}  # 10 N, 10 % of peak
    b = {"test": "b", **error_metrics([50.0, -50.0, 50.0, -50.0], [30.0, -30.0, 30.0, -30.0]).to_dict()}  # 20 N, 40 %
    p = pooled([a, b])
    assert p["rmse_n"] == pytest.approx(math.sqrt((2 * 100 + 4 * 400) / 6))
    assert (p["worst_ame_pct_of_peak"], p["worst_test"]) == (pytest.approx(40.0), "b")
