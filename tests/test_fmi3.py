"""The FMI 3.0 co-simulation FMUs (issue 28): the same kernel as the FMI 2.0 FMUs behind
damper_fmu/c/fmi3_damper.c. The FMI 2.0 FMU is the reference: same variables, same forces."""
import re
import shutil
import subprocess
import xml.etree.ElementTree as ET
import zipfile

import numpy as np
import pytest
from fmpy import extract, platform_tuple, read_model_description, sharedLibraryExtension, simulate_fmu
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from damper_fmu.fmu import build, ensure_fmu, native_reason
from damper_fmu.model_description import FMI3_VR

from test_fmi_conformance import H, Slave, exact_and_jittered, sine, stroke_run

KINDS = ["lumped", "maxwell", "maxwell_table", "twochamber"]
CC = shutil.which("cc") or shutil.which("gcc")

pytestmark = pytest.mark.skipif(bool(native_reason()), reason="FMI 3.0 FMUs are native: need a C compiler")


@pytest.fixture(scope="module")
def fmu3_paths():
    return {kind: ensure_fmu(kind, flavour="native", fmi_version=3) for kind in KINDS}


class Slave3:
    """One FMU instance through fmpy's raw FMI 3.0 calls (as test_fmi_conformance.Slave for FMI 2.0)."""

    def __init__(self, path, name="damper"):
        self.md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.dir = extract(str(path))
        self.fmu = FMU3Slave(guid=self.md.guid, unzipDirectory=self.dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        self.log = []  # (status, message) as the FMU logs them

        def logger(env, status, category, message):
            self.log.append((status, message.decode("utf-8", "replace") if message else ""))

        self.fmu.instantiate(logMessage=logger)

    def start(self, x0=0.0, v0=0.0, t0=0.0, reals=None):
        self.fmu.enterInitializationMode(startTime=t0)
        if reals:
            self.fmu.setFloat64([self.vr[k] for k in reals], list(reals.values()))
        self.set_inputs(x0, v0)

    def set_inputs(self, x, v):
        self.fmu.setFloat64([self.vr["stroke"], self.vr["stroke_velocity"]], [x, v])

    def force(self):
        return self.fmu.getFloat64([self.vr["force"]])[0]

    def close(self):
        self.fmu.terminate()
        self.free()

    def free(self):
        """Free the instance and delete the extracted FMU."""
        self.fmu.freeInstance()
        shutil.rmtree(self.dir, ignore_errors=True)


def stroke_run3(path, steps, input_mode=0):
    """test_fmi_conformance.stroke_run through the FMI 3.0 interface: force after each step of a
    5 Hz, 5 mm sine; doStep's out-arguments checked on every step."""
    s = Slave3(path)
    s.start(*sine(0.0))
    if input_mode:
        s.fmu.setInt32([s.vr["input_interpolation"]], [input_mode])
    s.fmu.exitInitializationMode()
    out = []
    for k, (t, h) in enumerate(steps):
        s.set_inputs(*sine((k + 1) * H if input_mode else k * H))
        event, terminate, early, last = s.fmu.doStep(t, h)
        assert (event, terminate, early, last) == (False, False, False, t + h)
        out.append(s.force())
    s.close()
    return np.array(out)


# -- model description ---------------------------------------------------------------------------

@pytest.mark.parametrize("kind", KINDS)
def test_fmu_is_valid_and_declares_the_fmi2_variables(fmu_paths, fmu3_paths, kind):
    """fmpy's validator finds no problem. Every variable of the FMI 2.0 FMU is there with the same
    name, causality, variability, initial, unit, start value and description; every Real keeps
    its value reference (as Float64), the Integer settings are Int32 at FMI3_VR (FMI 3.0 has one
    value-reference space); 'time' is the independent variable. Units, DefaultExperiment and the
    dependencies are the FMI 2.0 FMU's."""
    assert validate_fmu(str(fmu3_paths[kind])) == []
    md2, md3 = read_model_description(str(fmu_paths[kind])), read_model_description(str(fmu3_paths[kind]))
    assert (md2.fmiVersion, md3.fmiVersion) == ("2.0", "3.0")
    assert md3.coSimulation.modelIdentifier == md2.coSimulation.modelIdentifier
    assert md3.coSimulation.canHandleVariableCommunicationStepSize
    assert md3.coSimulation.canGetAndSetFMUstate and md3.coSimulation.canSerializeFMUstate
    v3 = {v.name: v for v in md3.modelVariables}
    assert v3["time"].causality == "independent" and v3["time"].valueReference == FMI3_VR["time"]
    assert set(v3) == {v.name for v in md2.modelVariables} | {"time"}
    for v in md2.modelVariables:
        w = v3[v.name]
        assert w.type == {"Real": "Float64", "Integer": "Int32"}[v.type], v.name
        assert w.valueReference == FMI3_VR.get(v.name, v.valueReference), v.name
        if v.type == "Real":
            assert w.valueReference == v.valueReference, v.name
        for attr in ("causality", "variability", "initial", "unit", "start", "description"):
            assert getattr(w, attr) == getattr(v, attr), (v.name, attr)
    assert [v.name for v in md2.modelVariables if v.causality == "parameter"] == \
        [v.name for v in md3.modelVariables if v.causality == "parameter"]
    assert {(u.name, str(u.baseUnit)) for u in md2.unitDefinitions} == \
        {(u.name, str(u.baseUnit)) for u in md3.unitDefinitions}
    e2, e3 = md2.defaultExperiment, md3.defaultExperiment
    assert (e2.startTime, e2.stopTime, e2.stepSize) == (e3.startTime, e3.stopTime, e3.stepSize)
    assert [u.variable.name for u in md3.outputs] == [u.variable.name for u in md2.outputs]
    assert all(u.dependencies == [] for u in md3.outputs)
    assert [(u.variable.name, sorted(d.name for d in u.dependencies)) for u in md3.initialUnknowns] == \
        [(u.variable.name, sorted(d.name for d in u.dependencies)) for u in md2.initialUnknowns]


def test_build_description_declares_fmi3_and_the_fmi3_wrapper(fmu3_paths, tmp_path):
    """FMI 3.0 declares source files in sources/buildDescription.xml only (fmpy validates it
    against the standard's schema when it reads the model description)."""
    md = read_model_description(str(fmu3_paths["lumped"]))
    assert md.buildConfigurations[0].sourceFileSets[0].sourceFiles == ["fmi3_damper.c", "damper_fmu_values.c"]
    with zipfile.ZipFile(fmu3_paths["lumped"]) as z:
        root = ET.fromstring(z.read("sources/buildDescription.xml"))
        names = set(z.namelist())
    assert root.get("fmiVersion") == "3.0"
    assert [lib.get("name") for lib in root.iter("Library")] == ["m"]
    assert f"binaries/{platform_tuple}/DamperLumped{sharedLibraryExtension}" in names  # FMI 3.0 layout
    assert not any(n.startswith("sources/fmi2") for n in names)


# -- the forces: the FMI 2.0 FMU is the reference -------------------------------------------------

@pytest.mark.parametrize("kind", KINDS)
def test_forces_equal_the_fmi2_fmu_bit_for_bit(fmu_paths, fmu3_paths, kind):
    """20 s of a 5 Hz, 5 mm sine at 1 ms, inputs at the start (mode 0) and at the end (mode 1) of
    each step, and with steps of (k+1)h - kh: the FMI 3.0 FMU's force equals the FMI 2.0 FMU's in
    every bit."""
    exact, jittered = exact_and_jittered(20000)
    for mode in (0, 1):
        ref = stroke_run(fmu_paths[kind], exact, mode)
        assert np.abs(ref).max() > 100.0
        np.testing.assert_array_equal(stroke_run3(fmu3_paths[kind], exact, mode), ref)
    np.testing.assert_array_equal(stroke_run3(fmu3_paths[kind], jittered), stroke_run(fmu_paths[kind], exact))


@pytest.mark.parametrize("kind", KINDS)
def test_simulate_fmu_gives_the_fmi2_fmus_result(fmu_paths, fmu3_paths, kind):
    """fmpy.simulate_fmu (its FMI 3.0 co-simulation loop: fmi3EnterInitializationMode with start
    and stop time, fmi3DoStep with its out-arguments) under the same sampled stroke, with start
    values (a tunable parameter, a setting, the Integer setting): every recorded output equals the
    FMI 2.0 FMU's bit for bit."""
    t = np.arange(0.0, 5.0 + H / 2, H)
    w = 2 * np.pi * 5.0
    signals = np.zeros(t.size, dtype=[("time", float), ("stroke", float), ("stroke_velocity", float)])
    signals["time"], signals["stroke"], signals["stroke_velocity"] = t, 5e-3 * np.sin(w * t), 5e-3 * w * np.cos(w * t)
    md = read_model_description(str(fmu_paths[kind]))
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    tunable = next(v.name for v in md.modelVariables if v.causality == "parameter" and v.variability == "tunable")
    start = {tunable: 1.1 * float(next(v.start for v in md.modelVariables if v.name == tunable)),
             "max_internal_step": 5e-4}
    for extra in ({}, {"input_interpolation": 1}):
        res = [simulate_fmu(str(p), stop_time=5.0, step_size=H, output_interval=H, input=signals, output=outputs,
                            start_values={**start, **extra}) for p in (fmu_paths[kind], fmu3_paths[kind])]
        assert res[0].size == res[1].size == t.size
        assert np.abs(res[0]["force"]).max() > 100.0
        for name in outputs:
            np.testing.assert_array_equal(res[1][name], res[0][name], err_msg=name)


# -- statuses ------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind, name, value", [("lumped", "M_P", 0.0), ("lumped", "hysteresis_displacement", 0.0),
                                               ("twochamber", "bypass_ratio", 1.5)])
