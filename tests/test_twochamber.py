"""The two-chamber (twin-tube) model against physics and an independent implementation."""
import ctypes

import numpy as np
import pytest

from damper_fmu import SolverOptions, defaults, make_model, models, native, simulate
from damper_fmu.models import CHECK_SHARE

needs_c = pytest.mark.skipif(not native.available(), reason=f"C kernel not available: {native.reason()}")


def multisine(t):
    """Railway-like stroke [m] and its exact velocity [m/s]: 0.8, 4.3 and 11 Hz."""
    parts = ((0.01, 0.8, 0.0), (0.002, 4.3, 1.0), (0.0005, 11.0, 0.0))
    x = sum(a * np.sin(2 * np.pi * f * t + ph) for a, f, ph in parts)
    v = sum(a * 2 * np.pi * f * np.cos(2 * np.pi * f * t + ph) for a, f, ph in parts)
    return x, v


@pytest.mark.parametrize("backend", ["python", pytest.param("native", marks=needs_c)])
@pytest.mark.parametrize("v", [-0.08, -0.004, 0.02, 0.08])
def test_steady_force_is_the_damping_table_plus_the_check_valve_and_gas_spring(backend, v):
    """At constant velocity the valves carry the flows of a twin-tube damper: rebound through the
    piston valve (Fc,O) with the compression chamber refilled through the intake check, compression
    through the foot valve (Fc,O by construction) with the rebound chamber refilled through the
    piston check. Analytic: F = Fc(v) + c_chk (1 - a)^2 v (rebound), Fc(v) + c_chk v (compression),
    plus the gas spring k_gas (x - x0)."""
    m = make_model("twochamber")
    p = m.params
    t = np.arange(0.0, 2.0, 1e-3)  # the valves' transients decay with time constants of ~0.1 s
    f = simulate(m, t, v * t, np.full(t.size, v), backend=backend)
    a, chk = p["area_ratio"], check_slope(p)
    expected = m.fc(v) + chk * ((1 - a) ** 2 * v if v > 0 else v) + p["k_gas"] * v * t[-1]
    assert abs(f[-1] - expected) <= 1e-6 * abs(expected)


def check_slope(p: dict) -> float:
    """The check valves' slope [N s/m] of the two-chamber parameters ``p``: ``check_damping``, or when it is 0
    CHECK_SHARE of the damping table's largest |ordinate| over its largest |rate abscissa| (its definition)."""
    if p["check_damping"]:
        return p["check_damping"]
    fs = [abs(v) for k, v in p.items() if k.startswith("Fc_") and k[3:].isdigit()]
    xs = [abs(v) for k, v in p.items() if k.startswith("Fc_v")]
    return CHECK_SHARE * max(fs) / max(xs)


def test_the_check_valves_follow_the_table_unless_set():
    """check_damping 0 (the default): the check valves' slope is CHECK_SHARE of the table's mean slope to its last
    rate (1.01e3 N s/m on the preset), s times larger on a table s times stronger; a value given is used as it is,
    and a negative one refused."""
    p = defaults("twochamber")
    assert make_model("twochamber").check_damping == pytest.approx(CHECK_SHARE * 25.29e3 / 0.1)
    strong = {k: 7.0 * v if k.startswith("Fc_") and k[3:].isdigit() else v for k, v in p.items()}
    assert make_model("twochamber", strong).check_damping == pytest.approx(7.0 * CHECK_SHARE * 25.29e3 / 0.1)
    assert make_model("twochamber", {"check_damping": 1e3}).check_damping == 1e3
    with pytest.raises(ValueError, match="check_damping .* must not be negative"):
        make_model("twochamber", {"check_damping": -1.0})


