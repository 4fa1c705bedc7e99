"""The FMUs through fmpy: validity, identity with the in-process engine, state, errors, co-simulation
(``examples/mass_spring_cosim.py``, loaded from its file: the examples are no package)."""
import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description

from damper_fmu import EXTRAPOLATE, MODEL_PARAMETERS, REPLAY, SolverOptions, defaults, simulate
from damper_fmu.fmu import build, validate
from tuner.identification.runner import FmuRunner, SimulationError
from stroke_cases import two_sines

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "mass_spring_cosim.py"


def _load_example():
    spec = importlib.util.spec_from_file_location("mass_spring_cosim", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


mass_spring_cosimulation = _load_example().mass_spring_cosimulation

KINDS = ["lumped", "maxwell", "maxwell_table", "twochamber"]
#: the form elements (damper_fmu.effects) both on: hysteresis, and a bypass groove the stroke crosses
FORMS = {"hysteresis_force": 500.0, "hysteresis_displacement": 5e-4, "bypass_ratio": 0.5, "bypass_center": 1e-3,
         "bypass_width": 4e-3}


def stroke(fs=1000.0, duration=2.0):
    return two_sines(fs, duration)


@pytest.fixture(scope="module")
def runners(fmu_paths):
    rs = {k: FmuRunner(fmu_paths[k]) for k in KINDS}
    yield rs
    for r in rs.values():
        r.close()


@pytest.mark.parametrize("kind", KINDS + [f"{k}_py" for k in KINDS] + ["empty"])
def test_fmpy_validator_reports_no_problem(fmu_paths, kind):
    assert validate(fmu_paths[kind]) == []


@pytest.mark.parametrize("kind", KINDS)
def test_every_parameter_is_an_fmu_variable_with_unit_and_preset_start(fmu_paths, kind):
    md = read_model_description(str(fmu_paths[kind]))
    variables = {v.name: v for v in md.modelVariables}
    for p in MODEL_PARAMETERS[kind]:
        var = variables[p.name]
        assert var.causality == "parameter"
        assert var.variability == ("tunable" if (p.tunable or p.effect) else "fixed")
        assert var.unit == p.unit and var.description
        assert float(var.start) == p.default
    assert variables["stroke"].causality == "input" and variables["stroke"].unit == "m"
    assert variables["stroke_velocity"].unit == "m/s"
    assert variables["force"].causality == "output" and variables["force"].unit == "N"


@pytest.mark.parametrize("kind", KINDS)
def test_fmu_and_in_process_model_give_the_same_force(runners, kind):
    t, x, v = stroke()
    fmu_force = runners[kind].run(t, x, v)
    np.testing.assert_allclose(fmu_force, simulate(kind, t, x, v), rtol=0, atol=1e-9)
    assert np.abs(fmu_force).max() > 1e3


def test_co_simulation_input_mode_matches_in_process_too(fmu_paths):
    t, x, v = stroke()
    with FmuRunner(fmu_paths["lumped"], input_mode=EXTRAPOLATE) as r:
        f = r.run(t, x, v)
    np.testing.assert_allclose(f, simulate("lumped", t, x, v, solver=SolverOptions(input_mode=EXTRAPOLATE)),
                               rtol=0, atol=1e-9)
    # the co-simulation convention lags the replay convention by about one sample
    replay = simulate("lumped", t, x, v, solver=SolverOptions(input_mode=REPLAY))
    assert np.abs(f - replay).max() > 10.0


def test_parameters_change_between_runs_and_reset_restores_a_clean_state(runners):
    t, x, v = stroke()
    r = runners["lumped"]
    base = r.run(t, x, v)
    p = {"c_B": 1e6, "Fc_12": 18e3, "M_O": 5.0}
    changed = r.run(t, x, v, params=p)
    np.testing.assert_allclose(changed, simulate("lumped", t, x, v, params=p), rtol=0, atol=1e-9)
    assert np.abs(changed - base).max() > 100.0
    np.testing.assert_array_equal(r.run(t, x, v), base)  # reset: start values back, state clean


@pytest.mark.parametrize("reals", [{}, FORMS], ids=["base", "forms"])
@pytest.mark.parametrize("flavour", ["lumped", "lumped_py"])
def test_get_and_set_fmu_state_resumes_identically(fmu_paths, flavour, reals):
    """Native and pythonfmu FMUs; with the form elements on, their states (hysteresis force, stroke
    seen at the last step) are rolled back too."""
    from fmpy import extract
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(fmu_paths[flavour]))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzip = extract(str(fmu_paths[flavour]))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="s")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    if reals:
        fmu.setReal([vr[k] for k in reals], list(reals.values()))
    fmu.exitInitializationMode()
    t, x, v = stroke(duration=1.0)
    h = t[1] - t[0]

    def advance(k0, k1):
        out = []
        for k in range(k0, k1):
            fmu.setReal([vr["stroke"], vr["stroke_velocity"]], [x[k], v[k]])
            fmu.doStep(t[k], h)
            out.append(fmu.getReal([vr["force"], vr["damping_force"]]))
        return np.array(out)

    advance(0, 500)
    saved = fmu.getFMUstate()
    first = advance(500, 1000)
    fmu.setFMUstate(saved)
    second = advance(500, 1000)
    fmu.freeFMUstate(saved)
    fmu.terminate()
    fmu.freeInstance()
    shutil.rmtree(unzip, ignore_errors=True)
    np.testing.assert_array_equal(first, second)
    assert np.abs(first[:, 0]).max() > 1e3


