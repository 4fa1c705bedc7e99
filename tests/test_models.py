"""Physics of the in-process damper models against analytic and independent references."""
import numpy as np
import pytest

from damper_fmu import SolverOptions, defaults, make_model, simulate, tunable_names
from damper_fmu.parameters import FC_ABSCISSAE, check_values
from damper_fmu.tables import PwlTable


def sine(amplitude, freq, fs, duration, phase=0.0):
    t = np.arange(0.0, duration, 1.0 / fs)
    w = 2 * np.pi * freq
    return t, amplitude * np.sin(w * t + phase), amplitude * w * np.cos(w * t + phase)


def fit_harmonic(t, y, freq):
    """Least-squares complex amplitude of y at freq (y ~ Re(Y exp(i w t)))."""
    w = 2 * np.pi * freq
    a = np.column_stack([np.cos(w * t), -np.sin(w * t)])
    (re, im), *_ = np.linalg.lstsq(a, y, rcond=None)
    return re + 1j * im


def test_table_passes_through_origin_and_interpolates_linearly():
    tab = PwlTable([-2.0, -1.0, 1.0, 3.0], [-4.0, -1.0, 2.0, 4.0])
    assert tab(0.0) == 0.0
    assert tab(0.5) == pytest.approx(1.0)
    assert tab(-1.5) == pytest.approx(-2.5)
    assert tab(5.0) == pytest.approx(6.0)  # extrapolated with the last slope 1: 4 + 1 * (5 - 3)
    assert tab(-3.0) == pytest.approx(-7.0)  # extrapolated with the first slope 3
    np.testing.assert_allclose(tab.evaluate([0.5, -1.5, 5.0]), [1.0, -2.5, 6.0])


@pytest.mark.parametrize("bad", [{"M_C": -1.0}, {"k_B": 0.0}, {"Fc_01": float("nan")}, {"nope": 1.0},
                                 {"Fk_x01": 0.5}])
def test_invalid_parameters_are_rejected_with_their_name(bad):
    with pytest.raises(ValueError, match=next(iter(bad)) if "x01" not in next(iter(bad)) else "abscissae"):
        check_values("lumped", bad)


def test_preset_is_the_papers_table2():
    p = defaults("lumped")
    assert (p["M_O"], p["M_C"], p["M_P"], p["k_B"], p["c_B"]) == (16.5, 15.8, 17.3, 4.08e8, 4.17e6)
    assert p["Fc_14"] == 25e3 and p["Fc_v14"] == pytest.approx(0.1)
    assert p["Fk_10"] == 36e3 and p["Fk_x10"] == pytest.approx(2e-3)
    assert len(tunable_names("lumped")) == 29
    from damper_fmu.parameters import EFFECT_PARAMETERS
    assert all(p[e.name] == 0.0 for e in EFFECT_PARAMETERS if e.name in ("friction_force", "preload_force", "free_play", "thermal_beta", "valve_tau", "time_delay", "inertia_mass"))  # effects off


@pytest.mark.parametrize("v_amp", [0.0025, 0.004, 0.0075, 0.012, 0.03, 0.06, 0.1])
def test_quasi_static_sinusoid_reproduces_the_damping_table(v_amp):
    """Slow sinusoid: at the velocity peaks F' ~ 0, so the force peak equals Fc,O(peak velocity)."""
    f = 0.1
    t, x, v = sine(v_amp / (2 * np.pi * f), f, 1000.0, 1.0 / f + 0.5)  # v = V cos(w t)
    force = simulate("lumped", t, x, v)
    fc = make_model("lumped").fc
    period = 1.0 / f
    # velocity peaks: -V at t = T/2 and +V at t = T
    assert force[t > 0.75 * period].max() == pytest.approx(fc(v_amp), rel=5e-3)
    assert force[(t > 0.25 * period) & (t < 0.75 * period)].min() == pytest.approx(fc(-v_amp), rel=5e-3)


