"""The C kernel equals the Python reference (same algorithm, operation for operation)."""
import numpy as np
import pytest

from damper_fmu import EXTRAPOLATE, REPLAY, SolverOptions, defaults, simulate
from damper_fmu import native
from damper_fmu.parameters import MODEL_PARAMETERS, check_values

pytestmark = pytest.mark.skipif(not native.available(), reason=f"C kernel not available: {native.reason()}")


def random_params(kind, rng):
    """A random, valid parameter set of ``kind``: tables scaled per side and piece (monotone kept)."""
    p = defaults(kind)
    for prefix in ("Fk", "Fc"):
        n = sum(1 for k in p if k.startswith(f"{prefix}_{'x' if prefix == 'Fk' else 'v'}"))
        if not n:
            continue
        xs = np.array([p[f"{prefix}_{'x' if prefix == 'Fk' else 'v'}{i:02d}"] for i in range(1, n + 1)])
        fs = np.array([p[f"{prefix}_{i:02d}"] for i in range(1, n + 1)])
        # cumulative positive increments outward from zero, scaled at random
        neg, pos = xs < 0, xs > 0
        for side in (neg, pos):
            f = fs[side]
            order = np.argsort(np.abs(xs[side]))
            inc = np.diff(np.concatenate([[0.0], np.abs(f[order])])) * rng.uniform(0.5, 1.6, order.size)
            f_new = np.empty_like(f)
            f_new[order] = np.sign(f[order]) * np.cumsum(inc)
            fs[side] = f_new
        for i in range(n):
            p[f"{prefix}_{i + 1:02d}"] = float(fs[i])
    if kind == "lumped":
        for name in ("M_C", "M_O", "M_P"):
            p[name] = rng.uniform(2.0, 20.0)
        p["k_B"] = 10 ** rng.uniform(6, 9)
        p["c_B"] = 10 ** rng.uniform(3, 6.7)
    elif kind == "twochamber":
        p["k_M"], p["c_M"] = 10 ** rng.uniform(7, 8.5), 10 ** rng.uniform(3.5, 5)
        p["k_R"], p["k_C"] = 10 ** rng.uniform(7, 8), 10 ** rng.uniform(7, 8.3)
        p["area_ratio"] = rng.uniform(0.2, 0.6)
        p["L_R"], p["L_C"] = rng.uniform(0.08, 0.5), rng.uniform(0.08, 0.5)
        p["air"], p["f_res"], p["k_gas"] = rng.uniform(0.0, 5.0), 10 ** rng.uniform(2.5, 3.5), rng.uniform(0, 3e3)
    else:
        p["k_s"] = 10 ** rng.uniform(6, 8)
        if kind == "maxwell":
            p["c"] = 10 ** rng.uniform(4, 6)
    return check_values(kind, p)


EFFECTS = [{}, {"friction_force": 120.0}, {"preload_force": -300.0}, {"free_play": 4e-4},
           {"thermal_beta": 0.02, "thermal_capacity": 300.0}, {"valve_tau": 4e-3}, {"time_delay": 3.3e-3},
           {"inertia_mass": 60.0},
           {"friction_force": 80.0, "free_play": 2e-4, "time_delay": 2e-3, "valve_tau": 2e-3, "inertia_mass": 20.0},
           # the form elements: pre-yield hysteresis, bypass groove, and both with the free play (which gates
           # the hysteresis force and moves the stroke both see) and the thermal drift (which the bypass scales)
           {"hysteresis_force": 500.0, "hysteresis_displacement": 5e-4},
           {"bypass_ratio": 0.5, "bypass_center": 1e-3, "bypass_width": 4e-3},
           {"hysteresis_force": 300.0, "hysteresis_displacement": 2e-4, "bypass_ratio": 0.7, "bypass_center": -2e-3,
            "bypass_width": 6e-3, "bypass_edge": 5e-4, "free_play": 3e-4, "thermal_beta": 0.02,
            "thermal_capacity": 300.0},
           # a groove in extension only, fading with speed; one in compression only
           {"bypass_ratio": 0.6, "bypass_center": 0.0, "bypass_width": 5e-3, "bypass_direction": 1.0,
            "bypass_velocity": 0.01},
           {"bypass_ratio": 0.4, "bypass_center": 1e-3, "bypass_width": 8e-3, "bypass_direction": -1.0}]


