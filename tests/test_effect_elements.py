"""Optional effect elements of the lumped model (and the form elements of both effect models): each
changes the force in its documented way."""
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


@pytest.mark.parametrize("h", [1e-3, 0.5])
def test_the_thermal_balance_is_its_closed_form_at_any_step(h):
    """At a constant power P the balance C dT/dt = P - G (T - T_ref) gives T = T_ref + P / G (1 - exp(-t G / C)):
    so the internal balance, at steps of 1 ms and of 0.5 s with the extremes of its typical C and G (time constant
    0.1 s; the explicit step it replaced diverged beyond 0.2 s), and at a damper 1e5 times smaller (C and G
    scaled with it: the same temperatures)."""
    from damper_fmu.effects import Effects

    for c, g, power in ((100.0, 1000.0, 2.0e3), (1e-3, 1e-2, 2.0e-2)):
        e = Effects({"thermal_beta": 0.01, "thermal_capacity": c, "thermal_conductance": g})
        e.initialize(0.0, 0.0)
        for k in range(1, 9):
            e.output(power / 0.1, h, 0.0, 0.1, 0.0, 0.0, None)  # f_model [N] x v_eff [m/s] = power [W]
            expected = 20.0 + power / g * (1.0 - np.exp(-k * h * g / c))
            assert e.temperature == pytest.approx(expected, rel=1e-12), (c, k)


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


# -- form elements (damper_fmu.effects: hysteresis, bypass), lumped and two-chamber -------------------------

def triangle(amp, quarter_s=1.0, fs=1000.0, quarters=9):
    """Triangle stroke 0 -> amp -> -amp -> ... with its reversals on samples (every ``quarter_s`` odd
    multiple); returns t, x, v and the sample indices of the reversals."""
    n = int(round(quarter_s * fs))
    k = np.arange(quarters * n + 1)
    ph = k % (4 * n)
    x = amp * np.where(ph < n, ph / n, np.where(ph < 3 * n, (2 * n - ph) / n, (ph - 4 * n) / n))
    t = k / fs
    return t, x, np.gradient(x, t), np.arange(n, quarters * n + 1, 2 * n)


def dahl(x, reversals, fh, xh):
    """Analytic Dahl force along a piecewise-monotone stroke x from z = 0 at x[0]: after each start
    or reversal at x_r (force z_r), z(x) = s F_h + (z_r - s F_h) exp(-|x - x_r| / x_h), s the sign of
    the motion on that leg."""
    z = np.empty_like(x)
    starts = [0, *reversals]
    ends = [*reversals, x.size - 1]
    z_r = 0.0
    for a, b in zip(starts, ends):
        s = np.sign(x[b] - x[a])
        leg = slice(a, b + 1)
        z[leg] = s * fh + (z_r - s * fh) * np.exp(-np.abs(x[leg] - x[a]) / xh)
        z_r = z[b]
    return z


@pytest.mark.parametrize("kind", ["lumped", "twochamber"])
def test_hysteresis_is_the_analytic_dahl_loop_and_dissipates_4_fh_a_per_cycle(kind):
    """On a slow 4 mm triangle the element alone (force with it minus without it: the element is in
    parallel and feeds nothing back into the model) is z(x) of the analytic Dahl solution after every
    reversal; the loop's energy per cycle, oint z dx, is 4 F_h (A - x_h) (the two exponential corners
    each cost 2 F_h x_h), which approaches 4 F_h A for A >> x_h.

    Tolerance 1e-6 F_h on z: per step the element applies the exact solution over the monotone
    increment, and exp(-a) exp(-b) = exp(-(a + b)), so only rounding separates it from the closed form."""
    amp, fh = 4e-3, 500.0
    t, x, v, rev = triangle(amp)
    base = simulate(kind, t, x, v, params=defaults(kind))
    for xh in (5e-4, 8e-5):
        p = {**defaults(kind), "hysteresis_force": fh, "hysteresis_displacement": xh}
        z = simulate(kind, t, x, v, params=p) - base
        np.testing.assert_allclose(z, dahl(x, rev, fh, xh), rtol=0, atol=1e-6 * fh)
        assert z[rev[0]] == pytest.approx(fh * (1.0 - np.exp(-amp / xh)), abs=1e-6 * fh)  # the virgin leg
        cycle = slice(rev[0], rev[2] + 1)  # A -> -A -> A: a closed, steady loop
        energy = np.trapezoid(z[cycle], x[cycle])
        assert energy == pytest.approx(4.0 * fh * (amp - xh), rel=1e-4)
        assert 1.0 - energy / (4.0 * fh * amp) == pytest.approx(xh / amp, rel=1e-2)  # -> 0 as x_h / A -> 0
    assert energy / (4.0 * fh * amp) > 0.97  # A = 50 x_h