def _euler_reference(t_fine, x_fine, p):
    """Force of tests/reference/twochamber_euler.c (implicit Euler, stiffness frozen over a step, the mount
    rate from differences: written separately from damper_fmu) on a finely sampled stroke."""
    from damper_fmu.native import compile_library
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    lib = ctypes.CDLL(str(compile_library(root / "tests" / "reference" / "twochamber_euler.c", "reference_twochamber")))
    d = ctypes.POINTER(ctypes.c_double)
    lib.simulate_tc.argtypes = [ctypes.c_int, d, ctypes.c_double, ctypes.c_int, ctypes.c_int, d, d, ctypes.c_int, d, d,
                                *[ctypes.c_double] * 11, d, ctypes.POINTER(ctypes.c_int)]
    xs = np.array([p[f"Fc_v{i:02d}"] for i in range(1, 29)])
    fs = np.array([p[f"Fc_{i:02d}"] for i in range(1, 29)])
    a, chk = p["area_ratio"], check_slope(p)
    # the valve tables as the prototype (docs/twin-tube-form-study.md) built them
    fpx = np.ascontiguousarray(np.concatenate([[-1.0, 0.0], xs[xs > 0]]))
    fpf = np.ascontiguousarray(np.concatenate([[-chk, 0.0], fs[xs > 0]]))
    ffx = np.ascontiguousarray(np.concatenate([[-1.0, 0.0], (-(1 - a) * xs[xs < 0])[::-1]]))
    fff = np.ascontiguousarray(np.concatenate([[-chk, 0.0], (-fs[xs < 0] / (1 - a))[::-1]]))
    x = np.ascontiguousarray(x_fine)
    out = np.empty_like(x)
    fails = ctypes.c_int(0)
    ptr = lambda arr: arr.ctypes.data_as(d)  # noqa: E731
    rc = lib.simulate_tc(x.size, ptr(x), float(t_fine[1] - t_fine[0]), 1, fpx.size, ptr(fpx), ptr(fpf), ffx.size,
                         ptr(ffx), ptr(fff), p["k_R"], p["k_C"], a, p["k_M"], p["c_M"], p["L_R"], p["L_C"], p["air"],
                         p["f_res"], 0.0, 5e-4, ptr(out), ctypes.byref(fails))
    assert rc == 0 and fails.value == 0
    return out + p["k_gas"] * (x - x[0])


@needs_c
def test_an_independent_first_order_implementation_converges_to_it():
    """tests/reference/twochamber_euler.c (implicit Euler) approaches the SDIRK2 result at first order as its
    step shrinks; at 25 us it is within 0.15 % of the peak force."""
    p = defaults("twochamber")
    t = np.arange(0.0, 3.0, 1e-3)
    x, v = multisine(t)
    ref = simulate("twochamber", t, x, v, solver=SolverOptions(tolerance=0.0, max_step=2e-5))
    errors = []
    for k in (10, 40):
        tf = np.arange((t.size - 1) * k + 1) * (1e-3 / k)
        errors.append(np.abs(_euler_reference(tf, multisine(tf)[0], p)[::k] - ref).max())
    assert errors[1] < errors[0] / 3.0, errors
    assert errors[1] < 1.5e-3 * np.abs(ref).max(), errors


@needs_c
def test_fixed_steps_converge_at_second_order_and_the_default_tolerance_is_accurate():
    t = np.arange(0.0, 3.0, 1e-3)
    x, v = multisine(t)
    ref = simulate("twochamber", t, x, v, solver=SolverOptions(tolerance=0.0, max_step=5e-6))
    rms = [np.sqrt(np.mean((simulate("twochamber", t, x, v, solver=SolverOptions(tolerance=0.0, max_step=h)) - ref)
                           ** 2))
           for h in (1e-4, 5e-5, 2.5e-5)]
    assert rms[0] / rms[1] > 3.0 and rms[1] / rms[2] > 3.0, rms
    assert np.abs(simulate("twochamber", t, x, v) - ref).max() < 1e-4 * np.abs(ref).max()


def test_starts_with_unloaded_chambers_and_reports_its_chamber_forces():
    """The start state has the chambers at reservoir pressure and the piston moving with the
    actuator: the force is the seal friction at that speed alone (the gas spring is zero there)."""
    m = make_model("twochamber", {"friction_force": 100.0})
    y = m.initial_state(0.012, 0.05)
    assert m.force(y, 0.012, 0.05) == pytest.approx(100.0 * np.tanh(0.05 / 5e-4))
    assert m.force(y, 0.014, 0.05) == pytest.approx(100.0 * np.tanh(0.05 / 5e-4) + m.params["k_gas"] * 0.002)
    d = m.diagnostics(y, 0.012, 0.05)
    assert set(d) == {"mount_elongation", "rebound_chamber_force", "compression_chamber_force",
                      "piston_valve_rate", "foot_valve_rate"}