def random_stroke(rng, fs=500.0, dur=1.2):
    t = np.arange(0.0, dur, 1.0 / fs) + rng.uniform(0, 0.5)
    x = np.zeros_like(t)
    v = np.zeros_like(t)
    for _ in range(3):
        a, f, ph = rng.uniform(2e-4, 1e-2), rng.uniform(0.3, 12.0), rng.uniform(0, 2 * np.pi)
        x += a * np.sin(2 * np.pi * f * t + ph)
        v += a * 2 * np.pi * f * np.cos(2 * np.pi * f * t + ph)
    v += rng.normal(0, 1e-4, t.size)  # a measured velocity is not exactly the stroke's derivative
    return t, x, v


def assert_equal_forces(a, b):
    scale = max(np.abs(b).max(), 1.0)
    assert np.abs(a - b).max() <= 1e-9 * scale, (np.abs(a - b).max(), scale)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("kind", ["lumped", "maxwell", "maxwell_table"])
def test_kernel_equals_python_reference(kind, seed):
    rng = np.random.default_rng(100 + seed)
    p = random_params(kind, rng)
    t, x, v = random_stroke(rng)
    for mode in (REPLAY, EXTRAPOLATE):
        for tol, max_step in ((1e-4, 1e-3), (0.0, 7e-4), (1e-6, 0.01)):
            kw = dict(params=p, solver=SolverOptions(input_mode=mode, tolerance=tol, max_step=max_step))
            assert_equal_forces(simulate(kind, t, x, v, backend="native", **kw),
                                simulate(kind, t, x, v, backend="python", **kw))


@pytest.mark.parametrize("seed", range(2))
def test_two_chamber_kernel_equals_python_reference(seed):
    rng = np.random.default_rng(300 + seed)
    p = random_params("twochamber", rng)
    t, x, v = random_stroke(rng)
    for mode, tol, max_step in ((REPLAY, 1e-4, 1e-3), (EXTRAPOLATE, 1e-6, 0.01)):
        kw = dict(params=p, solver=SolverOptions(input_mode=mode, tolerance=tol, max_step=max_step))
        assert_equal_forces(simulate("twochamber", t, x, v, backend="native", **kw),
                            simulate("twochamber", t, x, v, backend="python", **kw))


@pytest.mark.parametrize("effect", [1, 3, 4, 8, 9, 10, 11])
def test_two_chamber_kernel_equals_python_reference_with_effects(effect):
    """Friction inside the mounts, free play, thermal drift on the valves, and friction, free play,
    delay, valve lag and inertia together, the hysteresis and bypass form elements alone and with the
    mount's free play and the thermal drift; error-controlled and at the tuner's fixed 1 ms steps
    (where a failed stage solve is retried as two half steps)."""
    rng = np.random.default_rng(50 + effect)
    p = random_params("twochamber", rng)
    p.update(EFFECTS[effect])
    t, x, v = random_stroke(rng)
    for mode, temperature, tol in ((REPLAY, None, 1e-4), (EXTRAPOLATE, 20.0 + 15.0 * (t - t[0]), 1e-4),
                                   (REPLAY, None, 0.0)):
        kw = dict(params=p, temperature=temperature, solver=SolverOptions(input_mode=mode, tolerance=tol))
        assert_equal_forces(simulate("twochamber", t, x, v, backend="native", **kw),
                            simulate("twochamber", t, x, v, backend="python", **kw))