def test_bad_parameter_is_an_fmi3_error_naming_it(fmu3_paths, kind, name, value):
    """As the FMI 2.0 FMU: a parameter the model refuses makes the initial output and
    fmi3ExitInitializationMode fmi3Error, with a logged message naming it."""
    s = Slave3(fmu3_paths[kind])
    s.start(reals={name: value})
    with pytest.raises(Exception, match="fmi3GetFloat64.*status 3"):
        s.force()
    with pytest.raises(Exception, match="fmi3ExitInitializationMode.*status 3"):
        s.fmu.exitInitializationMode()
    errors = [text for status, text in s.log if status == 3]
    assert len(errors) == 2 and all("invalid parameters" in t and name in t for t in errors), s.log
    with pytest.raises(Exception, match="fmi3DoStep"):  # the error state
        s.fmu.doStep(0.0, H)
    assert "error state" in s.log[-1][1]
    s.fmu.reset()  # back to the start values: usable again
    s.start(*sine(0.0))
    s.fmu.exitInitializationMode()
    s.fmu.doStep(0.0, H)
    s.close()


def test_non_finite_input_is_an_fmi3_error_with_the_values(fmu3_paths):
    s = Slave3(fmu3_paths["twochamber"])
    s.start(*sine(0.0))
    s.fmu.exitInitializationMode()
    s.set_inputs(1e-3, float("nan"))
    with pytest.raises(Exception, match="fmi3DoStep.*status 3"):
        s.fmu.doStep(0.0, H)
    assert any(st == 3 and "non-finite input" in m and "stroke_velocity = nan" in m for st, m in s.log), s.log
    s.free()


