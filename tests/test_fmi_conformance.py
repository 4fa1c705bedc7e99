"""The native FMUs driven as different FMI masters drive them (issue 28): the step size as
(k+1)h - kh, ... Each test states the master behaviour it stands for."""
import ctypes
import json
import math
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

from damper_fmu.integrator import EXTRAPOLATE, REPLAY, Simulator
from damper_fmu.models import make_model

KINDS = ["lumped", "maxwell", "maxwell_table", "twochamber"]
H = 1e-3


def sine(t, amp=5e-3, freq=5.0):
    w = 2 * np.pi * freq
    return amp * math.sin(w * t), amp * w * math.cos(w * t)


class Slave:
    """One FMU instance through fmpy's raw FMI 2.0 calls."""

    def __init__(self, path, name="damper"):
        self.md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.dir = extract(str(path))
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        self.log = []  # (status, message) as the FMU logs them

        def logger(env, instance, status, category, message):
            self.log.append((status, message.decode("utf-8", "replace") if message else ""))

        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(logger)
        self._callbacks.allocateMemory = defaultCallbacks.allocateMemory
        self._callbacks.freeMemory = defaultCallbacks.freeMemory
        self.fmu.instantiate(callbacks=self._callbacks)

    def start(self, x0=0.0, v0=0.0, t0=0.0, reals=None):
        self.fmu.setupExperiment(startTime=t0)
        self.fmu.enterInitializationMode()
        if reals:
            self.fmu.setReal([self.vr[k] for k in reals], list(reals.values()))
        self.set_inputs(x0, v0)

    def set_inputs(self, x, v):
        self.fmu.setReal([self.vr["stroke"], self.vr["stroke_velocity"]], [x, v])

    def force(self):
        return self.fmu.getReal([self.vr["force"]])[0]

    def close(self):
        self.fmu.terminate()
        self.free()

    def free(self):
        """Free the instance and delete the extracted FMU."""
        self.fmu.freeInstance()
        shutil.rmtree(self.dir, ignore_errors=True)


def stroke_run(path, steps, input_mode=EXTRAPOLATE):
    """Force after each step of a 5 Hz, 5 mm sine; ``steps``: (communication point, step size)
    pairs as the master passes them."""
    s = Slave(path)
    s.start(*sine(0.0))
    if input_mode != EXTRAPOLATE:
        s.fmu.setInteger([s.vr["input_interpolation"]], [input_mode])
    s.fmu.exitInitializationMode()
    out = []
    for k, (t, h) in enumerate(steps):
        # the stroke at this communication point, or at the next one (REPLAY)
        s.set_inputs(*sine((k + 1) * H if input_mode == REPLAY else k * H))
        s.fmu.doStep(t, h)  # fmpy raises on an error status
        out.append(s.force())
    s.close()
    return np.array(out)


def exact_and_jittered(n, h=H):
    exact = [(k * h, h) for k in range(n)]
    # fmpy's simulate_fmu and libcosim: the step is the difference of two communication points
    jittered = [(k * h, (k + 1) * h - k * h) for k in range(n)]
    return exact, jittered


@pytest.mark.parametrize("kind", KINDS)
def test_force_does_not_depend_on_the_last_bits_of_the_step_size(fmu_paths, kind):
    """20 s of a 5 Hz, 5 mm sine: forces with exact steps of 1 ms and with steps of (k+1)h - kh
    (most of which differ from 1 ms by float jitter) are bit-identical."""
    exact, jittered = exact_and_jittered(20000)
    assert sum(h != H for _, h in jittered) > 19000  # the jitter is real
    assert max(abs(h - H) for _, h in jittered) > 1e-12 * H
    for mode in (EXTRAPOLATE, REPLAY):
        a, b = stroke_run(fmu_paths[kind], exact, mode), stroke_run(fmu_paths[kind], jittered, mode)
        assert np.abs(a).max() > 100.0
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("mode", [EXTRAPOLATE, REPLAY])
def test_python_reference_is_equally_independent_of_step_jitter(mode):
    """The Python integrator (behind the pythonfmu FMUs) divides the step the same way."""
    exact, jittered = exact_and_jittered(5000)
    forces = []
    for steps in (exact, jittered):
        sim = Simulator(make_model("lumped"), input_mode=mode)
        sim.initialize(*sine(0.0))
        forces.append([sim.step(h, *sine((k + 1) * H if mode == REPLAY else k * H))
                       for k, (t, h) in enumerate(steps)])
    np.testing.assert_array_equal(*forces)


