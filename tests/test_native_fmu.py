"""The native (C) FMUs as an importer sees them: FMI behaviour, errors, state, sources, libcosim."""
import shutil
import subprocess
import zipfile

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from damper_fmu import EXTRAPOLATE, REPLAY, defaults
from tuner.identification.runner import FmuRunner, SimulationError
from stroke_cases import two_sines

KINDS = ["lumped", "maxwell", "maxwell_table", "twochamber"]


def stroke(fs=1000.0, duration=1.5):
    return two_sines(fs, duration)


@pytest.mark.parametrize("kind", KINDS)
def test_native_fmu_is_self_contained_and_declares_what_masters_need(fmu_paths, kind):
    md = read_model_description(str(fmu_paths[kind]))
    cs = md.coSimulation
    assert not cs.needsExecutionTool
    assert cs.canGetAndSetFMUstate and cs.canSerializeFMUstate and cs.canInterpolateInputs
    assert md.defaultExperiment is not None and md.defaultExperiment.stepSize
    outputs = [v for v in md.modelVariables if v.causality == "output"]
    assert {u.variable.name for u in md.initialUnknowns} == {v.name for v in outputs}
    with zipfile.ZipFile(fmu_paths[kind]) as z:
        names = z.namelist()
    assert {"sources/fmi2_damper.c", "sources/damper_kernel.c", "sources/fmi2Functions.h"} <= set(names)
    binary = [n for n in names if n.startswith("binaries/")]
    assert len(binary) == 1
    # linked against libc/libm only: no Python, no numpy
    if shutil.which("ldd"):
        tmp = extract(str(fmu_paths[kind]))
        libs = subprocess.run(["ldd", f"{tmp}/{binary[0]}"], capture_output=True, text=True).stdout
        assert "python" not in libs.lower()
        shutil.rmtree(tmp, ignore_errors=True)


#: the form elements (damper_fmu.effects) both on: hysteresis, and a bypass groove the stroke crosses
FORMS = {"hysteresis_force": 500.0, "hysteresis_displacement": 5e-4, "bypass_ratio": 0.5, "bypass_center": 1e-3,
         "bypass_width": 4e-3}


@pytest.mark.parametrize("kind, params", [
    *[(k, {"friction_force": 90.0, "time_delay": 2e-3} if k == "lumped" else None) for k in KINDS],
    ("lumped", FORMS), ("twochamber", FORMS)])
@pytest.mark.parametrize("mode", [REPLAY, EXTRAPOLATE])
def test_native_and_pythonfmu_fmus_agree(fmu_paths, kind, params, mode):
    t, x, v = stroke()
    with FmuRunner(fmu_paths[kind], input_mode=mode) as a, FmuRunner(fmu_paths[f"{kind}_py"], input_mode=mode) as b:
        fa, fb = a.run(t, x, v, params), b.run(t, x, v, params)
    assert np.abs(fa - fb).max() <= 1e-9 * np.abs(fb).max()


@pytest.mark.parametrize("kind, bad, name", [
    ("lumped", {"M_P": 0.0}, "M_P"), ("lumped", {"k_B": float("nan")}, "k_B"), ("lumped", {"Fc_10": 1000.0}, "Fc"),
    ("lumped", {"free_play": -1e-3}, "free_play"),
    *[(kind, {name: value}, name) for kind in ("lumped", "twochamber")
      for name, value in (("hysteresis_displacement", 0.0), ("bypass_ratio", 1.5))]])
def test_invalid_parameters_fail_initialisation_with_their_name(fmu_paths, kind, bad, name):
    t, x, v = stroke()
    with FmuRunner(fmu_paths[kind]) as r:
        with pytest.raises(SimulationError, match=f"exit initialization failed.*{name}"):
            r.run(t, x, v, bad)
        assert np.all(np.isfinite(r.run(t, x, v)))  # reset and usable again


def test_absurd_inputs_are_errors_unless_the_limits_say_otherwise(fmu_paths):
    t, x, v = stroke()
    with FmuRunner(fmu_paths["lumped"]) as r:
        with pytest.raises(SimulationError, match="out of range.*mm"):
            r.run(t, x * 1e3, v * 1e3)  # a stroke in mm passed as m
        with pytest.raises(SimulationError, match="out of range"):
            r.run(t, x, v + 1e6)
        f = r.run(t, x * 100, v * 100, {"stroke_limit": 2.0, "velocity_limit": 100.0})
        assert np.all(np.isfinite(f))


def _instance(path, name="inst"):
    md = read_model_description(str(path))
    unzip = extract(str(path))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName=name)
    fmu.instantiate()
    vr = {v.name: v.valueReference for v in md.modelVariables}
    return fmu, vr, unzip