def test_what_the_fmu_does_not_have_is_an_error_with_a_reason(fmu3_paths):
    """Types without variables, event mode, clocks, configuration mode, derivatives: fmi3Error and
    a message (an empty request for a type without variables is fine)."""
    s = Slave3(fmu3_paths["maxwell"])
    s.start()
    assert s.fmu.getFloat32([]) == [] and s.fmu.getBoolean([]) == []
    calls = {
        "fmi3GetBoolean": lambda: s.fmu.getBoolean([5]),
        "fmi3SetFloat32": lambda: s.fmu.setFloat32([0], [1.0]),
        "fmi3GetInt32": lambda: s.fmu.getInt32([1]),  # thermal_source: lumped and two-chamber only
        "fmi3GetFloat64": lambda: s.fmu.getFloat64([9999]),
        "fmi3EnterEventMode": lambda: s.fmu.enterEventMode(),
        "fmi3EnterStepMode": lambda: s.fmu.enterStepMode(),
        "fmi3EnterConfigurationMode": lambda: s.fmu.enterConfigurationMode(),
        "fmi3GetClock": lambda: s.fmu.getClock([0]),
        "fmi3GetDirectionalDerivative": lambda: s.fmu.getDirectionalDerivative([2], [0], [1.0]),
    }
    for name, call in calls.items():
        n = len(s.log)
        with pytest.raises(Exception, match=f"{name}.*status 3"):
            call()
        assert len(s.log) == n + 1 and s.log[-1][0] == 3 and s.log[-1][1], name
    s.free()