@pytest.mark.parametrize("direction, v_b", [(0.0, 0.0), (1.0, 0.0), (-1.0, 1e-3)])
@pytest.mark.parametrize("kind", ["lumped", "twochamber"])
def test_bypass_scales_the_force_by_1_minus_r_deep_in_the_groove_and_not_outside(kind, direction, v_b):
    """A slow sine (10 mm, 0.02 Hz: 1.3 mm/s at most) through a groove of 4 mm around +1 mm with 0.2 mm
    edges, ratio 0.5: where the stroke is at least 5 edge lengths inside the groove the force is
    (1 - r) times the force without the groove, and where it is 10 edge lengths beyond its ends it is
    the force without it. Only while the stroke moves faster than 30 % of its peak (the force ratio
    near a reversal is 0 / 0). In the two-chamber model the gas spring k_gas (x - x_0) is not part of
    the damping characteristic: subtracted from both forces first.

    Tolerance 2e-3 on the ratio, for what the series elements change (silent blocks and the Fk
    elastic element of the lumped model; the mounts and the chamber compliance of the two-chamber
    model; stiffness k ~ 1.5e7 N/m in series with a damping slope c ~ 1e6 N s/m): the damper's own
    velocity differs from the stroke's by dF/dt / k. (a) After each groove end the force settles to
    its new level with tau = c / k ~ 60 ms, i.e. within ~0.1 mm of stroke at 1.3 mm/s: 1 mm (5 edge
    lengths) inside, that transient is below 1e-5. (b) The slow sine's acceleration keeps loading the
    springs, differently with and without the groove (force halved): a relative velocity error of
    c a / (k v) ~ 1e-3 at the groove, a few 1e-4 in the ratio. (c) The tanh tail inside, r (1 - tanh 5)
    ~ 5e-5. Measured: about 5e-4 inside, below 1e-7 outside.

    With a direction (+1: extension only, -1: compression only) the ratio is 1 in the other direction,
    and with a fade speed v_b it is 1 - r / (1 + (v / v_b)^2) at the stroke velocity v."""
    amp, f, r, c, w, e = 10e-3, 0.02, 0.5, 1e-3, 4e-3, 2e-4
    t = np.arange(0.0, 1.0 / f, 2e-3)
    om = 2 * np.pi * f
    x, v = -amp * np.cos(om * t), amp * om * np.sin(om * t)
    base = defaults(kind)
    p = {**base, "bypass_ratio": r, "bypass_center": c, "bypass_width": w, "bypass_edge": e,
         "bypass_direction": direction, "bypass_velocity": v_b}
    gas = base["k_gas"] * (x - x[0]) if kind == "twochamber" else 0.0
    with_groove = simulate(kind, t, x, v, params=p) - gas
    without = simulate(kind, t, x, v, params=base) - gas
    moving = np.abs(v) > 0.3 * amp * om
    inside = moving & (np.abs(x - c) <= w / 2 - 5 * e)
    outside = moving & (np.abs(x - c) >= w / 2 + 10 * e)
    assert inside.sum() > 100 and outside.sum() > 1000  # both directions of motion through both
    assert np.all(np.abs(without[inside]) > 500.0)  # the damping force, not a residue
    side = np.where(direction * v < 0.0, 0.0, 1.0)
    expected = 1.0 - r * side / (1.0 + (v / v_b) ** 2 if v_b else 1.0)
    assert np.ptp(expected[inside]) > (0.15 if direction or v_b else -1)  # the direction and fade are tested
    np.testing.assert_allclose(with_groove[inside] / without[inside], expected[inside], rtol=0, atol=2e-3)
    np.testing.assert_allclose(with_groove[outside] / without[outside], 1.0, rtol=0, atol=2e-3)
