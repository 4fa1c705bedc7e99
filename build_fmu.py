"""Build the damper FMUs (FMI 2.0 co-simulation, FMI 3.0 on request) and validate them with fmpy.

Usage:  python build_fmu.py [--out DIR] [--force] [--python] [--fmi-version 2|3 ...] [lumped maxwell ...]

Two flavours of every damper model, equal to 1e-9 (tests/test_native.py, tests/test_fmu.py):

* **native** (default; ``DamperLumped.fmu``, ``DamperMaxwell.fmu``, ``DamperMaxwellTable.fmu``):
  C against the FMI 2.0 headers, linked to libc/libm only. The binary for this platform is built
  with the system C compiler; the C sources are inside the FMU (``sources/``, listed in the model
  description's ``SourceFiles`` and in ``sources/buildDescription.xml``) so an importer on another
  platform can compile it. Needs no Python on the importing machine.
* **native FMI 3.0** (``--fmi-version 3``; ``DamperLumped3.fmu`` ...): the same kernel and
  variables behind the FMI 3.0 co-simulation interface (``damper_fmu/c/fmi3_damper.c``), forces
  equal to the FMI 2.0 FMU's bit for bit (tests/test_fmi3.py). A separate archive per FMI version:
  an FMU holds one modelDescription.xml, of one version.
* **python** (``DamperLumpedPy.fmu`` ...; pythonfmu, as the design card asks): the importing tool
  needs a Python 3 interpreter with numpy (``needsExecutionTool="true"``).

Built FMUs go to ``build/fmu/`` in the project folder (git-ignored) unless ``--out`` or the
environment variable ``DAMPER_FMU_DIR`` says otherwise. A stamp file next to each records a hash
of its sources so ``ensure_fmu`` rebuilds only when they changed. Without a C compiler
``ensure_fmu`` gives the Python FMU and ``fast_path_note()`` says why.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import uuid
import zipfile
from pathlib import Path
from xml.etree.ElementTree import Element, SubElement, tostring

from damper_fmu.integrator import DEFAULT_MAX_STEP, DEFAULT_TOLERANCE, INPUT_INTERPOLATION_DESCRIPTION

ROOT = Path(__file__).resolve().parent
SRC = ROOT / "fmu_src"
PACKAGE = ROOT / "damper_fmu"
C_DIR = PACKAGE / "c"
#: native FMUs: model kind -> model identifier (file name without .fmu)
SLAVES = {
    "lumped": "DamperLumped",
    "maxwell": "DamperMaxwell",
    "maxwell_table": "DamperMaxwellTable",
    "twochamber": "DamperTwoChamber",
}
#: pythonfmu FMUs: model kind -> slave class (model identifier); 'empty' has no physics (benchmark)
PY_SLAVES = {
    "lumped": "DamperLumpedPy",
    "maxwell": "DamperMaxwellPy",
    "maxwell_table": "DamperMaxwellTablePy",
    "twochamber": "DamperTwoChamberPy",
    "empty": "EmptyDamper",
}
BUILD_OPTIONS = {"canGetAndSetFMUstate": True, "canSerializeFMUstate": True}
#: file name of a native FMU of an FMI version: model identifier + this + '.fmu' (the model identifier,
#: binary name and function prefix stay the same across versions, as in the Modelica Reference-FMUs)
FMI_SUFFIX = {2: "", 3: "3"}
#: start values of the native FMUs' settings: name -> (value, unit, description)
NATIVE_SETTINGS = {
    "max_internal_step": (DEFAULT_MAX_STEP, "s", "Largest internal integration step"),
    "internal_tolerance": (DEFAULT_TOLERANCE, "", "Local error tolerance of the internal steps, relative to the damper's "
                                     "force scale (largest |Fc,O| ordinate); 0: fixed steps of max_internal_step"),
    "stroke_limit": (1.0, "m", "Largest |stroke| accepted; beyond it fmi2DoStep returns fmi2Error (a stroke in "
                               "mm read as m)"),
    "velocity_limit": (20.0, "m/s", "Largest |stroke_velocity| accepted; beyond it fmi2DoStep returns fmi2Error"),
}
_SETTING_VR = {"max_internal_step": 50, "internal_tolerance": 51, "stroke_limit": 52, "velocity_limit": 53}


def default_dir() -> Path:
    """Folder of the built FMUs: $DAMPER_FMU_DIR or <project>/build/fmu."""
    return Path(os.environ.get("DAMPER_FMU_DIR", ROOT / "build" / "fmu"))


def _source_hash(flavour: str) -> str:
    h = hashlib.sha256(flavour.encode())
    if flavour == "python":
        import pythonfmu

        h.update(pythonfmu.__version__.encode())
        files = [*PACKAGE.glob("*.py"), *SRC.glob("*.py")]
    else:
        files = [*C_DIR.glob("*.[ch]"), *FMI2_HEADERS.glob("*.h"), *FMI3_HEADERS.glob("*.h"), PACKAGE / "parameters.py", PACKAGE / "models.py",
                 PACKAGE / "integrator.py", Path(__file__)]
    for f in sorted(files):
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def native_reason() -> str:
    """Why native FMUs cannot be built here ('' when they can)."""
    from damper_fmu import native

    return "" if native.compiler() else "no C compiler found (set CC or install gcc)"


def fast_path_note() -> str:
    """One line for the user when the native (fast) path is off, else ''."""
    why = native_reason()
    return (f"note: the fast path is off ({why}); using the Python FMUs and the Python engine, "
            f"several times slower" if why else "")


def _check_fmi_version(fmi_version: int, flavour: str) -> None:
    if fmi_version not in FMI_SUFFIX:
        raise ValueError(f"unknown FMI version {fmi_version!r}, expected 2 or 3")
    if fmi_version == 3 and flavour != "native":
        raise ValueError("FMI 3.0 FMUs are native only (pythonfmu builds FMI 2.0); "
                         + (native_reason() or "use flavour='native'"))


def build(kind: str, out: str | Path | None = None, *, start_values: dict | None = None,
          settings: dict | None = None, filename: str | None = None, flavour: str = "auto",
          fmi_version: int = 2) -> Path:
    """Build the FMU of ``kind`` in ``flavour`` ('native', 'python', or 'auto': native where a C
    compiler is found) and return its path. ``fmi_version``: 2 (default) or 3 (native only; file
    ``<model identifier>3.fmu``).

    ``start_values``: parameter name -> SI value used as start values (e.g. identified
    parameters); ``settings``: optional ``max_internal_step`` [s], ``internal_tolerance`` [-] and
    ``input_interpolation`` (0 or 1). The file is written atomically.
    """
    if flavour == "auto":
        flavour = "native" if kind in SLAVES and not native_reason() else "python"
    if flavour not in ("native", "python"):
        raise ValueError(f"unknown FMU flavour '{flavour}', expected 'native', 'python' or 'auto'")
    _check_fmi_version(fmi_version, flavour)
    names = SLAVES if flavour == "native" else PY_SLAVES
    if kind not in names:
        raise ValueError(f"unknown {flavour} FMU kind '{kind}', expected one of {sorted(names)}")
    if kind != "empty" and start_values:
        from damper_fmu.parameters import check_values

        check_values(kind, start_values)
    out = Path(out) if out is not None else default_dir()
    out.mkdir(parents=True, exist_ok=True)
    target = out / (filename or f"{names[kind]}{FMI_SUFFIX[fmi_version]}.fmu")
    if flavour == "native":
        _build_native(kind, target, start_values or {}, settings or {}, fmi_version)
        return target
    # pythonfmu imports the slave script, which must not meet a slave module an FMU already
    # loaded in the caller: build in a fresh Python process
    spec = json.dumps({"kind": kind, "target": str(target), "start_values": start_values or {},
                       "settings": settings or {}})
    proc = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--build-spec", spec],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"building {target.name} failed:\n{proc.stderr.strip()}")
    return target


def _build_here(kind: str, target: Path, start_values: dict, settings: dict) -> None:
    from pythonfmu.builder import FmuBuilder

    with tempfile.TemporaryDirectory(prefix="damper_fmu_build_") as tmp:
        tmp = Path(tmp)
        project = []
        if kind != "empty":
            project = [PACKAGE, SRC / "damper_fmi.py"]
            if start_values or settings:
                staged = tmp / "start_values.json"
                data = {k: float(v) for k, v in start_values.items()}
                data["_settings"] = dict(settings)
                staged.write_text(json.dumps(data, indent=1, sort_keys=True))
                project.append(staged)
        sys.path.insert(0, str(SRC))
        built = FmuBuilder.build_FMU(SRC / f"{PY_SLAVES[kind]}.py", dest=tmp / "out", project_files=project,
                                     **BUILD_OPTIONS)
        part = target.with_suffix(".fmu.part")
        shutil.copyfile(built, part)
        os.replace(part, target)


# -- native FMU ---------------------------------------------------------------------------------

def _platform_tuple() -> str:
    """FMI 3.0 binaries folder: <architecture>-<system> (e.g. x86_64-linux)."""
    machine = platform.machine().lower()
    arch = ("aarch64" if machine in ("aarch64", "arm64") else
            ("x86_64" if sys.maxsize > 2 ** 32 else "x86") if machine in ("amd64", "x86_64", "i386", "i686", "x86")
            else machine)
    system = {"Linux": "linux", "Darwin": "darwin", "Windows": "windows"}.get(platform.system(),
                                                                             platform.system().lower())
    return f"{arch}-{system}"


def _platform_folder() -> str:
    bits = "64" if sys.maxsize > 2 ** 32 else "32"
    system = {"Linux": "linux", "Darwin": "darwin", "Windows": "win"}.get(platform.system(), platform.system().lower())
    return f"{system}{bits}"


#: the standard FMI 2.0.x headers of the Modelica Association, unmodified (BSD-2, the licence is in
#: them; see damper_fmu/c/fmi2/ORIGIN). fmpy's copies are altered to ignore FMI2_FUNCTION_PREFIX, which
#: source-code import of several FMUs into one program needs.
FMI2_HEADERS = C_DIR / "fmi2"
#: the standard FMI 3.0 headers, unmodified (damper_fmu/c/fmi3/ORIGIN)
FMI3_HEADERS = C_DIR / "fmi3"


def _fmi_headers(fmi_version: int = 2) -> list[Path]:
    if fmi_version == 3:
        return [FMI3_HEADERS / n for n in ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")]
    return [FMI2_HEADERS / n for n in ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")]


#: FMI 3.0 value references where FMI 2.0's cannot be kept: FMI 3.0 has one value-reference space for
#: all types, so the Integer settings (FMI 2.0 Integer 0 and 1, which Real 0 and 1 also use) move,
#: and the independent variable 'time' (none in FMI 2.0) gets one. Every Real keeps its FMI 2.0 value
#: reference. fmi3_damper.c uses the same numbers.
FMI3_VR = {"time": 4, "input_interpolation": 60, "thermal_source": 61}


def _variables(kind: str, start_values: dict, settings: dict) -> list[dict]:
    """The native FMU's variables, the one list both model descriptions (FMI 2.0, 3.0) are written
    from, in FMI 2.0 order: name, vr (FMI 2.0), vr3 (FMI 3.0), type ('Real' or 'Integer'),
    causality, variability, initial, unit, start, description, and 'known': True for the inputs
    and model parameters the initial outputs depend on (value references: fmi2_damper.c)."""
    from damper_fmu.models import DIAGNOSTICS
    from damper_fmu.parameters import EFFECT_MODELS, MODEL_PARAMETERS

    out = []

    def var(name, vr, causality, variability, unit, description, start=None, initial=None, kind_="Real",
            known=False):
        out.append({"name": name, "vr": vr, "vr3": FMI3_VR.get(name, vr), "type": kind_, "causality": causality,
                    "variability": variability, "initial": initial, "unit": unit or None, "start": start,
                    "description": description, "known": known})

    var("stroke", 0, "input", "continuous", "m", "Damper stroke, positive in extension", 0.0, known=True)
    var("stroke_velocity", 1, "input", "continuous", "m/s", "Damper stroke velocity, positive in extension", 0.0,
        known=True)
    if kind in EFFECT_MODELS:
        var("oil_temperature", 3, "input", "continuous", "degC",
            "Measured oil temperature; used by the thermal drift element when thermal_source = 1", 20.0)
    var("force", 2, "output", "continuous", "N", "Damper force, positive in tension", initial="calculated")
    for i, (name, (unit, text)) in enumerate(DIAGNOSTICS[kind].items()):
        var(name, 10 + i, "output", "continuous", unit, text, initial="calculated")
    for i, p in enumerate(MODEL_PARAMETERS[kind]):
        tunable = p.tunable or p.effect
        text = (f"{p.description} [{p.unit}]; identification bounds [{p.low:g}, {p.high:g}]" if p.tunable else
                f"Effect '{p.effect}' (off at 0): {p.description} [{p.unit}], range [{p.low:g}, {p.high:g}]"
                if p.effect else f"{p.description} [{p.unit}]")
        var(p.name, 100 + i, "parameter", "tunable" if tunable else "fixed", p.unit, text,
            start_values.get(p.name, p.default), initial="exact", known=True)
    for name, (value, unit, text) in NATIVE_SETTINGS.items():
        var(name, _SETTING_VR[name], "parameter", "fixed", unit, text, settings.get(name, value), initial="exact")
    var("input_interpolation", 0, "parameter", "fixed", None, INPUT_INTERPOLATION_DESCRIPTION,
        settings.get("input_interpolation", 0), initial="exact", kind_="Integer")
    if kind in EFFECT_MODELS:
        var("thermal_source", 1, "parameter", "fixed", None,
            "Oil temperature of the thermal drift element: 0 internal thermal balance, 1 the oil_temperature input",
            0, initial="exact", kind_="Integer")
    return out


def _units(kind: str, variables: list[dict]) -> list[tuple[str, dict]]:
    """UnitDefinitions: (name, SI base-unit exponents) of the units the description uses."""
    from damper_fmu.models import DIAGNOSTICS
    from damper_fmu.parameters import MODEL_PARAMETERS, UNIT_DEFINITIONS

    used = sorted({p.unit for p in MODEL_PARAMETERS[kind]} | {"m", "m/s", "N", "s", "degC"} |
                  {u for u, _ in DIAGNOSTICS[kind].values()})
    return [(name, {k: str(e) for k, e in UNIT_DEFINITIONS[name].items()}) for name in used]


_DESCRIPTION = ("Railway hydraulic damper, {kind} model (native C; SI units, stroke positive in extension, force "
                "positive in tension)")


def _model_description(kind: str, identifier: str, guid: str, start_values: dict, settings: dict) -> bytes:
    """modelDescription.xml of the native FMI 2.0 FMU of ``kind`` (value references: fmi2_damper.c)."""
    variables = _variables(kind, start_values, settings)
    root = Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": identifier, "guid": guid,
        "description": _DESCRIPTION.format(kind=kind),
        "author": "yaw-damper-toolchain", "license": "MIT", "generationTool": "yaw-damper-toolchain build_fmu.py",
        "variableNamingConvention": "flat", "numberOfEventIndicators": "0"})
    cs = SubElement(root, "CoSimulation", {
        "modelIdentifier": identifier, "canHandleVariableCommunicationStepSize": "true",
        "canInterpolateInputs": "true", "maxOutputDerivativeOrder": "0", "canGetAndSetFMUstate": "true",
        "canSerializeFMUstate": "true", "providesDirectionalDerivative": "false",
        "canNotUseMemoryManagementFunctions": "true", "canBeInstantiatedOnlyOncePerProcess": "false"})
    files = SubElement(cs, "SourceFiles")
    # one translation unit (fmi2_damper.c includes damper_kernel.c): only the fmi2 functions have
    # external linkage
    SubElement(files, "File", {"name": "fmi2_damper.c"})
    units = SubElement(root, "UnitDefinitions")
    for name, exponents in _units(kind, variables):
        SubElement(SubElement(units, "Unit", {"name": name}), "BaseUnit", exponents)
    cats = SubElement(root, "LogCategories")
    SubElement(cats, "Category", {"name": "logStatusError", "description": "Errors with their reason"})
    SubElement(root, "DefaultExperiment", {"startTime": "0", "stopTime": "10", "stepSize": "0.001"})
    mv = SubElement(root, "ModelVariables")
    outputs, knowns = [], []
    for v in variables:
        attrs = {"name": v["name"], "valueReference": str(v["vr"]), "description": v["description"],
                 "causality": v["causality"], "variability": v["variability"]}
        if v["initial"]:
            attrs["initial"] = v["initial"]
        sv = SubElement(mv, "ScalarVariable", attrs)
        t = {}
        if v["unit"]:
            t["unit"] = v["unit"]
        if v["start"] is not None:
            t["start"] = repr(float(v["start"])) if v["type"] == "Real" else str(int(v["start"]))
        SubElement(sv, v["type"], t)
        if v["causality"] == "output":
            outputs.append(len(mv))
        if v["known"]:
            knowns.append(len(mv))
    # Dependencies (fmi2_damper.c): after initialization the outputs are those of the last doStep, and
    # fmi2SetReal of an input changes none of them before the next doStep: no direct feedthrough, so
    # no input dependencies (an importer assuming feedthrough reports algebraic loops that do not
    # exist). In initialization mode the outputs are computed from the stroke, the stroke velocity
    # (friction) and the model parameters.
    ms = SubElement(root, "ModelStructure")
    outs = SubElement(ms, "Outputs")
    for i in outputs:
        SubElement(outs, "Unknown", {"index": str(i), "dependencies": ""})
    init = SubElement(ms, "InitialUnknowns")
    initial_knowns = " ".join(str(k) for k in sorted(knowns))
    for i in outputs:
        SubElement(init, "Unknown", {"index": str(i), "dependencies": initial_knowns})
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root, encoding="utf-8")


def _model_description3(kind: str, identifier: str, token: str, start_values: dict, settings: dict) -> bytes:
    """modelDescription.xml of the native FMI 3.0 FMU of ``kind``: the variables of the FMI 2.0 one
    (``_variables``; Real as Float64, Integer as Int32, value references FMI3_VR where FMI 2.0's
    cannot be kept) plus the independent variable 'time' (value references: fmi3_damper.c)."""
    variables = _variables(kind, start_values, settings)
    root = Element("fmiModelDescription", {
        "fmiVersion": "3.0", "modelName": identifier, "instantiationToken": token,
        "description": _DESCRIPTION.format(kind=kind),
        "author": "yaw-damper-toolchain", "license": "MIT", "generationTool": "yaw-damper-toolchain build_fmu.py",
        "variableNamingConvention": "flat"})
    SubElement(root, "CoSimulation", {
        "modelIdentifier": identifier, "canHandleVariableCommunicationStepSize": "true",
        "maxOutputDerivativeOrder": "0", "canGetAndSetFMUState": "true", "canSerializeFMUState": "true",
        "providesDirectionalDerivatives": "false", "providesAdjointDerivatives": "false",
        "canBeInstantiatedOnlyOncePerProcess": "false", "hasEventMode": "false",
        "mightReturnEarlyFromDoStep": "false", "providesIntermediateUpdate": "false"})
    units = SubElement(root, "UnitDefinitions")
    for name, exponents in _units(kind, variables):
        SubElement(SubElement(units, "Unit", {"name": name}), "BaseUnit", exponents)
    cats = SubElement(root, "LogCategories")
    SubElement(cats, "Category", {"name": "logStatusError", "description": "Errors with their reason"})
    SubElement(root, "DefaultExperiment", {"startTime": "0", "stopTime": "10", "stepSize": "0.001"})
    mv = SubElement(root, "ModelVariables")
    SubElement(mv, "Float64", {"name": "time", "valueReference": str(FMI3_VR["time"]),
                               "description": "Simulation time", "causality": "independent",
                               "variability": "continuous", "unit": "s"})
    for v in variables:
        attrs = {"name": v["name"], "valueReference": str(v["vr3"]), "description": v["description"],
                 "causality": v["causality"], "variability": v["variability"]}
        if v["initial"]:
            attrs["initial"] = v["initial"]
        if v["unit"]:
            attrs["unit"] = v["unit"]
        if v["start"] is not None:
            attrs["start"] = repr(float(v["start"])) if v["type"] == "Real" else str(int(v["start"]))
        SubElement(mv, {"Real": "Float64", "Integer": "Int32"}[v["type"]], attrs)
    # dependencies as in the FMI 2.0 description (see there), by value reference
    ms = SubElement(root, "ModelStructure")
    outputs = [v["vr3"] for v in variables if v["causality"] == "output"]
    knowns = " ".join(str(k) for k in sorted(v["vr3"] for v in variables if v["known"]))
    for vr in outputs:
        SubElement(ms, "Output", {"valueReference": str(vr), "dependencies": ""})
    for vr in outputs:
        SubElement(ms, "InitialUnknown", {"valueReference": str(vr), "dependencies": knowns})
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root, encoding="utf-8")


def _build_native(kind: str, target: Path, start_values: dict, settings: dict, fmi_version: int = 2) -> None:
    from damper_fmu import native

    cc = native.compiler()
    if cc is None:
        raise RuntimeError(f"cannot build the native {SLAVES[kind]} FMU: {native_reason()}; "
                           f"use flavour='python' (pythonfmu) instead")
    identifier = SLAVES[kind]
    payload = json.dumps([kind, sorted(start_values.items()), sorted(settings.items()),
                          _source_hash("native")] + ([3] if fmi_version == 3 else [])).encode()
    guid = "{" + str(uuid.UUID(hashlib.md5(payload).hexdigest())) + "}"
    header = native.parameter_header({kind: start_values})
    config = "\n".join([
        "/* Generated by build_fmu.py: model kind, GUID and setting start values of this FMU. */",
        f"#define DK_MODEL_KIND {native.KINDS[kind]}",
        f'#define DK_GUID "{guid}"',
        f"#define DK_START_MAX_STEP {float(settings.get('max_internal_step', DEFAULT_MAX_STEP))!r}",
        f"#define DK_START_TOLERANCE {float(settings.get('internal_tolerance', DEFAULT_TOLERANCE))!r}",
        f"#define DK_START_STROKE_LIMIT {float(settings.get('stroke_limit', NATIVE_SETTINGS['stroke_limit'][0]))!r}",
        f"#define DK_START_VELOCITY_LIMIT "
        f"{float(settings.get('velocity_limit', NATIVE_SETTINGS['velocity_limit'][0]))!r}",
        f"#define DK_START_INPUT_INTERPOLATION {int(settings.get('input_interpolation', 0))}", ""])
    with tempfile.TemporaryDirectory(prefix="damper_native_fmu_") as tmp:
        tmp = Path(tmp)
        src = tmp / "sources"
        src.mkdir()
        wrapper = f"fmi{fmi_version}_damper.c"
        for f in (C_DIR / wrapper, C_DIR / "damper_kernel.c", C_DIR / "damper_kernel.h", *_fmi_headers(fmi_version)):
            shutil.copyfile(f, src / f.name)
        (src / "damper_params.h").write_text(header)
        (src / "damper_fmu_config.h").write_text(config)
        # FMI 2.0 importers read the SourceFiles of modelDescription.xml (fmpy's CMake build does, and it
        # drops <Library> elements whatever the version: an importer must link the C math library
        # itself, e.g. fmpy's build_platform_binary(..., cmake_options={"CMAKE_C_STANDARD_LIBRARIES":
        # "-lm"})). This file gives the same in the FMI 3.0 build-description layout, for tools that
        # read it, with this FMU's FMI version (for FMI 3.0 it is where the source files are declared).
        (src / "buildDescription.xml").write_text(
            '<?xml version="1.0" encoding="UTF-8"?>\n'
            f'<fmiBuildDescription fmiVersion="{fmi_version}.0">\n'
            f'  <BuildConfiguration modelIdentifier="{identifier}">\n'
            '    <SourceFileSet language="C99">\n'
            f'      <SourceFile name="{wrapper}"/>\n'
            '    </SourceFileSet>\n    <Library name="m"/>\n  </BuildConfiguration>\n</fmiBuildDescription>\n')
        suffix = {"win": ".dll", "darwin": ".dylib"}.get(_platform_folder()[:-2], ".so")
        folder = _platform_tuple() if fmi_version == 3 else _platform_folder()
        binary = tmp / "binaries" / folder / f"{identifier}{suffix}"
        binary.parent.mkdir(parents=True)
        cmd = [cc, *native.CFLAGS, "-shared", "-I", str(src), str(src / wrapper), "-o", str(binary), "-lm"]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"compiling {identifier} failed ({' '.join(cmd)}):\n{proc.stderr.strip()}")
        write = _model_description3 if fmi_version == 3 else _model_description
        (tmp / "modelDescription.xml").write_bytes(write(kind, identifier, guid, start_values, settings))
        docs = tmp / "documentation"
        docs.mkdir()
        (docs / "index.html").write_text(
            f"<html><body><h1>{identifier}</h1><p>Railway hydraulic damper ({kind} model), FMI {fmi_version}.0 "
            f"co-simulation. Inputs stroke [m] (extension +) and stroke_velocity [m/s]; output force [N] "
            f"(tension +). See the project README, section 'The FMUs', for safe communication step "
            f"sizes.</p></body></html>\n")
        part = target.with_suffix(".fmu.part")
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
            for f in sorted(tmp.rglob("*")):
                if f.is_file():
                    z.write(f, f.relative_to(tmp).as_posix())
        os.replace(part, target)


def ensure_fmu(kind: str, out: str | Path | None = None, flavour: str = "auto", fmi_version: int = 2) -> Path:
    """Path of the default FMU of ``kind``, (re)building it if missing or its sources changed.

    flavour: 'native', 'python' or 'auto' (native where a C compiler is found; 'empty' is python).
    fmi_version: 2, or 3 (native only).
    """
    if flavour == "auto":
        flavour = "native" if kind in SLAVES and not native_reason() else "python"
    _check_fmi_version(fmi_version, flavour)
    names = SLAVES if flavour == "native" else PY_SLAVES
    out = Path(out) if out is not None else default_dir()
    path = out / f"{names[kind]}{FMI_SUFFIX[fmi_version]}.fmu"

    stamp = path.with_suffix(".sha256")
    digest = _source_hash(flavour)
    if path.exists() and stamp.exists() and stamp.read_text().strip() == digest:
        return path
    build(kind, out, flavour=flavour, fmi_version=fmi_version)
    stamp.write_text(digest + "\n")
    return path


def validate(path: str | Path) -> list[str]:
    """Problems fmpy's validator reports for the FMU at ``path`` (empty list: valid)."""
    from fmpy.validation import validate_fmu

    return list(validate_fmu(str(path)))


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--build-spec"]:  # internal: one pythonfmu build in this fresh process
        spec = json.loads(argv[1])
        _build_here(spec["kind"], Path(spec["target"]), spec["start_values"], spec["settings"])
        return 0
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("kinds", nargs="*", default=list(SLAVES),
                    help=f"FMUs to build, from {sorted(PY_SLAVES)} (default: the four damper models)")
    ap.add_argument("--out", type=Path, default=None, help="output folder (default build/fmu)")
    ap.add_argument("--force", action="store_true", help="rebuild even if up to date")
    ap.add_argument("--python", action="store_true", help="also build the pythonfmu FMUs (*Py.fmu)")
    ap.add_argument("--fmi-version", type=int, choices=sorted(FMI_SUFFIX), action="append", dest="fmi_versions",
                    help="FMI version of the native FMUs: 2 (default) or 3 (<name>3.fmu); repeat for both")
    args = ap.parse_args(argv)
    bad = [k for k in args.kinds if k not in PY_SLAVES]
    if bad:
        ap.error(f"unknown FMU kind(s) {bad}; choose from {sorted(PY_SLAVES)}")
    note = fast_path_note()
    if note:
        print(note)
    versions = args.fmi_versions or [2]
    if 3 in versions and note:
        ap.error(f"FMI 3.0 FMUs are native only: {native_reason()}")
    status = 0
    for kind in args.kinds:
        if 3 in versions and kind not in SLAVES:
            ap.error(f"no FMI 3.0 FMU of '{kind}' (native models only: {sorted(SLAVES)})")
        jobs = ([("auto", 2)] if 2 in versions else []) + ([("native", 3)] if 3 in versions else [])
        jobs += [("python", 2)] if args.python and kind in SLAVES and not note else []
        for flavour, version in jobs:
            if args.force:
                fl = flavour if flavour != "auto" else ("native" if kind in SLAVES and not note else "python")
                path = build(kind, args.out, flavour=fl, fmi_version=version)
                path.with_suffix(".sha256").write_text(_source_hash(fl) + "\n")
            else:
                path = ensure_fmu(kind, args.out, flavour, fmi_version=version)
            problems = validate(path)
            print(f"{path}: {'valid' if not problems else 'INVALID'}")
            for p in problems:
                print(f"  - {p}")
                status = 1
    return status


if __name__ == "__main__":
    sys.exit(main())