def test_wrong_instantiation_token_and_event_mode_are_refused(fmu3_paths):
    md = read_model_description(str(fmu3_paths["lumped"]))
    d = extract(str(fmu3_paths["lumped"]))
    log = []

    def logger(env, status, category, message):
        log.append(message.decode())

    wrong = md.guid[:-2] + ("1" if md.guid[-2] == "0" else "0") + "}"  # differs from the token whatever it is
    for guid, event_mode, text in ((wrong, False, "instantiation token"),
                                   (md.guid, True, "no event mode")):
        f = FMU3Slave(guid=guid, unzipDirectory=d, modelIdentifier="DamperLumped", instanceName="x")
        with pytest.raises(Exception, match="Failed to instantiate"):
            f.instantiate(logMessage=logger, eventModeUsed=event_mode)
        assert text in log[-1]
        f.freeLibrary()
    shutil.rmtree(d, ignore_errors=True)


# -- FMU state -----------------------------------------------------------------------------------

@pytest.mark.parametrize("reals", [{"time_delay": 2e-3, "friction_force": 200.0},
                                   {"hysteresis_force": 500.0, "hysteresis_displacement": 5e-4, "bypass_ratio": 0.5,
                                    "bypass_center": 1e-3, "bypass_width": 4e-3}], ids=["catalogue", "forms"])
@pytest.mark.parametrize("kind", ["lumped", "twochamber"])
def test_state_roll_back_is_exact(fmu3_paths, kind, reals):
    """Get the state at 0.2 s (the time-delay history filled, or the hysteresis force and the stroke
    seen mid-loop), step on, roll back through the state and through its serialization: the steps
    after it repeat bit for bit."""
    s = Slave3(fmu3_paths[kind])
    s.start(*sine(0.0), reals=reals)
    s.fmu.exitInitializationMode()

    def run(k0, n):
        out = []
        for k in range(k0, k0 + n):
            s.set_inputs(*sine(k * H))
            s.fmu.doStep(k * H, H)
            out.append(s.fmu.getFloat64([s.vr["force"], s.vr["time"]]))
        return out

    run(0, 200)
    state = s.fmu.getFMUState()
    blob = s.fmu.serializeFMUState(state)
    first = run(200, 300)
    s.fmu.setFMUState(state)
    assert run(200, 300) == first
    restored = s.fmu.deserializeFMUState(blob)
    s.fmu.setFMUState(restored)
    assert run(200, 300) == first
    assert first[-1][1] == 500 * H
    s.fmu.freeFMUState(state)
    s.fmu.freeFMUState(restored)
    s.close()


# -- symbols and source import -------------------------------------------------------------------

def _unzip(path, dest):
    with zipfile.ZipFile(path) as z:
        z.extractall(dest)
    return dest