def unlike_the_preset():
    """A two-chamber damper unlike the preset: other chambers, mounts, air and gas, and a damping
    table scaled differently per side (asymmetric, softer in compression)."""
    p = defaults("twochamber")
    p.update({"k_M": 6.0e7, "c_M": 2.0e4, "k_R": 1.6e7, "k_C": 1.1e8, "area_ratio": 0.45, "L_R": 0.15, "L_C": 0.12,
              "air": 1.5, "f_res": 1500.0, "k_gas": 900.0})
    for i in range(1, 29):
        p[f"Fc_{i:02d}"] *= 0.7 if p[f"Fc_v{i:02d}"] < 0 else 1.1
    return p


@pytest.mark.slow
@needs_c
def test_tuner_fits_a_two_chamber_damper_unlike_the_preset_to_the_noise_floor(tmp_path):
    """In-class data (the two-chamber model, parameters far from the preset, 20 N noise at 1 kHz):
    the product fit (``tuner.identification.fit``, data-driven start, no Firefly iteration, the
    converged local solve) reaches 1.2 x the in-band noise and finds the chamber parameters."""
    from campaign.synthetic import write_model_dataset
    from tuner.data.preprocess import Resampler
    from tuner.data.reading import load_dataset
    from tuner.identification.fit import FitSettings, fit

    truth = unlike_the_preset()
    path = write_model_dataset(tmp_path / "data", "twochamber", truth, seed=3, durations=(6.0, 6.0, 4.0),
                               roles=("identification", "identification", "validation"), noise_n=20.0)
    tests = load_dataset(path)
    settings = FitSettings(models=("twochamber",), population=20, iterations=0, workers=2, engine="native")
    res = fit([t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"],
              settings, log=lambda m: None)
    metrics = res.metrics
    band_noise = Resampler.design(1000.0, 200.0).apply(np.random.default_rng(0).normal(0.0, 20.0, 200_000)).std()
    hist = res.histories["twochamber"]
    assert hist["converged"]
    assert hist["identification_rmse_n"] <= 1.2 * band_noise, (hist["identification_rmse_n"], band_noise)
    held_out = [t["models"]["twochamber"]["rmse"] for t in metrics["tests"].values() if t["role"] == "validation"]
    assert max(held_out) <= 1.3 * band_noise, (held_out, band_noise)
    est = res.params["twochamber"]["values"]
    for name, tol in (("area_ratio", 0.05), ("k_R", 0.1), ("k_C", 0.1)):
        assert abs(est[name] / truth[name] - 1.0) <= tol, (name, est[name], truth[name])


@pytest.mark.parametrize("v", [-0.02, 0.01])
def test_seal_friction_acts_inside_the_mounts_and_adds_at_steady_speed(v):
    """At constant speed the seal friction (at the piston, inside the mounts) adds Ff tanh(v / v_eps)
    to the steady force."""
    p = {**defaults("twochamber"), "friction_force": 150.0}
    t = np.arange(0.0, 2.0, 1e-3)
    base = simulate("twochamber", t, v * t, np.full(t.size, v))
    with_f = simulate("twochamber", t, v * t, np.full(t.size, v), params=p)
    assert abs(with_f[-1] - base[-1] - 150.0 * np.tanh(v / p["friction_velocity"])) < 1e-6 * abs(base[-1])


@needs_c
def test_a_steep_seal_friction_at_fixed_steps_is_solved_the_same_in_c_and_python(monkeypatch):
    """300 N of seal friction (tanh over 0.5 mm/s) on the bundled data's first test at the tuner's
    fixed 1 ms steps: at the start the joint Newton iteration stalls and the nested solve (safeguarded
    Newton on the mount balance) takes over, in C as in Python."""
    from dataclasses import replace
    from pathlib import Path

    import damper_fmu.models as models
    from tuner.data.preprocess import prepare
    from tuner.data.reading import load_dataset
    from tuner.identification.engine import simulate_signals
    from tuner.identification.problem import to_signals

    calls = []
    nested = models.TwoChamberModel._stage_nested
    monkeypatch.setattr(models.TwoChamberModel, "_stage_nested", lambda self, *a: calls.append(1) or nested(self, *a))
    test = load_dataset(Path(__file__).resolve().parents[1] / "data" / "default")[0]
    s = to_signals(prepare(test, 200.0), 0.5)
    n = 60
    s = replace(s, time=s.time[:n], stroke=s.stroke[:n], stroke_velocity=s.stroke_velocity[:n], force=s.force[:n],
                mask=s.mask[:n], temperature=None)
    # the check valves at 1e3 N s/m, the preset's until it followed the table (1.01e3): the case that stalls
    p = {**defaults("twochamber"), "friction_force": 300.0, "check_damping": 1e3}
    py = simulate_signals("twochamber", p, s, engine="inprocess")
    assert calls, "the case no longer exercises the nested solve"
    c = simulate_signals("twochamber", p, s, engine="native")
    assert np.abs(py - c).max() <= 1e-9 * np.abs(py).max()


@needs_c
def test_free_play_at_fixed_steps_is_accurate_and_converges():
    """A 0.2 mm free play under a 3 Hz, 10 mm sine at the tuner's fixed 1 ms and at 0.5 ms steps: C
    equals Python, the force is within 0.2 % of its peak of the error-controlled one at 1 ms (the
    dead band is smoothed over 10 um, resolved at these speeds; a kinematic play on the stroke was
    820 N rms off) and closer at 0.5 ms."""
    t = np.arange(0.0, 1.0, 1e-3)
    x, v = 0.01 * np.sin(2 * np.pi * 3 * t), 0.01 * 2 * np.pi * 3 * np.cos(2 * np.pi * 3 * t)
    p = {**defaults("twochamber"), "free_play": 2e-4}
    ref = simulate("twochamber", t, x, v, params=p, solver=SolverOptions(tolerance=1e-7, max_step=1e-4))
    rms = []
    for h in (1e-3, 5e-4):
        c = simulate("twochamber", t, x, v, params=p, solver=SolverOptions(tolerance=0.0, max_step=h))
        py = simulate("twochamber", t, x, v, params=p, solver=SolverOptions(tolerance=0.0, max_step=h),
                      backend="python")
        assert np.abs(c - py).max() <= 1e-9 * np.abs(py).max()
        rms.append(np.sqrt(np.mean((c - ref) ** 2)))
    assert rms[0] < 2e-3 * np.abs(ref).max() and rms[1] < rms[0], rms


@pytest.mark.parametrize("mount_scale", [1.0, 10.0])
def test_a_free_plays_crossings_are_solved_by_the_joint_newton_iteration(monkeypatch, mount_scale):
    """A 0.5 mm free play under a 3 Hz, 10 mm sine at the tuner's fixed 1 ms steps, soft and stiff mounts: the
    stage's first guess linearises the mount with its dead band at the last piston velocity, so no crossing
    needs the nested fallback (with the engaged mount's guess, far off inside the gap, 1 and 8 crossings did,
    and the C kernel spent 10 x the time of a simulation without the gap in line searches and fallbacks)."""
    calls = []
    nested = models.TwoChamberModel._stage_nested
    monkeypatch.setattr(models.TwoChamberModel, "_stage_nested", lambda self, *a: calls.append(1) or nested(self, *a))
    t = np.arange(0.0, 1.0, 1e-3)
    x, v = 0.01 * np.sin(2 * np.pi * 3 * t), 0.01 * 2 * np.pi * 3 * np.cos(2 * np.pi * 3 * t)
    p = {**defaults("twochamber"), "free_play": 5e-4, "k_M": mount_scale * defaults("twochamber")["k_M"]}
    f = simulate("twochamber", t, x, v, params=p, solver=SolverOptions(tolerance=0.0, max_step=1e-3), backend="python")
    assert np.isfinite(f).all()
    assert not calls


@needs_c
def test_free_play_is_a_dead_band_in_the_mount_the_force_vanishes_for_gap_over_speed_at_each_reversal():
    """A triangle stroke at 50 mm/s: with a 0.5 mm free play the mount carries no force while the
    actuator crosses the gap, so after each reversal the force (gas spring off) stays near zero for
    about gap / speed = 10 ms; without play it crosses zero at once. As the gap tends to zero the model
    tends to the one without play."""
    v0, amp, gap = 0.05, 0.01, 5e-4
    t = np.arange(0.0, 1.6, 1e-4)
    period = 4 * amp / v0
    ph = (t / period) % 1.0
    x = amp * np.where(ph < 0.5, -1 + 4 * ph, 3 - 4 * ph)
    v = np.where(ph < 0.5, v0, -v0)
    base = {**defaults("twochamber"), "k_gas": 0.0}
    f0 = simulate("twochamber", t, x, v, params=base, solver=SolverOptions(tolerance=1e-7, max_step=1e-4))
    fg = simulate("twochamber", t, x, v, params={**base, "free_play": gap},
                  solver=SolverOptions(tolerance=1e-7, max_step=1e-4))
    peak = np.abs(f0).max()
    reversals = [k for k in range(1, t.size) if v[k] != v[k - 1] and t[k] > period]
    assert len(reversals) >= 2
    for k in reversals:
        window = slice(k, k + int(0.03 / 1e-4))
        quiet_gap = np.count_nonzero(np.abs(fg[window]) < 0.01 * peak) * 1e-4
        quiet_none = np.count_nonzero(np.abs(f0[window]) < 0.01 * peak) * 1e-4
        assert 0.7 * gap / v0 <= quiet_gap <= 1.2 * gap / v0, (t[k], quiet_gap)
        assert quiet_none <= 0.1 * gap / v0, (t[k], quiet_none)
    tiny = simulate("twochamber", t, x, v, params={**base, "free_play": 1e-9},
                    solver=SolverOptions(tolerance=1e-7, max_step=1e-4))
    assert np.abs(tiny - f0).max() <= 1e-3 * peak


def test_the_stage_system_solved_by_its_pattern_equals_a_general_solve():
    """The two-chamber stage's Newton system (rows 3 and 4 eliminated by their unit pivots, a 3 x 3 left) against
    numpy's LU solve, on random Jacobians of its pattern spanning the magnitudes a stage meets (stiffnesses times
    the stage's step, damping slopes)."""
    rng = np.random.default_rng(7)
    for _ in range(200):
        g = 10 ** rng.uniform(-5, -3)
        k0, k3 = 10 ** rng.uniform(6, 9, size=2)  # chamber stiffnesses [N/m]
        sp, sf = 10 ** rng.uniform(3, 6, size=2)  # valve damping slopes [N s/m]
        a = rng.uniform(0.1, 0.9)
        jac = [[-g * k0 * rng.uniform(0.5, 2), g * k0, 0.0, 1.0 - rng.uniform(0, 0.2), 0.0],
               [g * k3 * rng.uniform(0.5, 2), -g * k3 * a, g * k3, 0.0, 1.0 - rng.uniform(0, 0.2)],
               [0.0, -sp, 0.0, 1.0, -a],
               [0.0, 0.0, -sf, 0.0, 1.0],
               [10 ** rng.uniform(2, 6), 0.0, 0.0, 1.0, -1.0]]
        r = list(rng.normal(size=5) * 10 ** rng.uniform(-3, 3, size=5))
        d = models._solve_stage(jac, r)
        ref = np.linalg.solve(np.array(jac), np.array(r))
        assert d is not None
        np.testing.assert_allclose(np.array(jac) @ np.array(d), r, rtol=0, atol=1e-9 * np.abs(np.array(jac)).max()
                                   * np.abs(ref).max())
        np.testing.assert_allclose(d, ref, rtol=1e-7, atol=1e-12 * np.abs(ref).max())