def linear_lumped_response(p, freq):
    """Complex force per unit stroke of the linearised lumped model (small symmetric strokes)."""
    w = 2 * np.pi * freq
    kb, cb, mp, mo, mc = p["k_B"], p["c_B"], p["M_P"], p["M_O"], p["M_C"]
    sc = p["Fc_08"] / p["Fc_v08"]
    sk = p["Fk_06"] / p["Fk_x06"]
    zb = kb + 1j * w * cb
    a = np.array([[-w**2 * mp + 1j * w * sc + zb, -1j * w * sc, 0],
                  [-1j * w * sc, -w**2 * mo + 1j * w * sc + sk, -sk],
                  [0, -sk, -w**2 * mc + sk + zb]])
    x2 = np.linalg.solve(a, np.array([zb, 0, 0]))[0]
    return zb * (1 - x2), 1.0 / (2.0 / kb + 1.0 / sk)


@pytest.mark.parametrize("freq", [5.0, 20.0])
def test_small_fast_strokes_show_the_series_stiffness(freq):
    """Symmetric tables + strokes inside the first table pieces: the model is linear, so its
    steady-state response must equal the complex frequency response of the linear 3-mass chain,
    and at high frequency the dynamic stiffness approaches the series stiffness of the chain."""
    p = defaults("lumped")
    p["Fk_05"], p["Fc_07"] = -p["Fk_06"], -p["Fc_08"]
    amp = 1e-5  # 10 um: elongations << 0.25 mm, rates << 2.5 mm/s
    t, x, v = sine(amp, freq, 20000.0, 0.6)
    force = simulate("lumped", t, x, v, params=p)
    steady = t > 0.3
    measured = 1j * fit_harmonic(t[steady], force[steady], freq) / amp  # x = Re(-i amp e^{iwt})
    expected, k_series = linear_lumped_response(p, freq)
    assert abs(measured - expected) < 2e-3 * abs(expected)
    if freq == 20.0:
        assert abs(measured) == pytest.approx(k_series, rel=0.05)


def test_step_refinement_converges():
    fs = 500.0
    t = np.arange(0.0, 1.5, 1.0 / fs)
    w1, w2 = 2 * np.pi * 2, 2 * np.pi * 7
    x = 2e-3 * (1 - np.cos(w1 * t)) + 5e-4 * (1 - np.cos(w2 * t))
    v = 2e-3 * w1 * np.sin(w1 * t) + 5e-4 * w2 * np.sin(w2 * t)
    ref = simulate("lumped", t, x, v, solver=SolverOptions(max_step=2e-6, tolerance=0.0))
    steps = [2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4]
    rms = [np.sqrt(np.mean((simulate("lumped", t, x, v, solver=SolverOptions(max_step=h, tolerance=0.0)) - ref)
                           ** 2))
           for h in steps]
    assert all(b < a for a, b in zip(rms, rms[1:])), rms
    order = np.log(rms[1] / rms[-1]) / np.log(steps[1] / steps[-1])
    assert order > 1.2, order  # second order asymptotically; table kinks slow the pre-asymptotic range
    peak = np.abs(ref).max()
    coarse = simulate("lumped", t, x, v, solver=SolverOptions(max_step=1e-3, tolerance=0.0))
    assert np.abs(coarse - ref).max() < 1e-3 * peak
    # error control: the default tolerance (1e-4 of the force scale, local) lands near the
    # converged solution, and a tighter tolerance lands nearer
    err = [np.abs(simulate("lumped", t, x, v, solver=SolverOptions(max_step=1.0, tolerance=tol)) - ref).max()
           for tol in (1e-4, 1e-6)]
    assert err[0] < 1e-3 * peak and err[1] < 0.2 * err[0], (err, peak)


@pytest.mark.parametrize("h", [1e-4, 1e-3, 1e-2])
def test_stable_at_the_stiff_preset_without_substeps(h):
    """L-stability: one implicit step per communication step, from 0.1 ms to 10 ms, stays
    bounded and accurate even though the fastest time constant is microseconds."""
    t = np.arange(0.0, 4.0, h)
    w = 2 * np.pi * 0.5
    x, v = 0.02 * np.sin(w * t), 0.02 * w * np.cos(w * t)
    fine = simulate("lumped", t, x, v, solver=SolverOptions(max_step=1e-5, tolerance=0.0))
    coarse = simulate("lumped", t, x, v, solver=SolverOptions(max_step=1.0, tolerance=0.0))
    assert np.all(np.isfinite(coarse))
    assert np.abs(coarse - fine).max() < 0.02 * np.abs(fine).max()