@pytest.mark.skipif(shutil.which("nm") is None, reason="needs nm")
@pytest.mark.parametrize("kind", KINDS)
def test_binary_exports_the_fmi3_functions_only(fmu3_paths, kind, tmp_path):
    """nm -D: the defined dynamic symbols are exactly the 75 FMI 3.0 functions of the standard
    header (every function a co-simulation FMU must export, the inapplicable ones returning
    fmi3Error)."""
    d = _unzip(fmu3_paths[kind], tmp_path)
    binary = next((d / "binaries" / platform_tuple).glob("*.so"))
    out = subprocess.run(["nm", "-D", "--defined-only", str(binary)], capture_output=True, text=True,
                         check=True).stdout
    symbols = {line.split()[-1] for line in out.splitlines() if line.strip()}
    header = (d / "sources" / "fmi3Functions.h").read_text()
    standard = set(re.findall(r"#define\s+(fmi3\w+)\s+fmi3FullName\(\1\)", header))
    assert len(standard) == 75
    assert symbols == standard


TWO_FMU_HOST = r"""
#include <stdio.h>
#include <math.h>
#include "fmi3FunctionTypes.h"
#define DECLARE(P) \
    fmi3InstantiateCoSimulationTYPE P##fmi3InstantiateCoSimulation; \
    fmi3EnterInitializationModeTYPE P##fmi3EnterInitializationMode; \
    fmi3ExitInitializationModeTYPE P##fmi3ExitInitializationMode; fmi3SetFloat64TYPE P##fmi3SetFloat64; \
    fmi3GetFloat64TYPE P##fmi3GetFloat64; fmi3DoStepTYPE P##fmi3DoStep; fmi3FreeInstanceTYPE P##fmi3FreeInstance;
DECLARE(DamperLumped_)
DECLARE(DamperTwoChamber_)
static void logger(fmi3InstanceEnvironment e, fmi3Status s, fmi3String c, fmi3String m) {
    (void)e; (void)c; fprintf(stderr, "[%d]: %s\n", (int)s, m);
}
#define RUN(P, TOKEN) do { \
    fmi3ValueReference in[2] = {0, 1}, out = 2; \
    fmi3Float64 u[2], f, last; fmi3Boolean ev, term, early; int k; \
    fmi3Instance c = P##fmi3InstantiateCoSimulation(#P, TOKEN, "", fmi3False, fmi3False, fmi3False, fmi3False, \
                                                    NULL, 0, NULL, logger, NULL); \
    if (!c) return 1; \
    P##fmi3EnterInitializationMode(c, fmi3False, 0.0, 0.0, fmi3False, 0.0); \
    u[0] = 0.0; u[1] = 5e-3 * W; P##fmi3SetFloat64(c, in, 2, u, 2); \
    if (P##fmi3ExitInitializationMode(c) != fmi3OK) return 2; \
    for (k = 0; k < 500; k++) { \
        double t = k * 1e-3; /* the stroke as test_fmi_conformance.sine rounds it */ \
        u[0] = 5e-3 * sin(W * t); u[1] = 5e-3 * W * cos(W * t); \
        P##fmi3SetFloat64(c, in, 2, u, 2); \
        if (P##fmi3DoStep(c, k * 1e-3, 1e-3, fmi3True, &ev, &term, &early, &last) != fmi3OK) return 3; \
        P##fmi3GetFloat64(c, &out, 1, &f, 1); printf(#P " %.17g\n", f); \
    } \
    P##fmi3FreeInstance(c); } while (0)
#define W (2.0 * 3.141592653589793 * 5.0)
int main(int argc, char **argv) {
    if (argc < 3) return 9;
    RUN(DamperLumped_, argv[1]);
    RUN(DamperTwoChamber_, argv[2]);
    return 0;
}
"""