@pytest.mark.parametrize("tolerance", [0.0, 1e-4])
def test_a_step_a_hair_longer_than_max_step_takes_one_sub_step(tolerance):
    """h = max_step (1 + 1e-15): the same single sub-step as h = max_step, no sliver after it;
    two exact sub-steps of 0.5 ms differ (the division is not ignored)."""
    results = {}
    for h in (H, H * (1 + 1e-15), H * (1 + 4e-12)):
        sim = Simulator(make_model("lumped"), max_step=H, tolerance=tolerance)
        sim.initialize(0.0, 0.1)
        results[h] = [sim.step(h, 1e-4 * k, 0.1) for k in range(5)]
    assert len(set(map(tuple, results.values()))) == 1
    sim = Simulator(make_model("lumped"), max_step=H / 2, tolerance=tolerance)
    sim.initialize(0.0, 0.1)
    assert [sim.step(H, 1e-4 * k, 0.1) for k in range(5)] != results[H]


# -- symbols and source import -------------------------------------------------------------------

def _unzip(path, dest):
    with zipfile.ZipFile(path) as z:
        z.extractall(dest)
    return dest


def _standard_function_names(header):
    """The FMI 2.0 function names as the standard header lists them (#define fmi2X fmi2FullName(fmi2X))."""
    return set(re.findall(r"#define\s+(fmi2\w+)\s+fmi2FullName\(\1\)", header.read_text()))


@pytest.mark.skipif(shutil.which("nm") is None, reason="needs nm")
@pytest.mark.parametrize("kind", KINDS)
def test_binary_exports_the_fmi_functions_only(fmu_paths, kind, tmp_path):
    """nm -D: the defined dynamic symbols are exactly the FMI 2.0 functions of the standard header."""
    d = _unzip(fmu_paths[kind], tmp_path)
    binary = next((d / "binaries").rglob("*.so"))
    out = subprocess.run(["nm", "-D", "--defined-only", str(binary)], capture_output=True, text=True,
                         check=True).stdout
    symbols = {line.split()[-1] for line in out.splitlines() if line.strip()}
    standard = _standard_function_names(d / "sources" / "fmi2Functions.h")
    assert len(standard) == 44
    assert symbols == standard


TWO_FMU_HOST = r"""
#include <stdio.h>
#include <stdlib.h>
#include <math.h>
#include "fmi2FunctionTypes.h"
#define DECLARE(P) \
    fmi2InstantiateTYPE P##fmi2Instantiate; fmi2SetupExperimentTYPE P##fmi2SetupExperiment; \
    fmi2EnterInitializationModeTYPE P##fmi2EnterInitializationMode; \
    fmi2ExitInitializationModeTYPE P##fmi2ExitInitializationMode; fmi2SetRealTYPE P##fmi2SetReal; \
    fmi2GetRealTYPE P##fmi2GetReal; fmi2DoStepTYPE P##fmi2DoStep; fmi2FreeInstanceTYPE P##fmi2FreeInstance;
DECLARE(DamperLumped_)
DECLARE(DamperTwoChamber_)
static void logger(fmi2ComponentEnvironment e, fmi2String n, fmi2Status s, fmi2String c, fmi2String m, ...) {
    (void)e; (void)c; fprintf(stderr, "%s [%d]: %s\n", n, (int)s, m);
}
#define RUN(P, GUID) do { \
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL}; \
    fmi2ValueReference in[2] = {0, 1}, out = 2; \
    fmi2Real u[2], f; int k; \
    fmi2Component c = P##fmi2Instantiate(#P, fmi2CoSimulation, GUID, "", &cb, fmi2False, fmi2False); \
    if (!c) return 1; \
    P##fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0); \
    P##fmi2EnterInitializationMode(c); \
    u[0] = 0.0; u[1] = 5e-3 * W; P##fmi2SetReal(c, in, 2, u); \
    if (P##fmi2ExitInitializationMode(c) != fmi2OK) return 2; \
    for (k = 0; k < 500; k++) { \
        u[0] = 5e-3 * sin(W * k * 1e-3); u[1] = 5e-3 * W * cos(W * k * 1e-3); \
        P##fmi2SetReal(c, in, 2, u); \
        if (P##fmi2DoStep(c, k * 1e-3, 1e-3, fmi2True) != fmi2OK) return 3; \
        P##fmi2GetReal(c, &out, 1, &f); printf(#P " %.17g\n", f); \
    } \
    P##fmi2FreeInstance(c); } while (0)
#define W (2.0 * 3.141592653589793 * 5.0)
int main(int argc, char **argv) {
    if (argc < 3) return 9;
    RUN(DamperLumped_, argv[1]);
    RUN(DamperTwoChamber_, argv[2]);
    return 0;
}
"""


@pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None, reason="needs a C compiler")
def test_two_fmus_sources_compile_into_one_program_with_the_function_prefix(fmu_paths, tmp_path):
    """Source-code import: the sources/ of DamperLumped and DamperTwoChamber, each compiled with
    FMI2_FUNCTION_PREFIX=<modelIdentifier>_ as buildDescription.xml lists them, link into one
    executable (no duplicate symbol) whose forces equal the shipped binaries' (run by fmpy)."""
    cc = shutil.which("cc") or shutil.which("gcc")
    objects, guids, ref = [], [], {}
    for kind in ("lumped", "twochamber"):
        d = _unzip(fmu_paths[kind], tmp_path / kind)
        md = read_model_description(str(fmu_paths[kind]))
        ident = md.coSimulation.modelIdentifier
        bd = ET.parse(d / "sources" / "buildDescription.xml").getroot()
        sources = [f.get("name") for f in bd.iter("SourceFile")]
        for name in sources:
            obj = tmp_path / f"{ident}_{name}.o"
            subprocess.run([cc, "-c", "-std=c99", "-O2", f"-DFMI2_FUNCTION_PREFIX={ident}_", "-I", str(d / "sources"),
                            str(d / "sources" / name), "-o", str(obj)], check=True)
            objects.append(str(obj))
        guids.append(md.guid)
        exact, _ = exact_and_jittered(500)
        ref[ident] = stroke_run(fmu_paths[kind], exact)
    host = tmp_path / "host.c"
    host.write_text(TWO_FMU_HOST)
    exe = tmp_path / "host"
    link = subprocess.run([cc, "-std=c99", "-O2", "-I", str(tmp_path / "lumped" / "sources"), str(host), *objects,
                           "-o", str(exe), "-lm"], capture_output=True, text=True)
    assert link.returncode == 0, link.stderr
    run = subprocess.run([str(exe), *guids], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    got = {}
    for line in run.stdout.splitlines():
        name, value = line.split()
        got.setdefault(name.rstrip("_"), []).append(float(value))
    for ident, forces in ref.items():
        np.testing.assert_allclose(got[ident], forces, rtol=0, atol=1e-9 * np.abs(forces).max())


RTLD_GLOBAL_SCRIPT = r"""
import ctypes, json, sys
import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
paths = sys.argv[1:]
dirs = [extract(p) for p in paths]
mds = [read_model_description(p) for p in paths]
for d, md in zip(dirs, mds):  # as a host that loads every FMU into the global namespace
    import glob
    ctypes.CDLL(glob.glob(str(d) + "/binaries/*/*.so")[0], mode=ctypes.RTLD_GLOBAL)
out = {}
for d, md in zip(dirs, mds):
    f = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="x")
    f.instantiate(); f.setupExperiment(startTime=0.0); f.enterInitializationMode()
    w = 2 * np.pi * 5
    f.setReal([0, 1], [0.0, 5e-3 * w]); f.exitInitializationMode()
    forces = []
    for k in range(400):
        t = k * 1e-3
        f.setReal([0, 1], [5e-3 * np.sin(w * t), 5e-3 * w * np.cos(w * t)])
        if k == 200:  # serialize, run on, roll back through the serialized state
            s = f.serializeFMUstate(f.getFMUstate())
            f.doStep(t, 1e-3); f.doStep(t + 1e-3, 1e-3)
            f.setFMUstate(f.deSerializeFMUstate(s))
        f.doStep(t, 1e-3)
        forces.append(f.getReal([2])[0])
    f.terminate(); f.freeInstance()
    out[md.coSimulation.modelIdentifier] = forces
import shutil
for d in dirs:
    shutil.rmtree(d, ignore_errors=True)
print(json.dumps(out))
"""


def test_two_fmus_loaded_with_rtld_global_in_one_process(fmu_paths, tmp_path):
    """A host that dlopens FMUs with RTLD_GLOBAL (one process, both binaries in the global symbol
    namespace): each FMU runs its own code, state serialization included, and gives the forces
    it gives alone."""
    paths = [str(fmu_paths[k]) for k in ("lumped", "twochamber")]
    run = subprocess.run([sys.executable, "-c", RTLD_GLOBAL_SCRIPT, *paths], capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stderr
    got = json.loads(run.stdout)
    exact, _ = exact_and_jittered(400)
    for kind, path in zip(("lumped", "twochamber"), paths):
        ident = read_model_description(path).coSimulation.modelIdentifier
        np.testing.assert_array_equal(got[ident], stroke_run(path, exact))


# -- initialization mode -------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["lumped", "twochamber"])
@pytest.mark.parametrize("velocity", [0.0, 0.01])
def test_initial_force_is_read_in_initialization_mode(fmu_paths, kind, velocity):
    """Between fmi2EnterInitializationMode and fmi2ExitInitializationMode the force is the initial
    output: the model starts force-free, so it is the preload plus the friction
    Ff tanh(v / v_eps) at the initial velocity (parameter definitions), and it stays so on exit."""
    preload, ff, v_eps = 1234.0, 300.0, 5e-4
    s = Slave(fmu_paths[kind])
    s.start(2e-3, velocity, reals={"preload_force": preload, "friction_force": ff, "friction_velocity": v_eps})
    expected = preload + ff * math.tanh(velocity / v_eps)
    assert s.force() == pytest.approx(expected, rel=1e-12)
    s.fmu.exitInitializationMode()
    assert s.force() == pytest.approx(expected, rel=1e-12)
    s.close()


@pytest.mark.parametrize("kind", ["maxwell", "maxwell_table"])
def test_maxwell_initial_force_is_zero_in_initialization_mode(fmu_paths, kind):
    s = Slave(fmu_paths[kind])
    s.start(3e-3, 0.05)
    assert s.force() == 0.0
    s.close()


def test_bad_parameters_fail_the_initial_output_with_their_name(fmu_paths):
    """A parameter the model refuses makes the initial output an fmi2Error that names it."""
    s = Slave(fmu_paths["lumped"])
    s.start(reals={"M_P": 0.0})
    with pytest.raises(Exception, match="fmi2GetReal"):
        s.force()
    assert any(status == 3 and "M_P" in text for status, text in s.log), s.log
    s.free()


# -- model structure -----------------------------------------------------------------------------

@pytest.mark.parametrize("kind", KINDS)
def test_outputs_declare_no_direct_feedthrough_and_it_is_true(fmu_paths, kind):
    """ModelStructure/Outputs: dependencies="" (no input acts on an output before the next doStep),
    which the FMU does: after a step, new inputs leave every output unchanged until the next step.
    The initial unknowns depend on the inputs (the friction acts at the initial velocity). fmpy's
    validator accepts the description."""
    md = read_model_description(str(fmu_paths[kind]))
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(fmu_paths[kind])) == []
    outputs = [v for v in md.modelVariables if v.causality == "output"]
    inputs = {v.name for v in md.modelVariables if v.causality == "input"}
    assert [u.variable for u in md.outputs] == outputs
    assert all(u.dependencies == [] for u in md.outputs)
    for u in md.initialUnknowns:
        names = {v.name for v in u.dependencies}
        assert {"stroke", "stroke_velocity"} <= names and names & inputs <= {"stroke", "stroke_velocity"}
    s = Slave(fmu_paths[kind])
    s.start(*sine(0.0))
    s.fmu.exitInitializationMode()
    vrs = [v.valueReference for v in outputs]
    for k in range(20):
        s.set_inputs(*sine(k * H))
        s.fmu.doStep(k * H, H)
    before = s.fmu.getReal(vrs)
    s.set_inputs(4e-3, -0.3)  # far from the stroke reached
    assert s.fmu.getReal(vrs) == before
    s.fmu.doStep(20 * H, H)
    assert s.fmu.getReal(vrs) != before
    s.close()


# -- an importer's build flags -------------------------------------------------------------------

FLAGS_SCRIPT = r"""
import json, math, sys
sys.path.insert(0, sys.argv[3])
from test_fmi_conformance import Slave, sine, H
s = Slave(sys.argv[1])
s.start(*sine(0.0))
s.fmu.exitInitializationMode()
out, error = [], None
try:
    for k in range(int(sys.argv[2])):
        x, v = sine(k * H)
        if k == 300:
            # a NaN acceleration from the master: not used (the acceleration is estimated)
            s.fmu.setRealInputDerivatives([s.vr["stroke_velocity"]], [1], [float("nan")])
        if k == 1000:
            v = float("nan")  # a NaN input: fmi2Error with a message, not a hang or a NaN force
        s.set_inputs(x, v)
        s.fmu.doStep(k * H, H)
        out.append(s.force())
except Exception as exc:
    error = str(exc)
import shutil
shutil.rmtree(s.dir, ignore_errors=True)  # the extracted FMU
print(json.dumps({"forces": out, "error": error, "log": [m for st, m in s.log if st >= 3]}))
"""


def _rebuild(path, tmp_path, flags):
    """The FMU with its binary compiled from sources/ (buildDescription.xml's files) with ``flags``."""
    cc = shutil.which("cc") or shutil.which("gcc")
    d = _unzip(path, tmp_path / "fmu")
    binary = next((d / "binaries").rglob("*.so"))
    src = d / "sources"
    files = [str(src / f.get("name")) for f in ET.parse(src / "buildDescription.xml").getroot().iter("SourceFile")]
    subprocess.run([cc, "-std=c99", *flags, "-shared", "-fPIC", "-I", str(src), *files, "-o", str(binary), "-lm"],
                   check=True)
    out = tmp_path / path.name
    with zipfile.ZipFile(out, "w") as z:
        for f in d.rglob("*"):
            if f.is_file():
                z.write(f, f.relative_to(d).as_posix())
    return out


@pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None, reason="needs a C compiler")
@pytest.mark.parametrize("flags", [["-O2", "-ffast-math"], ["-O2", "-ffinite-math-only"], ["-O0"],
                                   ["-O3", "-march=native"]])
