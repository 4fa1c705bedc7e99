"""The pythonfmu FMUs have the native FMUs' interface (issue 28, item 8): a master can swap one for
the other without re-mapping. The native FMU of the same model is the reference throughout:
every variable with its value reference, causality, variability, initial, start and unit; the
DefaultExperiment; Outputs and InitialUnknowns with their dependencies; and the forces of a run
addressed by the native value references."""
import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

from damper_fmu import EXTRAPOLATE, REPLAY
from tuner.identification.runner import FmuRunner, SimulationError
from stroke_cases import two_sines

KINDS = ["lumped", "maxwell", "maxwell_table", "twochamber"]
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def descriptions(fmu_paths):
    """(native, python) model descriptions of each model, read once."""
    return {k: (read_model_description(str(fmu_paths[k])), read_model_description(str(fmu_paths[f"{k}_py"])))
            for k in KINDS}


def _start(v):
    if v.start is None:
        return None
    return float(v.start) if v.type == "Real" else int(v.start)


@pytest.mark.parametrize("kind", KINDS)
def test_every_native_variable_is_in_the_python_fmu_with_the_same_attributes(descriptions, kind):
    native, py = descriptions[kind]
    by_name = {v.name: v for v in py.modelVariables}
    for n in native.modelVariables:
        p = by_name[n.name]
        for attr in ("valueReference", "type", "causality", "variability", "initial", "unit"):
            assert getattr(p, attr) == getattr(n, attr), (n.name, attr)
        assert _start(p) == _start(n), n.name
    # the same variables in the same order; no (type, value reference) twice
    assert [v.name for v in py.modelVariables] == [v.name for v in native.modelVariables]
    refs = [(v.type, v.valueReference) for v in py.modelVariables]
    assert len(set(refs)) == len(refs)
    outputs = [v for v in py.modelVariables if v.causality == "output"]
    assert outputs and all(v.initial == "calculated" and v.start is None for v in outputs)


@pytest.mark.parametrize("kind", KINDS)
def test_default_experiment_and_model_structure_are_the_natives(descriptions, kind):
    native, py = descriptions[kind]
    assert py.defaultExperiment is not None
    for attr in ("startTime", "stopTime", "stepSize", "tolerance"):
        assert getattr(py.defaultExperiment, attr) == getattr(native.defaultExperiment, attr), attr

    def structure(unknowns):
        return [(u.variable.name, sorted(d.name for d in u.dependencies)) for u in unknowns]

    assert structure(py.outputs) == structure(native.outputs)
    assert structure(py.initialUnknowns) == structure(native.initialUnknowns)
    assert len(py.initialUnknowns) == len([v for v in py.modelVariables if v.causality == "output"])
    assert all(deps == [] for _, deps in structure(py.outputs))


@pytest.mark.parametrize("kind", KINDS)
def test_fmpy_validator_finds_no_problem_in_the_python_fmu(fmu_paths, kind):
    assert validate_fmu(str(fmu_paths[f"{kind}_py"])) == []


def test_empty_benchmark_fmu_has_the_native_references_of_its_three_variables(fmu_paths):
    native = {v.name: v.valueReference for v in read_model_description(str(fmu_paths["lumped"])).modelVariables}
    empty = {v.name: v.valueReference for v in read_model_description(str(fmu_paths["empty"])).modelVariables}
    assert empty == {n: native[n] for n in ("stroke", "stroke_velocity", "force")}


# -- swapping the FMUs under a master that addresses by value reference -------------------------

def stroke(fs=1000.0, duration=1.0):
    return two_sines(fs, duration)


def close(a, b):
    """The native-vs-Python tolerance of tests/test_native_fmu.py (test_native_and_pythonfmu_fmus_agree)."""
    return np.abs(a - b).max() <= 1e-9 * np.abs(b).max()


def in_initialization(path, vr, name, reals=None, integers=None):
    """(the FMU at ``path`` instantiated and in initialization mode with the parameters ``reals`` and
    ``integers`` set by the value references ``vr``, its unzip folder)."""
    md = read_model_description(str(path))
    unzip = extract(str(path))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName=name)
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    if reals:
        fmu.setReal([vr[k] for k in reals], list(reals.values()))
    if integers:
        fmu.setInteger([vr[k] for k in integers], list(integers.values()))
    return fmu, unzip


def run_by_reference(path, vr, t, x, v, reals=None, integers=None):
    """A master that knows only the native FMU's value references ``vr`` (name -> int, taken from
    the native model description once) and uses them on whatever FMU it is given: forces and
    diagnostic outputs after every step."""
    fmu, unzip = in_initialization(path, vr, "swap", reals, integers)
    fmu.setReal([vr["stroke"], vr["stroke_velocity"]], [x[0], v[0]])
    outs = [vr[n] for n in vr["_outputs"]]
    initial = fmu.getReal(outs)
    fmu.exitInitializationMode()
    rows = [initial]
    for k in range(len(t) - 1):
        fmu.setReal([vr["stroke"], vr["stroke_velocity"]], [x[k], v[k]])
        fmu.doStep(t[k], t[k + 1] - t[k])
        rows.append(fmu.getReal(outs))
    fmu.terminate()
    fmu.freeInstance()
    shutil.rmtree(unzip, ignore_errors=True)
    return np.array(rows)