@pytest.mark.parametrize("kind, reals", [("lumped", {"time_delay": 4e-3, "free_play": 2e-4}),
                                         ("lumped", {**FORMS, "free_play": 2e-4}), ("twochamber", FORMS)],
                         ids=["lumped-delay", "lumped-forms", "twochamber-forms"])
def test_serialized_state_rolls_back_exactly_with_effect_history(fmu_paths, kind, reals):
    """The time-delay history, the free play's gap state and the form elements' states (hysteresis
    force, stroke seen at the last step) survive serialization: the steps after a roll-back repeat."""
    t, x, v = stroke()
    fmu, vr, unzip = _instance(fmu_paths[kind])
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.setReal([vr[k] for k in reals], list(reals.values()))
    fmu.setReal([vr["stroke"], vr["stroke_velocity"]], [x[0], v[0]])
    fmu.exitInitializationMode()

    def advance(a, b):
        out = []
        for k in range(a, b):
            fmu.setReal([vr["stroke"], vr["stroke_velocity"]], [x[k], v[k]])
            fmu.doStep(t[k], t[k + 1] - t[k])
            out.append(fmu.getReal([vr["force"]])[0])
        return np.array(out)

    advance(0, 400)
    blob = fmu.serializeFMUstate(fmu.getFMUstate())
    first = advance(400, 900)
    state = fmu.deSerializeFMUstate(blob)
    fmu.setFMUstate(state)
    second = advance(400, 900)
    fmu.freeFMUstate(state)
    np.testing.assert_array_equal(first, second)
    # reset: back to the state after instantiation, parameters at their start values
    fmu.reset()
    assert fmu.getReal([vr[k] for k in reals]) == [defaults(kind)[k] for k in reals]
    fmu.terminate()
    fmu.freeInstance()
    shutil.rmtree(unzip, ignore_errors=True)


@pytest.mark.parametrize("reals", [FORMS, {"free_play": 4e-4, "time_delay": 2e-3}], ids=["forms", "play-delay"])
@pytest.mark.parametrize("kind", ["lumped", "twochamber"])
def test_effects_switched_on_mid_run_start_at_the_present_stroke_in_both_flavours(fmu_paths, kind, reals):
    """Effect parameters are tunable: switched on between steps (stroke offset 3 mm), the elements
    start at the stroke reached (free play engaged, no hysteresis force, the groove seen there), in
    the native FMU and the pythonfmu one alike (Simulator.set_model: they used to start at 0 there)."""
    t, x, v = stroke(duration=1.0)
    x = x + 3e-3
    runs = []
    for path in (fmu_paths[kind], fmu_paths[f"{kind}_py"]):
        fmu, vr, unzip = _instance(path)
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setReal([vr["stroke"], vr["stroke_velocity"]], [x[0], v[0]])
        fmu.exitInitializationMode()
        out = []
        for k in range(t.size - 1):
            if k == 300:
                fmu.setReal([vr[n] for n in reals], list(reals.values()))
            fmu.setReal([vr["stroke"], vr["stroke_velocity"]], [x[k], v[k]])
            fmu.doStep(t[k], t[k + 1] - t[k])
            out.append(fmu.getReal([vr["force"]])[0])
        fmu.terminate()
        fmu.freeInstance()
        shutil.rmtree(unzip, ignore_errors=True)
        runs.append(np.array(out))
    with FmuRunner(fmu_paths[kind], input_mode=EXTRAPOLATE) as r:
        without = r.run(t, x, v)[1:]
    np.testing.assert_array_equal(runs[0][:300], without[:300])
    assert np.abs(runs[0] - without)[300:].max() > 100.0  # they act
    assert np.abs(runs[0] - runs[1]).max() <= 1e-9 * np.abs(runs[1]).max()