def test_nan_stroke_gives_an_fmi_error_status_with_a_message_not_a_nan_force(runners):
    t, x, v = stroke()
    x[300] = np.nan
    with pytest.raises(SimulationError, match=r"non-finite input.*stroke ?= ?nan"):
        runners["lumped"].run(t, x, v)
    t, x, v = stroke()
    assert np.all(np.isfinite(runners["lumped"].run(t, x, v)))  # usable again after the error


def test_invalid_parameter_is_reported_by_name(runners):
    t, x, v = stroke()
    with pytest.raises(SimulationError, match="M_P"):
        runners["lumped"].run(t, x, v, params={"M_P": -3.0})
    with pytest.raises(ValueError, match="no parameter 'bogus'"):
        runners["lumped"].run(t, x, v, params={"bogus": 1.0})


@pytest.mark.parametrize("h", [1e-4, 1e-3, 1e-2])
def test_communication_steps_from_0p1_to_10_ms_are_stable_and_accurate(runners, h):
    """With internal sub-stepping the FMU result does not depend on the communication step."""
    t = np.arange(0.0, 3.0 + h / 2, h)
    w = 2 * np.pi * 0.5
    x, v = 0.02 * np.sin(w * t), 0.02 * w * np.cos(w * t)
    f = runners["lumped"].run(t, x, v)
    ref = simulate("lumped", t, x, v, solver=SolverOptions(max_step=1e-5))
    assert np.all(np.isfinite(f))
    assert np.abs(f - ref).max() < 2e-3 * np.abs(ref).max()


def test_exported_fmu_carries_tuned_start_values(tmp_path):
    p = defaults("lumped")
    tuned = {"k_B": 2e8, "c_B": 9e5, "Fc_14": 27e3, "M_C": 3.0}
    path = build("lumped", tmp_path, start_values=tuned, filename="tuned.fmu")
    assert validate(path) == []
    md = read_model_description(str(path))
    starts = {v.name: float(v.start) for v in md.modelVariables if v.causality == "parameter"}
    for name, value in tuned.items():
        assert starts[name] == value
    assert starts["M_O"] == p["M_O"]
    t, x, v = stroke()
    with FmuRunner(path) as r:  # no parameter set: the FMU must use its tuned start values
        f = r.run(t, x, v)
    np.testing.assert_allclose(f, simulate("lumped", t, x, v, params=tuned), rtol=0, atol=1e-9)


