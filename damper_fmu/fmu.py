"""Build the damper FMUs (FMI 2.0 co-simulation, FMI 3.0 on request) and validate them with fmpy.

The command line is ``python build_fmu.py`` (project root); this module is what it, the tuner,
the tests and the benchmarks call. Two flavours of every damper model, equal to 1e-9
(tests/test_native.py, tests/test_fmu.py):

* **native** (default; ``DamperLumped.fmu``, ``DamperMaxwell.fmu``, ``DamperMaxwellTable.fmu``,
  ``DamperTwoChamber.fmu``): C against the FMI 2.0 headers, linked to libc/libm only. The binary
  for this platform is built with the system C compiler; the C sources are inside the FMU
  (``sources/``, listed in the model description's ``SourceFiles`` and in
  ``sources/buildDescription.xml``) so an importer on another platform can compile it. Needs no
  Python on the importing machine.
* **native FMI 3.0** (``fmi_version=3``; ``DamperLumped3.fmu`` ...): the same kernel and
  variables behind the FMI 3.0 co-simulation interface (``c/fmi3_damper.c``), forces equal to the
  FMI 2.0 FMU's bit for bit (tests/test_fmi3.py). A separate archive per FMI version: an FMU
  holds one modelDescription.xml, of one version.
* **python** (``DamperLumpedPy.fmu`` ...; pythonfmu, as the design card asks): the importing tool
  needs a Python 3 interpreter with numpy (``needsExecutionTool="true"``). Built from the slave
  classes in the project's ``fmu_src/`` (next to this package in a source checkout or an
  editable install).

Built FMUs go to ``build/fmu/`` in the project folder (git-ignored) unless ``out`` or the
environment variable ``DAMPER_FMU_DIR`` says otherwise. A stamp file next to each records a hash
of its sources so ``ensure_fmu`` rebuilds only when they changed. Without a C compiler
``ensure_fmu`` gives the Python FMU and ``fast_path_note()`` says why.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import uuid
import zipfile
from pathlib import Path

from . import model_description, native
from .model_description import NATIVE_SETTINGS
from .parameters import MODEL_PARAMETERS, check_values

__all__ = ["SLAVES", "PY_SLAVES", "FMI_SUFFIX", "default_dir", "native_reason", "fast_path_note", "build",
           "ensure_fmu", "validate", "source_hash"]

PACKAGE = Path(__file__).resolve().parent
#: the project folder: the package's parent in a source checkout or an editable install
ROOT = PACKAGE.parent
#: pythonfmu slave classes (a project folder, not part of the package)
SRC = ROOT / "fmu_src"
C_DIR = PACKAGE / "c"
#: the standard FMI 2.0.x headers of the Modelica Association, unmodified (BSD-2, the licence is in
#: them; see c/fmi2/ORIGIN). fmpy's copies are altered to ignore FMI2_FUNCTION_PREFIX, which
#: source-code import of several FMUs into one program needs.
FMI2_HEADERS = C_DIR / "fmi2"
#: the standard FMI 3.0 headers, unmodified (c/fmi3/ORIGIN)
FMI3_HEADERS = C_DIR / "fmi3"

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


def default_dir() -> Path:
    """Folder of the built FMUs: $DAMPER_FMU_DIR or <project>/build/fmu."""
    return Path(os.environ.get("DAMPER_FMU_DIR", ROOT / "build" / "fmu"))


def source_hash(flavour: str) -> str:
    """Hash of everything an FMU of ``flavour`` ('native' or 'python') is built from."""
    h = hashlib.sha256(flavour.encode())
    if flavour == "python":
        # pythonfmu is needed for the Python FMUs only (and takes a while to import)
        import pythonfmu

        h.update(pythonfmu.__version__.encode())
        files = [*PACKAGE.glob("*.py"), *SRC.glob("*.py")]
    else:
        files = [*C_DIR.glob("*.[ch]"), *FMI2_HEADERS.glob("*.h"), *FMI3_HEADERS.glob("*.h"), *PACKAGE.glob("*.py")]
    for f in sorted(files):
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def native_reason() -> str:
    """Why native FMUs cannot be built here ('' when they can)."""
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


def _resolve_flavour(kind: str, flavour: str) -> str:
    if flavour == "auto":
        return "native" if kind in SLAVES and not native_reason() else "python"
    if flavour not in ("native", "python"):
        raise ValueError(f"unknown FMU flavour '{flavour}', expected 'native', 'python' or 'auto'")
    return flavour


def build(kind: str, out: str | Path | None = None, *, start_values: dict | None = None,
          settings: dict | None = None, filename: str | None = None, flavour: str = "auto",
          fmi_version: int = 2, parameter_notes: dict | None = None) -> Path:
    """Build the FMU of ``kind`` in ``flavour`` ('native', 'python', or 'auto': native where a C
    compiler is found) and return its path. ``fmi_version``: 2 (default) or 3 (native only; file
    ``<model identifier>3.fmu``).

    ``start_values``: parameter name -> SI value used as start values (e.g. identified
    parameters); ``settings``: optional ``max_internal_step`` [s], ``internal_tolerance`` [-] and
    ``input_interpolation`` (0 or 1); ``parameter_notes``: parameter name -> text appended to its
    description in the model description (a tuned FMU's determined range of each identified value; any
    text, XML-escaped when written). The file is written atomically.
    """
    flavour = _resolve_flavour(kind, flavour)
    _check_fmi_version(fmi_version, flavour)
    names = SLAVES if flavour == "native" else PY_SLAVES
    if kind not in names:
        raise ValueError(f"unknown {flavour} FMU kind '{kind}', expected one of {sorted(names)}")
    if kind != "empty" and start_values:
        check_values(kind, start_values)
    notes = {str(k): str(v) for k, v in (parameter_notes or {}).items()}
    unknown = sorted(set(notes) - {p.name for p in MODEL_PARAMETERS.get(kind, ())})
    if unknown:
        raise ValueError(f"parameter_notes for unknown parameter(s) of '{kind}': {', '.join(unknown)}")
    out = Path(out) if out is not None else default_dir()
    out.mkdir(parents=True, exist_ok=True)
    target = out / (filename or f"{names[kind]}{FMI_SUFFIX[fmi_version]}.fmu")
    if flavour == "native":
        _build_native(kind, target, start_values or {}, settings or {}, fmi_version, notes)
        return target
    if not (SRC / f"{PY_SLAVES[kind]}.py").is_file():
        raise FileNotFoundError(f"cannot build {target.name}: the pythonfmu slave classes are not at {SRC} "
                                f"(the project's fmu_src/ folder, next to the damper_fmu package in a source "
                                f"checkout or an editable install)")
    # pythonfmu imports the slave script, which must not meet a slave module an FMU already
    # loaded in the caller: build in a fresh Python process, which imports this package from here
    spec = json.dumps({"kind": kind, "target": str(target), "start_values": start_values or {},
                       "settings": settings or {}, "notes": notes})
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    proc = subprocess.run([sys.executable, "-c", "import sys; from damper_fmu.fmu import _build_python; "
                           "_build_python(sys.argv[1])", spec], capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        raise RuntimeError(f"building {target.name} failed:\n{proc.stderr.strip()}")
    return target


def _build_python(spec: str) -> None:
    """One pythonfmu build (``build`` runs it in a fresh process); ``spec``: JSON of kind, target,
    start_values, settings."""
    # pythonfmu: needed for the Python FMUs only
    from pythonfmu.builder import FmuBuilder

    spec = json.loads(spec)
    kind, target, start_values, settings = spec["kind"], Path(spec["target"]), spec["start_values"], spec["settings"]
    notes = spec.get("notes") or {}
    with tempfile.TemporaryDirectory(prefix="damper_fmu_build_") as tmp:
        tmp = Path(tmp)
        project = []
        if kind != "empty":
            project = [PACKAGE, SRC / "damper_fmi.py"]
            if start_values or settings or notes:
                staged = tmp / "start_values.json"
                data = {k: float(v) for k, v in start_values.items()}
                data["_settings"] = dict(settings)
                data["_notes"] = dict(notes)
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


def _fmi_headers(fmi_version: int = 2) -> list[Path]:
    if fmi_version == 3:
        return [FMI3_HEADERS / n for n in ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")]
    return [FMI2_HEADERS / n for n in ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")]


VALUES_FILE = "damper_fmu_values.c"
#: the settings' start values in damper_fmu_values.c's DK_START_SETTINGS, in this order (fmu_common.c reads them)
START_SETTINGS = ("max_internal_step", "internal_tolerance", "stroke_limit", "velocity_limit")


def _config_header(kind: str, identifier: str, fmi_version: int) -> str:
    """damper_fmu_config.h: the model kind and the names of this FMU's generated values, the same for every FMU
    of ``kind`` and FMI version (the compiled object of the rest of sources/ is shared by them)."""
    name = f"{identifier}_fmi{fmi_version}"
    return "\n".join([
        "/* Generated by damper_fmu/fmu.py: the model kind, and the names of the GUID and start values that",
        "   damper_fmu_values.c defines (the model identifier and FMI version in them: several FMUs' sources",
        "   compile into one program without clashes). */",
        f"#define DK_MODEL_KIND {native.KINDS[kind]}",
        f"#define DK_GUID {name}_guid",
        f"#define DK_START_VALUES {name}_start_values",
        f"#define DK_START_SETTINGS {name}_start_settings",
        f"#define DK_START_INPUT_INTERPOLATION {name}_start_input_interpolation",
        "#if defined(__GNUC__) && !defined(_WIN32)",
        '#define DK_HIDDEN __attribute__((visibility("hidden")))',
        "#else", "#define DK_HIDDEN", "#endif", ""])


def _c_double(v: float) -> str:
    """A C double literal of ``v`` (exact: Python's repr round-trips)."""
    v = float(v)
    return repr(v) if math.isfinite(v) else ("INFINITY" if v > 0 else "-INFINITY") if math.isinf(v) else "NAN"


def _values_source(kind: str, guid: str, start_values: dict, settings: dict) -> str:
    """damper_fmu_values.c: this FMU's GUID and start values (parameters in ``MODEL_PARAMETERS`` order, SI)."""
    params = MODEL_PARAMETERS[kind]
    starts = [_c_double(start_values.get(p.name, p.default)) for p in params]
    setting = [_c_double(settings.get(k, NATIVE_SETTINGS[k][0])) for k in START_SETTINGS]
    return "\n".join([
        "/* Generated by damper_fmu/fmu.py: this FMU's GUID and start values (parameters in the order of",
        "   damper_params.h; settings: max_internal_step [s], internal_tolerance [-], stroke_limit [m],",
        "   velocity_limit [m/s]). */",
        "#include <math.h>", '#include "damper_fmu_config.h"',
        f'DK_HIDDEN const char DK_GUID[] = "{guid}";',
        f"DK_HIDDEN const double DK_START_VALUES[{len(params)}] = {{",
        *(f"    {v}," for v in starts), "};",
        f"DK_HIDDEN const double DK_START_SETTINGS[4] = {{{', '.join(setting)}}};",
        f"DK_HIDDEN const int DK_START_INPUT_INTERPOLATION = {int(settings.get('input_interpolation', 0))};", ""])


def _build_native(kind: str, target: Path, start_values: dict, settings: dict, fmi_version: int = 2,
                  notes: dict | None = None) -> None:
    cc = native.compiler()
    if cc is None:
        raise RuntimeError(f"cannot build the native {SLAVES[kind]} FMU: {native_reason()}; "
                           f"use flavour='python' (pythonfmu) instead")
    identifier = SLAVES[kind]
    payload = json.dumps([kind, sorted(start_values.items()), sorted(settings.items()),
                          source_hash("native")] + ([3] if fmi_version == 3 else [])
                         + ([sorted(notes.items())] if notes else [])).encode()
    guid = "{" + str(uuid.UUID(hashlib.md5(payload).hexdigest())) + "}"
    with tempfile.TemporaryDirectory(prefix="damper_native_fmu_") as tmp:
        tmp = Path(tmp)
        src = tmp / "sources"
        src.mkdir()
        wrapper = f"fmi{fmi_version}_damper.c"
        # the wrapper includes the rest: the FMI-independent part, the kernel, their headers
        for f in (C_DIR / wrapper, C_DIR / "fmu_common.c", C_DIR / "damper_kernel.c", C_DIR / "damper_kernel.h",
                  C_DIR / "damper_index.h", *_fmi_headers(fmi_version)):
            shutil.copyfile(f, src / f.name)
        (src / "damper_params.h").write_text(native.parameter_header())
        (src / "damper_fmu_config.h").write_text(_config_header(kind, identifier, fmi_version))
        # compiled once per model and FMI version (cached); this FMU's values are the small second file
        shared = native.compile_object(src / wrapper, f"{identifier}_fmi{fmi_version}", sorted(src.iterdir()))
        (src / VALUES_FILE).write_text(_values_source(kind, guid, start_values, settings))
        _write_build_description(src, identifier, fmi_version, [wrapper, VALUES_FILE])
        suffix = {"win": ".dll", "darwin": ".dylib"}.get(_platform_folder()[:-2], ".so")
        folder = _platform_tuple() if fmi_version == 3 else _platform_folder()
        binary = tmp / "binaries" / folder / f"{identifier}{suffix}"
        binary.parent.mkdir(parents=True)
        cmd = [cc, *native.CFLAGS, "-shared", "-I", str(src), str(shared), str(src / VALUES_FILE), "-o", str(binary),
               "-lm"]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"compiling {identifier} failed ({' '.join(cmd)}):\n{proc.stderr.strip()}")
        xml = (model_description.fmi3(kind, identifier, guid, start_values, settings, notes) if fmi_version == 3 else
               model_description.fmi2(kind, identifier, guid, start_values, settings, [wrapper, VALUES_FILE], notes))
        (tmp / "modelDescription.xml").write_bytes(xml)
        _write_documentation(tmp, identifier, kind, fmi_version)
        part = target.with_suffix(".fmu.part")
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
            for f in sorted(tmp.rglob("*")):
                if f.is_file():
                    z.write(f, f.relative_to(tmp).as_posix())
        os.replace(part, target)