@pytest.mark.parametrize("kind", KINDS)
def test_swapped_in_python_fmu_gives_the_native_forces_by_value_reference(fmu_paths, descriptions, kind):
    native, _ = descriptions[kind]
    vr = {v.name: v.valueReference for v in native.modelVariables}
    vr["_outputs"] = [v.name for v in native.modelVariables if v.causality == "output"]
    t, x, v = stroke()
    # effects on, the form elements too (model parameters by reference), and a Real and an Integer
    # setting: Integer 0 is input_interpolation where Real 0 is the stroke
    reals = {"friction_force": 90.0, "time_delay": 2e-3, "preload_force": 250.0, "hysteresis_force": 300.0,
             "hysteresis_displacement": 3e-4, "bypass_ratio": 0.4, "bypass_center": 1e-3,
             "bypass_width": 4e-3} if "preload_force" in vr else {}
    reals["max_internal_step"] = 5e-4
    for mode in (EXTRAPOLATE, REPLAY):
        a = run_by_reference(fmu_paths[kind], vr, t, x, v, reals, {"input_interpolation": mode})
        b = run_by_reference(fmu_paths[f"{kind}_py"], vr, t, x, v, reals, {"input_interpolation": mode})
        assert np.abs(a[:, 0]).max() > 100.0
        for j, name in enumerate(vr["_outputs"]):  # every output, the force first, the initial ones first
            assert close(a[:, j], b[:, j]), (mode, name)


@pytest.mark.parametrize("kind", KINDS)
def test_simulate_fmu_with_the_native_references_gives_the_native_forces(fmu_paths, descriptions, kind):
    """fmpy.simulate_fmu, inputs and outputs chosen by the native FMU's value references (looked
    up in each FMU's own description, as a master keyed by value reference resolves them)."""
    native, _ = descriptions[kind]
    ref = {v.name: v.valueReference for v in native.modelVariables if v.type == "Real"}
    t, x, v = stroke(duration=0.5)
    results = []
    for path in (fmu_paths[kind], fmu_paths[f"{kind}_py"]):
        names = {u.valueReference: u.name for u in read_model_description(str(path)).modelVariables
                 if u.type == "Real"}
        stroke_, velocity, force = (names[ref[n]] for n in ("stroke", "stroke_velocity", "force"))
        signals = np.array(list(zip(t, x, v)), dtype=[("time", float), (stroke_, float), (velocity, float)])
        res = simulate_fmu(str(path), start_time=0.0, stop_time=t[-1], step_size=t[1] - t[0],
                           output_interval=t[1] - t[0], input=signals, output=[force])
        results.append(res[force])
    assert np.abs(results[0]).max() > 100.0
    assert close(results[0], results[1])


# -- what the declared interface promises, kept by the Python FMU -------------------------------

@pytest.mark.parametrize("kind", ["lumped", "twochamber", "maxwell"])
def test_initial_outputs_are_calculated_in_initialization_mode_as_the_native_does(fmu_paths, descriptions, kind):
    """initial="calculated" with InitialUnknowns depending on the inputs and parameters: read
    between fmi2EnterInitializationMode and fmi2ExitInitializationMode, every output is the
    initial one (preload and friction at the initial velocity), the native FMU's."""
    native, _ = descriptions[kind]
    vr = {v.name: v.valueReference for v in native.modelVariables}
    outs = [v.valueReference for v in native.modelVariables if v.causality == "output"]
    reals = {"preload_force": 1234.0, "friction_force": 300.0} if kind != "maxwell" else {}
    got = []
    for path in (fmu_paths[kind], fmu_paths[f"{kind}_py"]):
        fmu, unzip = in_initialization(path, vr, "init", reals)
        fmu.setReal([vr["stroke"], vr["stroke_velocity"]], [2e-3, 0.01])
        during = fmu.getReal(outs)
        fmu.exitInitializationMode()
        after = fmu.getReal(outs)
        fmu.terminate()
        fmu.freeInstance()
        shutil.rmtree(unzip, ignore_errors=True)
        np.testing.assert_allclose(during, after, rtol=1e-12, atol=0)
        got.append(np.array(during))
    np.testing.assert_allclose(got[1], got[0], rtol=1e-9, atol=1e-9)
    if reals:
        assert got[0][0] == pytest.approx(1234.0 + 300.0 * math.tanh(0.01 / 5e-4), rel=1e-9)