@pytest.mark.parametrize("freq", [0.5, 2.0, 8.0])
def test_linear_maxwell_matches_analytic_steady_state(freq):
    k, c = 1.4e7, 5e5
    t, x, v = sine(1e-3, freq, 2000.0, 3.0 + 15 * c / k)
    force = simulate("maxwell", t, x, v, params={"k_s": k, "c": c})
    w = 2 * np.pi * freq
    kdyn = k * 1j * w * c / (k + 1j * w * c)
    steady = t > 15 * c / k  # start transient decays as exp(-t k / c)
    expected = np.real(kdyn * 1e-3 * np.exp(1j * w * t[steady]) * -1j)  # x = Im(X e^{iwt})
    assert np.abs(force[steady] - expected).max() < 2e-3 * abs(kdyn) * 1e-3


@pytest.mark.parametrize("model", ["lumped", "maxwell", "maxwell_table"])
@pytest.mark.parametrize("amp,freq", [(2e-3, 2.0), (2e-2, 0.5), (2e-4, 8.0)])
def test_energy_dissipated_over_a_closed_cycle_is_positive(model, amp, freq):
    t, x, v = sine(amp, freq, 2000.0, 3.0 / freq + 1.0)
    force = simulate(model, t, x, v)
    last = t >= t[-1] - 1.0 / freq
    work = np.trapezoid(force[last], x[last])
    assert work > 0.0
    if model == "maxwell":
        k, c = defaults("maxwell")["k_s"], defaults("maxwell")["c"]
        w = 2 * np.pi * freq
        analytic = np.pi * amp**2 * c * w * k**2 / (k**2 + (c * w) ** 2)
        assert work == pytest.approx(analytic, rel=2e-2)


def test_table_maxwell_quasi_static_force_follows_its_table():
    t, x, v = sine(0.03 / (2 * np.pi * 0.1), 0.1, 1000.0, 10.5)
    force = simulate("maxwell_table", t, x, v)
    fc = make_model("maxwell_table").fc
    assert force[t > 3].max() == pytest.approx(fc(0.03), rel=5e-3)


def test_non_finite_input_is_rejected():
    t, x, v = sine(1e-3, 2.0, 1000.0, 0.1)
    x[20] = np.nan
    with pytest.raises(ValueError, match="non-finite input"):
        simulate("lumped", t, x, v)


def test_fc_abscissae_are_the_papers():
    assert np.allclose(np.array(FC_ABSCISSAE) * 1e3,
                       [-100, -30, -15, -10, -7.5, -5, -2.5, 2.5, 5, 7.5, 10, 15, 30, 100])


@pytest.mark.parametrize("stroke", [1.0, 1e-6])
def test_damped_newton_fallback_agrees_with_plain_newton(stroke):
    """Two solvers of the same stage equations (plain piecewise-linear Newton and the damped
    fallback used when Newton cycles between table pieces) give the same solution, on strokes of
    millimetres and of nanometres (``stroke`` times smaller; before, the damped solve failed on 12 of
    these 200 at 1e-6: its potential, taken from the far node of a piece, lost every digit)."""
    from damper_fmu.integrator import GAMMA

    m = make_model("lumped")
    rng = np.random.default_rng(3)
    for _ in range(200):
        yb = [stroke * rng.normal(0, 1e-3), stroke * rng.normal(0, 1e-3), stroke * rng.normal(0, 1e-3),
              stroke * rng.normal(0, 0.05), stroke * rng.normal(0, 0.05), stroke * rng.normal(0, 0.02)]
        g = GAMMA * rng.choice([1e-4, 1e-3, 5e-3])
        x1, v1 = stroke * rng.normal(0, 2e-3), stroke * rng.normal(0, 0.05)
        plain = m.stage(yb, g, x1, v1)
        damped = m._stage_damped(yb, g, x1, v1)
        np.testing.assert_allclose(damped, plain, rtol=1e-9, atol=stroke * 1e-12)


def test_table_primitive_is_the_integral():
    from scipy.integrate import quad

    tab = PwlTable([-2.0, -1.0, 1.0, 3.0], [-4.0, -1.0, 2.0, 4.0])
    for x in (-3.0, -1.5, -0.2, 0.5, 2.0, 5.0):
        assert tab.primitive(x) == pytest.approx(quad(tab, 0.0, x, points=[-2, -1, 0, 1, 3])[0], rel=1e-12)