def _write_build_description(src: Path, identifier: str, fmi_version: int, files: list[str]) -> None:
    """sources/buildDescription.xml. FMI 2.0 importers read the SourceFiles of modelDescription.xml (fmpy's CMake
    build does, and it drops <Library> elements whatever the version: an importer must link the C math library
    itself, e.g. fmpy's build_platform_binary(..., cmake_options={"CMAKE_C_STANDARD_LIBRARIES": "-lm"})). This
    file gives the same in the FMI 3.0 build-description layout, for tools that read it, with this FMU's FMI
    version (for FMI 3.0 it is where the source files are declared)."""
    (src / "buildDescription.xml").write_text(
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        f'<fmiBuildDescription fmiVersion="{fmi_version}.0">\n'
        f'  <BuildConfiguration modelIdentifier="{identifier}">\n'
        '    <SourceFileSet language="C99">\n'
        + "".join(f'      <SourceFile name="{f}"/>\n' for f in files)
        + '    </SourceFileSet>\n    <Library name="m"/>\n  </BuildConfiguration>\n</fmiBuildDescription>\n')


def _write_documentation(folder: Path, identifier: str, kind: str, fmi_version: int) -> None:
    """documentation/index.html of the FMU in ``folder``."""
    docs = folder / "documentation"
    docs.mkdir()
    (docs / "index.html").write_text(
        f"<html><body><h1>{identifier}</h1><p>Railway hydraulic damper ({kind} model), FMI {fmi_version}.0 "
        f"co-simulation. Inputs stroke [m] (extension +) and stroke_velocity [m/s]; output force [N] "
        f"(tension +). See the project's docs/fmus.md, 'Which communication steps are safe', for safe "
        f"communication step sizes.</p></body></html>\n")


