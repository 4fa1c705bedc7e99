"""Build the damper FMUs (FMI 2.0 co-simulation) and validate them with fmpy.

Usage:  python build_fmu.py [--out DIR] [--force] [--python] [lumped maxwell maxwell_table empty]

Two flavours of every damper model, equal to 1e-9 (tests/test_native.py, tests/test_fmu.py):

* **native** (default; ``DamperLumped.fmu``, ``DamperMaxwell.fmu``, ``DamperMaxwellTable.fmu``):
  C against the FMI 2.0 headers, linked to libc/libm only. The binary for this platform is built
  with the system C compiler; the C sources are inside the FMU (``sources/``, listed in the model
  description's ``SourceFiles`` and in ``sources/buildDescription.xml``) so an importer on another
  platform can compile it. Needs no Python on the importing machine.
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
        files = [*C_DIR.glob("*.[ch]"), *FMI2_HEADERS.glob("*.h"), PACKAGE / "parameters.py", PACKAGE / "models.py",
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


def build(kind: str, out: str | Path | None = None, *, start_values: dict | None = None,
          settings: dict | None = None, filename: str | None = None, flavour: str = "auto") -> Path:
    """Build the FMU of ``kind`` in ``flavour`` ('native', 'python', or 'auto': native where a C
    compiler is found) and return its path.

    ``start_values``: parameter name -> SI value used as start values (e.g. identified
    parameters); ``settings``: optional ``max_internal_step`` [s], ``internal_tolerance`` [-] and
    ``input_interpolation`` (0 or 1). The file is written atomically.
    """
    if flavour == "auto":
        flavour = "native" if kind in SLAVES and not native_reason() else "python"
    if flavour not in ("native", "python"):
        raise ValueError(f"unknown FMU flavour '{flavour}', expected 'native', 'python' or 'auto'")
    names = SLAVES if flavour == "native" else PY_SLAVES
    if kind not in names:
        raise ValueError(f"unknown {flavour} FMU kind '{kind}', expected one of {sorted(names)}")
    if kind != "empty" and start_values:
        from damper_fmu.parameters import check_values

        check_values(kind, start_values)
    out = Path(out) if out is not None else default_dir()
    out.mkdir(parents=True, exist_ok=True)
    target = out / (filename or f"{names[kind]}.fmu")
    if flavour == "native":
        _build_native(kind, target, start_values or {}, settings or {})
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

def _platform_folder() -> str:
    bits = "64" if sys.maxsize > 2 ** 32 else "32"
    system = {"Linux": "linux", "Darwin": "darwin", "Windows": "win"}.get(platform.system(), platform.system().lower())
    return f"{system}{bits}"


#: the standard FMI 2.0.x headers of the Modelica Association, unmodified (BSD-2, the licence is in
#: them; see damper_fmu/c/fmi2/ORIGIN). fmpy's copies are altered to ignore FMI2_FUNCTION_PREFIX, which
#: source-code import of several FMUs into one program needs.
FMI2_HEADERS = C_DIR / "fmi2"


def _fmi_headers() -> list[Path]:
    return [FMI2_HEADERS / n for n in ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")]


def _model_description(kind: str, identifier: str, guid: str, start_values: dict, settings: dict) -> bytes:
    """modelDescription.xml of the native FMU of ``kind`` (value references: fmi2_damper.c)."""
    from damper_fmu.models import DIAGNOSTICS
    from damper_fmu.parameters import EFFECT_MODELS, MODEL_PARAMETERS, UNIT_DEFINITIONS

    params = MODEL_PARAMETERS[kind]
    root = Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": identifier, "guid": guid,
        "description": f"Railway hydraulic damper, {kind} model (native C; SI units, stroke positive in "
                       f"extension, force positive in tension)",
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
    used = sorted({p.unit for p in params} | {"m", "m/s", "N", "s", "degC"} |
                  {u for u, _ in DIAGNOSTICS[kind].values()})
    for name in used:
        SubElement(SubElement(units, "Unit", {"name": name}), "BaseUnit",
                   {k: str(e) for k, e in UNIT_DEFINITIONS[name].items()})
    cats = SubElement(root, "LogCategories")
    SubElement(cats, "Category", {"name": "logStatusError", "description": "Errors with their reason"})
    SubElement(root, "DefaultExperiment", {"startTime": "0", "stopTime": "10", "stepSize": "0.001"})
    mv = SubElement(root, "ModelVariables")
    outputs = []

    def var(name, vr, causality, variability, unit, description, start=None, initial=None, kind_="Real"):
        attrs = {"name": name, "valueReference": str(vr), "description": description, "causality": causality,
                 "variability": variability}
        if initial:
            attrs["initial"] = initial
        sv = SubElement(mv, "ScalarVariable", attrs)
        t = {}
        if unit:
            t["unit"] = unit
        if start is not None:
            t["start"] = repr(float(start)) if kind_ == "Real" else str(int(start))
        SubElement(sv, kind_, t)
        return len(mv)

    inputs = [var("stroke", 0, "input", "continuous", "m", "Damper stroke, positive in extension", 0.0),
              var("stroke_velocity", 1, "input", "continuous", "m/s", "Damper stroke velocity, positive in extension",
                  0.0)]
    model_params = []
    if kind in EFFECT_MODELS:
        var("oil_temperature", 3, "input", "continuous", "degC",
            "Measured oil temperature; used by the thermal drift element when thermal_source = 1", 20.0)
    outputs.append(var("force", 2, "output", "continuous", "N", "Damper force, positive in tension",
                       initial="calculated"))
    for i, (name, (unit, text)) in enumerate(DIAGNOSTICS[kind].items()):
        outputs.append(var(name, 10 + i, "output", "continuous", unit, text, initial="calculated"))
    for i, p in enumerate(params):
        tunable = p.tunable or p.effect
        text = (f"{p.description} [{p.unit}]; identification bounds [{p.low:g}, {p.high:g}]" if p.tunable else
                f"Effect '{p.effect}' (off at 0): {p.description} [{p.unit}], range [{p.low:g}, {p.high:g}]"
                if p.effect else f"{p.description} [{p.unit}]")
        model_params.append(var(p.name, 100 + i, "parameter", "tunable" if tunable else "fixed", p.unit, text,
                                start_values.get(p.name, p.default), initial="exact"))
    for name, (value, unit, text) in NATIVE_SETTINGS.items():
        var(name, _SETTING_VR[name], "parameter", "fixed", unit or None, text, settings.get(name, value),
            initial="exact")
    var("input_interpolation", 0, "parameter", "fixed", None, INPUT_INTERPOLATION_DESCRIPTION,
        settings.get("input_interpolation", 0), initial="exact", kind_="Integer")
    if kind in EFFECT_MODELS:
        var("thermal_source", 1, "parameter", "fixed", None,
            "Oil temperature of the thermal drift element: 0 internal thermal balance, 1 the oil_temperature input",
            0, initial="exact", kind_="Integer")
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
    initial_knowns = " ".join(str(k) for k in sorted(inputs + model_params))
    for i in outputs:
        SubElement(init, "Unknown", {"index": str(i), "dependencies": initial_knowns})
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root, encoding="utf-8")


def _build_native(kind: str, target: Path, start_values: dict, settings: dict) -> None:
    from damper_fmu import native

    cc = native.compiler()
    if cc is None:
        raise RuntimeError(f"cannot build the native {SLAVES[kind]} FMU: {native_reason()}; "
                           f"use flavour='python' (pythonfmu) instead")
    identifier = SLAVES[kind]
    payload = json.dumps([kind, sorted(start_values.items()), sorted(settings.items()),
                          _source_hash("native")]).encode()
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
        for f in (C_DIR / "fmi2_damper.c", C_DIR / "damper_kernel.c", C_DIR / "damper_kernel.h", *_fmi_headers()):
            shutil.copyfile(f, src / f.name)
        (src / "damper_params.h").write_text(header)
        (src / "damper_fmu_config.h").write_text(config)
        # FMI 2.0 importers read the SourceFiles of modelDescription.xml (fmpy's CMake build does, and it
        # drops <Library> elements whatever the version: an importer must link the C math library
        # itself, e.g. fmpy's build_platform_binary(..., cmake_options={"CMAKE_C_STANDARD_LIBRARIES":
        # "-lm"})). This file gives the same in the FMI 3.0 build-description layout, for tools that
        # read it, with this FMU's FMI version.
        (src / "buildDescription.xml").write_text(
            '<?xml version="1.0" encoding="UTF-8"?>\n'
            '<fmiBuildDescription fmiVersion="2.0">\n'
            f'  <BuildConfiguration modelIdentifier="{identifier}">\n'
            '    <SourceFileSet language="C99">\n'
            '      <SourceFile name="fmi2_damper.c"/>\n'
            '    </SourceFileSet>\n    <Library name="m"/>\n  </BuildConfiguration>\n</fmiBuildDescription>\n')
        suffix = {"win": ".dll", "darwin": ".dylib"}.get(_platform_folder()[:-2], ".so")
        binary = tmp / "binaries" / _platform_folder() / f"{identifier}{suffix}"
        binary.parent.mkdir(parents=True)
        cmd = [cc, *native.CFLAGS, "-shared", "-I", str(src), str(src / "fmi2_damper.c"), "-o", str(binary), "-lm"]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"compiling {identifier} failed ({' '.join(cmd)}):\n{proc.stderr.strip()}")
        (tmp / "modelDescription.xml").write_bytes(
            _model_description(kind, identifier, guid, start_values, settings))
        docs = tmp / "documentation"
        docs.mkdir()
        (docs / "index.html").write_text(
            f"<html><body><h1>{identifier}</h1><p>Railway hydraulic damper ({kind} model), FMI 2.0 "
            f"co-simulation. Inputs stroke [m] (extension +) and stroke_velocity [m/s]; output force [N] "
            f"(tension +). See the project README, section 'The FMUs', for safe communication step "
            f"sizes.</p></body></html>\n")
        part = target.with_suffix(".fmu.part")
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
            for f in sorted(tmp.rglob("*")):
                if f.is_file():
                    z.write(f, f.relative_to(tmp).as_posix())
        os.replace(part, target)


def ensure_fmu(kind: str, out: str | Path | None = None, flavour: str = "auto") -> Path:
    """Path of the default FMU of ``kind``, (re)building it if missing or its sources changed.

    flavour: 'native', 'python' or 'auto' (native where a C compiler is found; 'empty' is python).
    """
    if flavour == "auto":
        flavour = "native" if kind in SLAVES and not native_reason() else "python"
    names = SLAVES if flavour == "native" else PY_SLAVES
    out = Path(out) if out is not None else default_dir()
    path = out / f"{names[kind]}.fmu"

    stamp = path.with_suffix(".sha256")
    digest = _source_hash(flavour)
    if path.exists() and stamp.exists() and stamp.read_text().strip() == digest:
        return path
    build(kind, out, flavour=flavour)
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
    args = ap.parse_args(argv)
    bad = [k for k in args.kinds if k not in PY_SLAVES]
    if bad:
        ap.error(f"unknown FMU kind(s) {bad}; choose from {sorted(PY_SLAVES)}")
    note = fast_path_note()
    if note:
        print(note)
    status = 0
    for kind in args.kinds:
        flavours = ["auto"] + (["python"] if args.python and kind in SLAVES and not note else [])
        for flavour in flavours:
            if args.force:
                fl = flavour if flavour != "auto" else ("native" if kind in SLAVES and not note else "python")
                path = build(kind, args.out, flavour=fl)
                path.with_suffix(".sha256").write_text(_source_hash(fl) + "\n")
            else:
                path = ensure_fmu(kind, args.out, flavour)
            problems = validate(path)
            print(f"{path}: {'valid' if not problems else 'INVALID'}")
            for p in problems:
                print(f"  - {p}")
                status = 1
    return status


if __name__ == "__main__":
    sys.exit(main())