def test_input_derivatives_from_the_master_are_used(fmu_paths):
    """The acceleration given by fmi2SetRealInputDerivatives replaces the FMU's own estimate (which
    also extrapolates the jerk, so it is not worse) and keeps the force within the 5 ms bar."""
    h = 5e-3
    t = np.arange(0.0, 1.0, h)
    w = 2 * np.pi * 6.0
    x, v, a = 2e-3 * np.sin(w * t), 2e-3 * w * np.cos(w * t), -2e-3 * w * w * np.sin(w * t)
    with FmuRunner(fmu_paths["lumped"], input_mode=REPLAY) as r:
        fine_t = np.arange(0.0, 1.0, 1e-4)
        ref = np.interp(t, fine_t, r.run(fine_t, 2e-3 * np.sin(w * fine_t), 2e-3 * w * np.cos(w * fine_t)))
    errors, forces = {}, {}
    for with_derivative in (False, True):
        fmu, vr, unzip = _instance(fmu_paths["lumped"], f"d{with_derivative}")
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setReal([vr["stroke"], vr["stroke_velocity"]], [x[0], v[0]])
        fmu.exitInitializationMode()
        out = [fmu.getReal([vr["force"]])[0]]
        for k in range(t.size - 1):
            fmu.setReal([vr["stroke"], vr["stroke_velocity"]], [x[k], v[k]])
            if with_derivative:
                fmu.setRealInputDerivatives([vr["stroke_velocity"]], [1], [a[k]])
            fmu.doStep(t[k], h)
            out.append(fmu.getReal([vr["force"]])[0])
        fmu.terminate()
        fmu.freeInstance()
        shutil.rmtree(unzip, ignore_errors=True)
        forces[with_derivative] = np.array(out)
        errors[with_derivative] = np.abs(np.array(out) - ref)[t > 0.1].max()
    assert np.abs(forces[True] - forces[False]).max() > 1.0  # the derivative is used
    assert max(errors.values()) < 0.02 * np.abs(ref).max(), errors


def test_the_bundled_sources_compile_into_an_equal_fmu(fmu_paths, tmp_path):
    """An importer on another platform compiles sources/: here, with gcc, into a binary that
    replaces the shipped one and gives the same forces."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler")
    unzip = tmp_path / "fmu"
    with zipfile.ZipFile(fmu_paths["lumped"]) as z:
        z.extractall(unzip)
    binary = next((unzip / "binaries").rglob("*.so"))
    binary.unlink()
    src = unzip / "sources"
    files = read_model_description(str(fmu_paths["lumped"])).buildConfigurations[0].sourceFileSets[0].sourceFiles
    assert files == ["fmi2_damper.c", "damper_fmu_values.c"]  # the wrapper and this FMU's GUID and start values
    subprocess.run([cc, "-std=c99", "-O2", "-ffp-contract=off", "-shared", "-fPIC", "-I", str(src),
                    *(str(src / f) for f in files), "-o", str(binary), "-lm"], check=True)
    rebuilt = tmp_path / "rebuilt.fmu"
    with zipfile.ZipFile(rebuilt, "w") as z:
        for f in unzip.rglob("*"):
            if f.is_file():
                z.write(f, f.relative_to(unzip).as_posix())
    t, x, v = stroke()
    with FmuRunner(rebuilt) as a, FmuRunner(fmu_paths["lumped"]) as b:
        np.testing.assert_array_equal(a.run(t, x, v), b.run(t, x, v))


def test_runs_in_libcosim_as_in_fmpy(fmu_paths):
    """libcosim (an independent importer) steps the FMU; a manipulator sets the stroke of each
    communication point, as a multibody master would; the force equals fmpy's in co-simulation mode."""
    libcosimpy = pytest.importorskip("libcosimpy", reason="libcosimpy has no wheel for this platform")
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    assert libcosimpy
    h = 1e-3
    t = np.arange(0.0, 0.5, h)
    w = 2 * np.pi * 3.0
    x, v = 5e-3 * np.sin(w * t), 5e-3 * w * np.cos(w * t)
    md = read_model_description(str(fmu_paths["lumped"]))
    vr = {u.name: u.valueReference for u in md.modelVariables}
    ex = CosimExecution.from_step_size(step_size=int(round(h * 1e9)))
    idx = ex.add_local_slave(CosimLocalSlave(fmu_path=str(fmu_paths["lumped"]), instance_name="damper"))
    manip = CosimManipulator.create_override()
    obs = CosimObserver.create_last_value()
    ex.add_manipulator(manipulator=manip)
    ex.add_observer(observer=obs)
    ex.real_initial_value(idx, vr["stroke"], float(x[0]))
    ex.real_initial_value(idx, vr["stroke_velocity"], float(v[0]))
    forces = []
    for k in range(t.size - 1):
        manip.slave_real_values(idx, [vr["stroke"], vr["stroke_velocity"]], [float(x[k]), float(v[k])])
        assert ex.step()
        forces.append(obs.last_real_values(idx, [vr["force"]])[0])
    with FmuRunner(fmu_paths["lumped"], input_mode=EXTRAPOLATE) as r:
        ref = r.run(t, x, v)
    np.testing.assert_allclose(forces, ref[1:], rtol=0, atol=1e-9 * np.abs(ref).max())
    assert np.abs(ref).max() > 1e3