def ensure_fmu(kind: str, out: str | Path | None = None, flavour: str = "auto", fmi_version: int = 2,
               force: bool = False) -> Path:
    """Path of the default FMU of ``kind``, (re)building it if missing, its sources changed or
    ``force``.

    flavour: 'native', 'python' or 'auto' (native where a C compiler is found; 'empty' is python).
    fmi_version: 2, or 3 (native only).
    """
    flavour = _resolve_flavour(kind, flavour)
    _check_fmi_version(fmi_version, flavour)
    names = SLAVES if flavour == "native" else PY_SLAVES
    if kind not in names:
        raise ValueError(f"unknown {flavour} FMU kind '{kind}', expected one of {sorted(names)}")
    out = Path(out) if out is not None else default_dir()
    path = out / f"{names[kind]}{FMI_SUFFIX[fmi_version]}.fmu"

    stamp = path.with_suffix(".sha256")
    digest = source_hash(flavour)
    if not force and path.exists() and stamp.exists() and stamp.read_text().strip() == digest:
        return path
    out.mkdir(parents=True, exist_ok=True)
    with _exclusive(path.with_suffix(".lock")):  # processes building the same FMU at once wait for each other
        if force or not (path.exists() and stamp.exists() and stamp.read_text().strip() == digest):
            build(kind, out, flavour=flavour, fmi_version=fmi_version)
            stamp.write_text(digest + "\n")
    return path


@contextlib.contextmanager
def _exclusive(lock_path: Path):
    """An exclusive lock on ``lock_path`` across processes (POSIX ``flock``; none where it does not exist)."""
    try:
        import fcntl
    except ImportError:  # Windows: builds are not run concurrently there by the project itself
        yield
        return
    with open(lock_path, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def validate(path: str | Path) -> list[str]:
    """Problems fmpy's validator reports for the FMU at ``path`` (empty list: valid)."""
    # fmpy's validator: only here, for the build's check (the rest of the package needs no fmpy)
    from fmpy.validation import validate_fmu

    return list(validate_fmu(str(path)))
