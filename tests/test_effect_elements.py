"""Optional effect elements of the lumped model: each changes the force in its documented way."""
import numpy as np
import pytest

from damper_fmu import REPLAY, Simulator, defaults, make_model, simulate


def sine(amp=0.01, freq=1.0, fs=1000.0, dur=4.0):
    t = np.arange(0.0, dur, 1.0 / fs)
    w = 2 * np.pi * freq
    return t, amp * np.sin(w * t), amp * w * np.cos(w * t), -amp * w * w * np.sin(w * t)


def with_effect(**kw):
    p = defaults("lumped")
    p.update(kw)
    return p


def test_all_effects_off_is_the_base_model():
    t, x, v, _ = sine()
    sim = Simulator(make_model("lumped"))
    assert not sim.effects.active
    np.testing.assert_array_equal(simulate("lumped", t, x, v), simulate("lumped", t, x, v, params=defaults("lumped")))


def test_friction_preload_inertia_and_delay_are_their_formulas():
    t, x, v, a = sine()
    base = simulate("lumped", t, x, v)
    late = t > 0.1
    f = simulate("lumped", t, x, v, params=with_effect(friction_force=150.0))
    np.testing.assert_allclose((f - base)[late], 150.0 * np.tanh(v[late] / 5e-4), atol=1e-6)
    f = simulate("lumped", t, x, v, params=with_effect(preload_force=-250.0))
    np.testing.assert_allclose(f - base, -250.0, atol=1e-6)
    f = simulate("lumped", t, x, v, params=with_effect(inertia_mass=80.0))
    assert np.abs((f - base)[late] - 80.0 * a[late]).max() < 0.01 * 80.0 * np.abs(a).max()
    f = simulate("lumped", t, x, v, params=with_effect(time_delay=4e-3))
    np.testing.assert_allclose(f[late], np.interp(t[late] - 4e-3, t, base), atol=1e-6)


def test_free_play_force_vanishes_for_gap_over_speed_after_each_reversal():
    t, x, v, _ = sine(amp=0.01, freq=0.5, dur=6.0)
    gap = 6e-4
    f = simulate("lumped", t, x, v, params=with_effect(free_play=gap))
    reversal = np.argmin(np.abs(t - 1.5))  # x peaks at t = 0.5 s, 1.5 s, ...
    gap_open = reversal + np.argmax(np.abs(f[reversal:]) < 1e-9)
    assert t[gap_open] - t[reversal] < 0.01  # contact lost right after the reversal
    after = t[gap_open:][np.abs(f[gap_open:]) > 1e-9][0] - t[reversal]
    # near the reversal x ~ X (1 - cos(w dt)): the gap is crossed when X w^2 dt^2 / 2 = gap
    w = 2 * np.pi * 0.5
    expected = np.sqrt(2 * gap / (0.01 * w * w))
    assert after == pytest.approx(expected, rel=0.1)


def test_thermal_drift_heats_the_oil_and_lowers_the_damping():
    t, x, v, _ = sine(amp=0.01, freq=1.0, dur=20.0)
    p = with_effect(thermal_beta=0.02, thermal_capacity=500.0)
    sim = Simulator(make_model("lumped", p), input_mode=REPLAY)
    sim.initialize(x[0], v[0])
    forces, temps, power = [], [], 0.0
    for k in range(1, t.size):
        forces.append(sim.step(t[k] - t[k - 1], x[k], v[k]))
        power += forces[-1] * v[k] * (t[k] - t[k - 1])
        temps.append(sim.effects.temperature)
    temps, forces = np.array(temps), np.array(forces)
    assert temps[-1] > 25.0
    # energy balance C dT = P dt - G (T - T_ref) dt, integrated over the run
    losses = 5.0 * np.sum(temps - 20.0) * (t[1] - t[0])
    assert temps[-1] - 20.0 == pytest.approx((power - losses) / 500.0, rel=0.02)
    first, last = np.abs(forces[1000:3000]).max(), np.abs(forces[-2000:]).max()
    scale = np.exp(-0.02 * (temps[-1] - 20.0))
    assert scale < last / first < 0.95  # damping falls (force less than the damping scale: series spring)


def knee_table(**kw):
    """Symmetric damping table: 1e6 N s/m up to a knee at 10 mm/s, 1e5 N s/m beyond."""
    p = with_effect(**kw)
    for i in range(1, 15):
        vx = p[f"Fc_v{i:02d}"]
        p[f"Fc_{i:02d}"] = np.sign(vx) * (1e6 * min(abs(vx), 0.01) + 1e5 * max(abs(vx) - 0.01, 0.0))
    return p


def test_valve_lag_acts_only_beyond_the_blow_off_knee_and_leads_the_force():
    tau = 5e-3
    t, x, v, _ = sine(amp=1e-3, freq=1.0)  # 6 mm/s peak: below the knee
    d = simulate("lumped", t, x, v, params=knee_table(valve_tau=tau)) - simulate("lumped", t, x, v, params=knee_table())
    assert np.abs(d).max() < 1e-6
    t, x, v, a = sine(amp=0.01, freq=1.0)  # 63 mm/s peak: through the knee
    d = simulate("lumped", t, x, v, params=knee_table(valve_tau=tau)) - simulate("lumped", t, x, v, params=knee_table())
    beyond = (t > 1.0) & (np.abs(v) > 0.015)
    # a lead: the force correction is tau (c0 - c_knee) x'' beyond the knee
    np.testing.assert_allclose(d[beyond], tau * 9e5 * a[beyond], rtol=0.05, atol=0.02 * tau * 9e5 * np.abs(a).max())