@pytest.mark.skipif(CC is None, reason="needs a C compiler")
def test_two_fmus_sources_compile_into_one_program_with_the_function_prefix(fmu_paths, fmu3_paths, tmp_path):
    """Source-code import (FMI 3.0): the sources/ of DamperLumped3 and DamperTwoChamber3, each
    compiled with FMI3_FUNCTION_PREFIX=<modelIdentifier>_ as buildDescription.xml lists them, link
    into one executable (no duplicate symbol) whose forces equal the FMI 2.0 FMUs' (run by fmpy)
    bit for bit (compiled with -ffp-contract=off as the shipped binaries)."""
    objects, tokens, ref = [], [], {}
    for kind in ("lumped", "twochamber"):
        d = _unzip(fmu3_paths[kind], tmp_path / kind)
        md = read_model_description(str(fmu3_paths[kind]))
        ident = md.coSimulation.modelIdentifier
        for name in md.buildConfigurations[0].sourceFileSets[0].sourceFiles:
            obj = tmp_path / f"{ident}_{name}.o"
            subprocess.run([CC, "-c", "-std=c99", "-O2", "-ffp-contract=off", f"-DFMI3_FUNCTION_PREFIX={ident}_",
                            "-I", str(d / "sources"), str(d / "sources" / name), "-o", str(obj)], check=True)
            objects.append(str(obj))
            # every global symbol carries the model identifier: the FMI functions their prefix, the generated
            # values (damper_fmu_values.c) their names
            nm = subprocess.run(["nm", "--defined-only", "-g", str(obj)], capture_output=True, text=True).stdout
            assert all(line.split()[-1].startswith(f"{ident}_fmi3") for line in nm.splitlines() if line.strip())
        tokens.append(md.guid)
        ref[ident] = stroke_run(fmu_paths[kind], exact_and_jittered(500)[0])
    host = tmp_path / "host.c"
    host.write_text(TWO_FMU_HOST)
    exe = tmp_path / "host"
    link = subprocess.run([CC, "-std=c99", "-O2", "-I", str(tmp_path / "lumped" / "sources"), str(host), *objects,
                           "-o", str(exe), "-lm"], capture_output=True, text=True)
    assert link.returncode == 0, link.stderr
    run = subprocess.run([str(exe), *tokens], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    got = {}
    for line in run.stdout.splitlines():
        name, value = line.split()
        got.setdefault(name.rstrip("_"), []).append(float(value))
    for ident, forces in ref.items():
        np.testing.assert_array_equal(got[ident], forces)


def test_fmi2_and_fmi3_binaries_of_one_model_share_a_process(fmu_paths, fmu3_paths):
    """The FMI 2.0 and 3.0 binaries of one model (same model identifier, same file name) loaded into
    one process, instances interleaved step by step: each gives the forces it gives alone."""
    exact, _ = exact_and_jittered(300)
    s2 = Slave(fmu_paths["lumped"])
    s3 = Slave3(fmu3_paths["lumped"])
    s2.start(*sine(0.0))
    s3.start(*sine(0.0))
    s2.fmu.exitInitializationMode()
    s3.fmu.exitInitializationMode()
    f2, f3 = [], []
    for k, (t, h) in enumerate(exact):
        s2.set_inputs(*sine(k * H))
        s3.set_inputs(*sine(k * H))
        s2.fmu.doStep(t, h)
        s3.fmu.doStep(t, h)
        f2.append(s2.force())
        f3.append(s3.force())
    s2.close()
    s3.close()
    ref = stroke_run(fmu_paths["lumped"], exact)
    np.testing.assert_array_equal(f2, ref)
    np.testing.assert_array_equal(f3, ref)


def test_tuned_fmi3_fmu_equals_the_tuned_fmi2_fmu(tmp_path):
    """build(..., start_values=identified, fmi_version=3), as the tuner exports a tuned FMU: its
    start values are the identified ones and its forces equal the tuned FMI 2.0 FMU's."""
    from damper_fmu.parameters import MODEL_PARAMETERS

    preset = {p.name: p.default for p in MODEL_PARAMETERS["lumped"]}
    values = {"k_B": 0.5 * preset["k_B"], "c_B": 1.5 * preset["c_B"], "Fc_14": 1.2 * preset["Fc_14"],
              "friction_force": 150.0}
    paths = [build("lumped", tmp_path, start_values=values, filename=f"tuned{v}.fmu", fmi_version=v) for v in (2, 3)]
    for p in paths:
        start = {v.name: v.start for v in read_model_description(str(p)).modelVariables}
        assert all(float(start[k]) == v for k, v in values.items())
    exact, _ = exact_and_jittered(3000)
    ref = stroke_run(paths[0], exact)
    np.testing.assert_array_equal(stroke_run3(paths[1], exact), ref)
    with pytest.raises(ValueError, match="native only"):
        build("lumped", tmp_path, flavour="python", fmi_version=3)