def maxwell_mass_spring_exact(m, k, ks, c, x0, t):
    from scipy.linalg import expm

    a = np.array([[0, 1, 0], [-(k + ks) / m, 0, ks / m], [ks / c, 0, -ks / c]])
    y0 = np.array([x0, 0.0, x0])  # the damper starts force-free: dashpot end at the stroke
    return np.array([(expm(a * ti) @ y0)[0] for ti in t])


def test_cosimulation_with_a_mass_on_a_spring_converges_to_the_monolithic_solution(fmu_paths):
    m, k, x0 = 1000.0, 1e6, 0.01
    p = defaults("maxwell")
    errors = []
    for h in (2e-3, 1e-3, 5e-4):
        res = mass_spring_cosimulation(fmu_paths["maxwell"], mass=m, stiffness=k, x0=x0, h=h, t_end=1.0)
        exact = maxwell_mass_spring_exact(m, k, p["k_s"], p["c"], x0, res["time"])
        errors.append(np.abs(res["x"] - exact).max() / x0)
    assert errors[2] < errors[1] < errors[0]
    assert errors[2] < 0.02, errors


def test_cosimulation_with_the_lumped_damper_dissipates_and_comes_to_rest(fmu_paths):
    m, k, x0 = 500.0, 2e6, 0.01
    res = mass_spring_cosimulation(fmu_paths["lumped"], mass=m, stiffness=k, x0=x0, h=1e-3, t_end=3.0)
    energy = 0.5 * m * res["v"] ** 2 + 0.5 * k * res["x"] ** 2
    assert energy[-1] < 1e-3 * energy[0]
    # the damper's internal springs exchange energy with the mass, so look at the envelope:
    # the largest energy in each successive 0.25 s window decreases
    envelope = energy[: 3000].reshape(12, 250).max(axis=1)
    assert np.all(np.diff(envelope) < 0.0)


def test_the_cosimulation_example_runs_as_a_script(fmu_paths):
    out = subprocess.run([sys.executable, str(EXAMPLE), str(fmu_paths["lumped"]), "--t-end", "0.2"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "peak damper force" in out.stdout


@pytest.mark.parametrize("effect,value", [("friction_force", 150.0), ("free_play", 4e-4), ("time_delay", 4e-3),
                                          ("thermal_beta", 0.02), ("valve_tau", 4e-3), ("inertia_mass", 80.0),
                                          ("preload_force", -250.0), ("hysteresis_force", 500.0),
                                          ("bypass_ratio", 0.5)])
def test_effect_elements_through_the_fmu_match_in_process_and_state_restores(runners, fmu_paths, effect, value):
    t, x, v = stroke()
    p = {effect: value}
    f = runners["lumped"].run(t, x, v, params=p)
    np.testing.assert_allclose(f, simulate("lumped", t, x, v, params=p), rtol=0, atol=1e-9)
    assert np.abs(f - runners["lumped"].run(t, x, v)).max() > 10.0  # the effect acts


@pytest.mark.parametrize("flavour", ["lumped", "lumped_py"])
@pytest.mark.parametrize("mode", [REPLAY, EXTRAPOLATE])
def test_c_stepping_loop_makes_the_same_calls_as_the_python_loop(fmu_paths, flavour, mode):
    from tuner.identification.runner import stepper

    if stepper() is None:
        pytest.skip("no C compiler: the runner uses its Python loop only")
    t, x, v = stroke(duration=1.0)
    with FmuRunner(fmu_paths[flavour], input_mode=mode) as a, \
            FmuRunner(fmu_paths[flavour], input_mode=mode, c_loop=False) as b:
        kw = dict(params={"time_delay": 2e-3, "thermal_beta": 0.01}, temperature=20.0 + 5.0 * t)
        np.testing.assert_array_equal(a.run(t, x, v, **kw), b.run(t, x, v, **kw))
        out = ("force", "damping_force")
        np.testing.assert_array_equal(a.run(t, x, v, outputs=out), b.run(t, x, v, outputs=out))
        x[400] = np.nan
        with pytest.raises(SimulationError, match="step 40[01]"):
            a.run(t, x, v)