def test_input_limits_of_the_native_fmu_hold_in_the_python_fmu(fmu_paths):
    """stroke_limit and velocity_limit (native variables) act in the Python FMU too: a stroke in mm
    passed as m is refused with the reason; raised limits let it through."""
    t, x, v = stroke()
    with FmuRunner(fmu_paths["lumped_py"]) as r:
        with pytest.raises(SimulationError, match="out of range.*mm"):
            r.run(t, x * 1e3, v * 1e3)
        with pytest.raises(SimulationError, match="out of range"):
            r.run(t, x, v + 1e6)
        f = r.run(t, x * 100, v * 100, {"stroke_limit": 2.0, "velocity_limit": 100.0})
        assert np.all(np.isfinite(f))


@pytest.mark.parametrize("kind", ["lumped", "twochamber"])
def test_form_element_parameters_are_checked_by_name_in_the_python_fmu(fmu_paths, kind):
    """The form elements' parameters go through check_values as in the native FMU (which gives
    fmi2Error at fmi2ExitInitializationMode, test_native_fmu): a value out of range names the
    parameter and fails the run (pythonfmu: at the first step, where it can refuse without a fatal
    status); the FMU is usable afterwards."""
    t, x, v = stroke()
    with FmuRunner(fmu_paths[f"{kind}_py"]) as r:
        for name, value in (("hysteresis_displacement", 0.0), ("bypass_ratio", 1.5)):
            with pytest.raises(SimulationError, match=f"initialisation failed: effect parameter {name} .* outside"):
                r.run(t, x, v, {name: value})
        assert np.all(np.isfinite(r.run(t, x, v, {"hysteresis_force": 200.0, "bypass_ratio": 0.3})))


def test_variables_beyond_the_native_ones_get_stable_references_clear_of_them():
    """A variable the native FMU does not have gets the next reference from EXTRA_VR_BASE of its
    type, in registration order; get/set find each by type and reference (in a fresh process: the
    slave module must not meet a pythonfmu FMU's copy of it)."""
    code = """
import json, sys
sys.path.insert(0, sys.argv[1])
from pythonfmu import Fmi2Causality, Fmi2Variability, Integer
from damper_fmi import EXTRA_VR_BASE, UnitReal
from DamperMaxwellPy import DamperMaxwellPy
s = DamperMaxwellPy(instance_name="x")
s.extra_a, s.extra_b, s.extra_i = 1.5, 2.5, 7
for var in (UnitReal("extra_a", causality=Fmi2Causality.local, variability=Fmi2Variability.continuous),
            UnitReal("extra_b", causality=Fmi2Causality.local, variability=Fmi2Variability.continuous),
            Integer("extra_i", causality=Fmi2Causality.local, variability=Fmi2Variability.discrete)):
    s.register_variable(var)
s.set_real([EXTRA_VR_BASE + 1], [4.0])
print(json.dumps({"base": EXTRA_VR_BASE, "vr": {v.name: v.value_reference for v in s.vars.values()},
                  "real": s.get_real([EXTRA_VR_BASE, EXTRA_VR_BASE + 1, 0, 2]),
                  "int": s.get_integer([EXTRA_VR_BASE, 0])}))
"""
    out = subprocess.run([sys.executable, "-c", code, str(ROOT / "fmu_src")], capture_output=True, text=True,
                         check=True).stdout
    res = json.loads(out)
    base, vr = res["base"], res["vr"]
    natives = [r for n, r in vr.items() if not n.startswith("extra_")]
    assert base > max(natives)
    assert (vr["extra_a"], vr["extra_b"], vr["extra_i"]) == (base, base + 1, base)
    assert vr["stroke"] == 0 and vr["force"] == 2 and vr["input_interpolation"] == 0
    assert res["real"] == [1.5, 4.0, 0.0, 0.0] and res["int"] == [7, 0]


def test_tuned_fmus_of_both_flavours_carry_the_same_start_values_to_the_last_bit(tmp_path):
    """An exported FMU (tuner: identified start values, settings): the Python FMU's start values
    are the native's exactly (pythonfmu's own '%.16g' would drop the last bit of 0.1 + 0.2)."""
    from damper_fmu.fmu import build

    tuned = {"k_B": 0.1 + 0.2, "c_B": 9e5 / 7, "Fc_14": 27e3 + 1e-11, "M_C": 3.0}
    settings = {"max_internal_step": 2.5e-4, "internal_tolerance": 1e-5, "stroke_limit": 0.3,
                "input_interpolation": REPLAY}
    mds = [read_model_description(str(build("lumped", tmp_path, start_values=tuned, settings=settings,
                                            filename=f"tuned_{flavour}.fmu", flavour=flavour)))
           for flavour in ("native", "python")]
    starts = [{v.name: v.start for v in md.modelVariables if v.start is not None} for md in mds]
    assert starts[1] == starts[0]  # the strings as written
    assert float(starts[1]["k_B"]) == 0.1 + 0.2 and float(starts[1]["c_B"]) == 9e5 / 7
    assert float(starts[1]["stroke_limit"]) == 0.3 and int(starts[1]["input_interpolation"]) == REPLAY