@pytest.mark.parametrize("effect", range(len(EFFECTS)))
def test_kernel_equals_python_reference_with_effects(effect):
    rng = np.random.default_rng(7 + effect)
    p = random_params("lumped", rng)
    p.update(EFFECTS[effect])
    t, x, v = random_stroke(rng)
    temp = 20.0 + 15.0 * (t - t[0])
    for mode in (REPLAY, EXTRAPOLATE):
        for temperature in (None, temp):
            kw = dict(params=p, temperature=temperature, solver=SolverOptions(input_mode=mode))
            assert_equal_forces(simulate("lumped", t, x, v, backend="native", **kw),
                                simulate("lumped", t, x, v, backend="python", **kw))


FORMS = {"hysteresis": {"hysteresis_force": 500.0, "hysteresis_displacement": 5e-4},
         "bypass": {"bypass_ratio": 0.5, "bypass_center": 1e-3, "bypass_width": 4e-3},
         "bypass_rebound_fading": {"bypass_ratio": 0.5, "bypass_center": 1e-3, "bypass_width": 4e-3,
                                   "bypass_direction": 1.0, "bypass_velocity": 0.01}}


@pytest.mark.parametrize("form", FORMS)
@pytest.mark.parametrize("kind", ["lumped", "twochamber"])
def test_kernel_equals_python_reference_with_the_form_elements_on_a_sine(kind, form):
    """The preset model under 3 s of a 4 mm, 1.5 Hz sine (stroke seen crossing the groove and reversing
    every 1/3 s, many x_h each way) with each form element: the element acts (hundreds of N at least)
    and C equals Python to the kernel's 1e-9 relative, in both input modes and at fixed steps."""
    t = np.arange(0.0, 3.0, 1e-3)
    w = 2 * np.pi * 1.5
    x, v = 4e-3 * np.sin(w * t), 4e-3 * w * np.cos(w * t)
    p = {**defaults(kind), **FORMS[form]}
    base = simulate(kind, t, x, v, params=defaults(kind), backend="native")
    for mode, tol in ((REPLAY, 1e-4), (EXTRAPOLATE, 1e-4), (REPLAY, 0.0)):
        kw = dict(params=p, solver=SolverOptions(input_mode=mode, tolerance=tol))
        c = simulate(kind, t, x, v, backend="native", **kw)
        assert_equal_forces(c, simulate(kind, t, x, v, backend="python", **kw))
        assert np.abs(c - base).max() > 400.0


def test_kernel_parameter_order_is_the_python_one():
    lib = native.library()
    for kind, code in native.KINDS.items():
        names = lib.dk_parameter_names(code).decode().split(",")
        assert names == [p.name for p in MODEL_PARAMETERS[kind]]


@pytest.mark.parametrize("bad, words", [
    ({"M_P": 0.0}, ["M_P", "positive"]),
    ({"k_B": float("nan")}, ["k_B", "not finite"]),
    ({"free_play": 0.5}, ["free_play", "outside"]),
    ({"Fc_10": 1000.0}, ["Fc", "not monotone"]),
    ({"Fk_x03": -3e-3}, ["Fk", "increasing"]),
    ({"area_ratio": 1.0}, ["area_ratio", "outside"]),
    ({"air": -0.5}, ["air", "outside"]),
    ({"L_R": 0.0}, ["L_R", "positive"]),
    ({"Fc_20": 0.0}, ["Fc", "not monotone"]),
    ({"hysteresis_displacement": 0.0}, ["hysteresis_displacement", "outside"]),
    ({"bypass_ratio": 1.5}, ["bypass_ratio", "outside"]),
    ({"bypass_edge": float("inf")}, ["bypass_edge", "not finite"]),
])
def test_kernel_and_python_reject_the_same_parameters(bad, words):
    t, x, v = random_stroke(np.random.default_rng(0))
    kind = "twochamber" if {"area_ratio", "air", "L_R", "Fc_20"} & set(bad) else "lumped"
    p = {**defaults(kind), **bad}
    with pytest.raises(ValueError) as py_err:
        simulate(kind, t, x, v, params=p, backend="python")
    with pytest.raises(ValueError) as c_err:
        simulate(kind, t, x, v, params=p, backend="native")
    for w in words:
        assert w in str(c_err.value), str(c_err.value)
        assert w in str(py_err.value), str(py_err.value)