@pytest.mark.parametrize("kind", KINDS)
def test_importer_build_flags_give_a_result_or_an_error_never_a_hang(fmu_paths, tmp_path, kind, flags):
    """sources/ compiled with an importer's flags, run under a time limit: the stroke gives the
    shipped binary's forces (to the rounding the flags change), a NaN input an fmi2Error with its
    message, in time: no hang, no NaN returned as fmi2OK."""
    fmu = _rebuild(fmu_paths[kind], tmp_path, flags)
    run = subprocess.run([sys.executable, "-c", FLAGS_SCRIPT, str(fmu), "1200", str(Path(__file__).parent)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    got = json.loads(run.stdout)
    forces = np.array(got["forces"])
    assert len(forces) == 1000 and np.all(np.isfinite(forces))
    assert got["error"] and "fmi2DoStep" in got["error"]
    assert any("non-finite input" in m for m in got["log"]), got["log"]
    exact, _ = exact_and_jittered(1000)
    ref = stroke_run(fmu_paths[kind], exact)
    np.testing.assert_allclose(forces, ref, rtol=0, atol=1e-9 * np.abs(ref).max())


# -- source builds -------------------------------------------------------------------------------

def test_build_description_matches_the_model_description(fmu_paths, tmp_path):
    """sources/buildDescription.xml declares the FMU's FMI version (2.0), the files of the model
    description's SourceFiles and the math library."""
    d = _unzip(fmu_paths["lumped"], tmp_path)
    md = read_model_description(str(fmu_paths["lumped"]))
    root = ET.parse(d / "sources" / "buildDescription.xml").getroot()
    assert root.get("fmiVersion") == md.fmiVersion == "2.0"
    assert [f.get("name") for f in root.iter("SourceFile")] == md.buildConfigurations[0].sourceFileSets[0].sourceFiles
    assert [lib.get("name") for lib in root.iter("Library")] == ["m"]


PLAIN_HOST = r"""
#include <dlfcn.h>
#include <stdio.h>
int main(int argc, char **argv) {
    void *h = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!h) { printf("%s\n", dlerror()); return 1; }
    return dlsym(h, "fmi2DoStep") ? 0 : 2;
}
"""


@pytest.mark.skipif(shutil.which("cmake") is None or shutil.which("readelf") is None, reason="needs cmake, readelf")
def test_fmpy_cmake_build_of_the_sources_links_libm_and_equals_the_shipped_binary(fmu_paths, tmp_path):
    """fmpy's CMake project builds sources/; fmpy reads an FMI 2.0 FMU's SourceFiles only and drops
    <Library> elements, so the importer passes the math library as CMake's standard libraries. The
    binary then needs libm, loads in a C host that is not linked with libm, and gives the shipped
    binary's forces."""
    from fmpy.build import build_platform_binary

    cc = shutil.which("cc") or shutil.which("gcc")
    d = _unzip(fmu_paths["lumped"], tmp_path / "fmu")
    binary = next((d / "binaries").rglob("*.so"))
    binary.unlink()
    (tmp_path / "build").mkdir()
    build_platform_binary(d.resolve(), tmp_path / "build", cmake_options={"CMAKE_C_STANDARD_LIBRARIES": "-lm"})
    needed = subprocess.run(["readelf", "-d", str(binary)], capture_output=True, text=True, check=True).stdout
    assert "libm.so" in needed
    host = tmp_path / "host.c"
    host.write_text(PLAIN_HOST)
    subprocess.run([cc, str(host), "-o", str(tmp_path / "host")], check=True)
    assert "libm" not in subprocess.run(["ldd", str(tmp_path / "host")], capture_output=True, text=True).stdout
    load = subprocess.run([str(tmp_path / "host"), str(binary)], capture_output=True, text=True, timeout=60)
    assert load.returncode == 0, load.stdout
    rebuilt = tmp_path / "rebuilt.fmu"
    with zipfile.ZipFile(rebuilt, "w") as z:
        for f in d.rglob("*"):
            if f.is_file():
                z.write(f, f.relative_to(d).as_posix())
    exact, _ = exact_and_jittered(1000)
    np.testing.assert_array_equal(stroke_run(rebuilt, exact), stroke_run(fmu_paths["lumped"], exact))


# -- status inquiries ----------------------------------------------------------------------------

def test_status_inquiries_the_slave_cannot_answer_are_discard_without_an_error_log(fmu_paths):
    """FMI 2.0 (4.2.3): a status the slave cannot give is fmi2Discard. Steps never pend, so
    fmi2DoStepStatus and fmi2PendingStatus cannot be given; fmi2LastSuccessfulTime and
    fmi2Terminated (never asked for) can."""
    s = Slave(fmu_paths["lumped"])
    s.start(*sine(0.0))
    s.fmu.exitInitializationMode()
    s.set_inputs(*sine(0.0))
    s.fmu.doStep(0.0, H)
    dll, c = s.fmu.dll, s.fmu.component
    DO_STEP, PENDING, LAST_TIME, TERMINATED = 0, 1, 2, 3  # fmi2StatusKind
    DISCARD = 2
    for fn, ctype in (("fmi2GetStatus", ctypes.c_int), ("fmi2GetIntegerStatus", ctypes.c_int),
                      ("fmi2GetStringStatus", ctypes.c_char_p), ("fmi2GetRealStatus", ctypes.c_double),
                      ("fmi2GetBooleanStatus", ctypes.c_int)):
        f = getattr(dll, fn)
        f.restype = ctypes.c_int
        for kind in (DO_STEP, PENDING) + ((LAST_TIME, TERMINATED) if fn in ("fmi2GetStatus",) else ()):
            value = ctype()
            assert f(c, kind, ctypes.byref(value)) == DISCARD, (fn, kind)
    t = ctypes.c_double()
    assert dll.fmi2GetRealStatus(c, LAST_TIME, ctypes.byref(t)) == 0 and t.value == H
    b = ctypes.c_int(7)
    assert dll.fmi2GetBooleanStatus(c, TERMINATED, ctypes.byref(b)) == 0 and b.value == 0
    assert not [m for st, m in s.log if st >= 3], s.log
    s.close()


def test_a_wrong_guid_is_refused_with_a_message_naming_the_binarys(fmu_paths):
    """fmi2Instantiate with another GUID returns NULL and says which GUID the binary has, as a plain message (a
    logger written in Python reads no C varargs: the message must not carry a conversion)."""
    md = read_model_description(str(fmu_paths["lumped"]))
    d = extract(str(fmu_paths["lumped"]))
    log = []

    def logger(env, instance, status, category, message):
        log.append(message.decode())

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(logger)
    callbacks.allocateMemory, callbacks.freeMemory = defaultCallbacks.allocateMemory, defaultCallbacks.freeMemory
    wrong = md.guid[:-2] + ("1" if md.guid[-2] == "0" else "0") + "}"
    f = FMU2Slave(guid=wrong, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="x")
    with pytest.raises(Exception, match="Failed to instantiate"):
        f.instantiate(callbacks=callbacks)
    assert md.guid in log[-1] and "GUID does not match" in log[-1] and "%" not in log[-1]
    f.freeLibrary()
    shutil.rmtree(d, ignore_errors=True)
