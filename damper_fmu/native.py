"""The C kernel (``damper_fmu/c``), compiled on first use and called through ctypes.

The kernel implements the same equations and integrator as the Python reference
(``models.py``, ``effects.py``, ``integrator.py``) and is what the native FMUs contain. Here it
simulates a whole sampled stroke per call (``simulate``): the fast path of the tuner.

Build: the system C compiler (``$CC``, else ``cc`` or ``gcc``) compiles ``damper_kernel.c`` with a
parameter header generated from ``parameters.py`` (one source for names, bounds and checks) into a
shared library cached under ``$DAMPER_NATIVE_DIR`` (default ``~/.cache/yaw-damper-toolchain``),
keyed by a hash of the sources. Without a compiler, ``available()`` is False and ``reason()`` says
why; everything then runs on the Python reference (slower).
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from .models import ConvergenceError
from .parameter_spec import check_rule
from .parameters import MODEL_PARAMETERS
from .solver_options import SolverOptions

__all__ = ["available", "reason", "library", "simulate", "parameter_header", "KINDS", "CFLAGS", "compiler",
           "compile_object", "compile_library"]

C_DIR = Path(__file__).resolve().parent / "c"
KINDS = {"lumped": 0, "maxwell": 1, "maxwell_table": 2, "twochamber": 3}
#: -ffp-contract=off: no fused multiply-add, so the C results equal the Python reference's
CFLAGS = ("-O2", "-ffp-contract=off", "-fPIC", "-std=c99", "-Wall")

_CHECK = {"none": 0, "positive": 1, "range": 2, "nonnegative": 3}
_state: dict = {}


def parameter_header(start_values: dict[str, dict[str, float]] | None = None) -> str:
    """C header with every model's parameters (name, unit, start value, bounds, check) in the order
    of ``parameters.MODEL_PARAMETERS``; ``start_values``: kind -> name -> value overriding presets."""
    start_values = start_values or {}
    lines = ["/* Generated from damper_fmu/parameters.py by damper_fmu/native.py: do not edit. */",
             "#ifndef DAMPER_PARAMS_H", "#define DAMPER_PARAMS_H",
             "typedef struct { const char *name; const char *unit; double start, low, high; int check, fixed, effect; }"
             " DkParamSpec;",
             "#define DK_CHECK_NONE 0", "#define DK_CHECK_POSITIVE 1", "#define DK_CHECK_RANGE 2",
             "#define DK_CHECK_NONNEGATIVE 3"]
    for kind, params in MODEL_PARAMETERS.items():
        tag = kind.upper()
        sv = start_values.get(kind, {})
        lines.append(f"#define DK_PARAMS_{tag}_N {len(params)}")
        lines.append(f"static const DkParamSpec DK_PARAMS_{tag}[{len(params)}] = {{")
        for p in params:
            lines.append(f'    {{"{p.name}", "{p.unit}", {float(sv.get(p.name, p.default))!r}, {p.low!r}, '
                         f'{p.high!r}, {_CHECK[check_rule(p)]}, {int(not (p.tunable or p.effect))}, '
                         f'{int(p.effect is not None)}}},')
        lines.append("};")
    lines.append("#endif")
    return "\n".join(lines).replace("inf,", "INFINITY,") + "\n"


def compiler() -> str | None:
    """Path of the C compiler to use, or None."""
    cc = os.environ.get("CC")
    if cc:
        return shutil.which(cc)
    return shutil.which("cc") or shutil.which("gcc")


def _cache_dir() -> Path:
    return Path(os.environ.get("DAMPER_NATIVE_DIR", Path.home() / ".cache" / "yaw-damper-toolchain"))


def _require_compiler() -> str:
    """The C compiler's path; OSError without one."""
    cc = compiler()
    if cc is None:
        raise OSError("no C compiler found (set CC or install gcc)")
    return cc


def _compile_cached(target: Path, source: Path, command, files: dict[str, str] | None = None) -> Path:
    """``target`` (a file of the cache), compiled unless it exists: ``command(tmp, out)`` is the compiler's
    argument list for a temporary folder ``tmp`` holding the generated ``files`` (name -> text) and the output
    path ``out``, moved into place atomically (concurrent builders never see half a file). OSError naming the
    command and the compiler's message when it fails."""
    if not target.exists():
        target.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix=f"{target.stem}_") as tmp:
            for name, text in (files or {}).items():
                (Path(tmp) / name).write_text(text)
            out = Path(tmp) / target.name
            cmd = command(tmp, out)
            proc = subprocess.run(cmd, capture_output=True, text=True)
            if proc.returncode != 0:
                raise OSError(f"compiling {source.name} failed ({' '.join(cmd)}):\n{proc.stderr.strip()}")
            os.replace(out, target)
    return target


def compile_library(source: Path, name: str, *, headers: dict[str, str] | None = None,
                    include_dirs=()) -> Path:
    """Compile the C file ``source`` (plus generated ``headers``: file name -> text) into a shared
    library cached under ``$DAMPER_NATIVE_DIR``, keyed by a hash of everything that goes in;
    return its path. Raises OSError without a compiler or when compilation fails."""
    cc = _require_compiler()
    h = hashlib.sha256(source.read_bytes())
    for hname, text in sorted((headers or {}).items()):
        h.update(hname.encode() + text.encode())
    for d in include_dirs:
        for f in sorted(Path(d).glob("*.h")):
            h.update(f.read_bytes())
    h.update(" ".join(CFLAGS).encode())
    suffix = ".dll" if sys.platform == "win32" else ".dylib" if sys.platform == "darwin" else ".so"
    target = _cache_dir() / f"{name}_{h.hexdigest()[:16]}{suffix}"
    return _compile_cached(target, source, lambda tmp, out: [
        cc, *CFLAGS, "-shared", "-I", tmp, *[f"-I{d}" for d in include_dirs], str(source), "-o", str(out), "-lm"],
        headers)


def compile_object(source: Path, name: str, inputs: list[Path]) -> Path:
    """Compile the C file ``source`` (``-c``, include path its folder) into an object file cached under
    ``$DAMPER_NATIVE_DIR``, keyed by a hash of ``inputs`` (every file it is built from, the source included),
    the flags and the compiler; return its path. Raises OSError without a compiler or when compilation fails."""
    cc = _require_compiler()
    h = hashlib.sha256(" ".join([cc, *CFLAGS]).encode())
    for f in inputs:
        h.update(f.name.encode() + b"\0" + f.read_bytes())
    target = _cache_dir() / f"{name}_{h.hexdigest()[:16]}.o"
    return _compile_cached(target, source, lambda tmp, out: [
        cc, *CFLAGS, "-c", "-I", str(source.parent), str(source), "-o", str(out)])


def _build() -> ctypes.CDLL:
    target = compile_library(C_DIR / "damper_kernel.c", "damper_kernel",
                             headers={"damper_params.h": parameter_header()}, include_dirs=[C_DIR])
    lib = ctypes.CDLL(str(target))
    dp, cp = ctypes.POINTER(ctypes.c_double), ctypes.c_char_p
    lib.dk_simulate.argtypes = [ctypes.c_int, dp, ctypes.c_int, ctypes.c_double, ctypes.c_double, ctypes.c_int,
                                ctypes.c_int, dp, dp, dp, dp, dp, cp, ctypes.c_int]
    lib.dk_simulate.restype = ctypes.c_int
    lib.dk_parameter_names.argtypes = [ctypes.c_int]
    lib.dk_parameter_names.restype = ctypes.c_char_p
    return lib


def library() -> ctypes.CDLL:
    """The compiled kernel (built on first call); raises OSError when it cannot be built."""
    if "lib" not in _state:
        try:
            _state["lib"] = _build()
        except OSError as err:
            _state["lib"] = None
            _state["reason"] = str(err)
    if _state["lib"] is None:
        raise OSError(_state["reason"])
    return _state["lib"]


def available() -> bool:
    """True when the C kernel is compiled (or can be); ``reason()`` says why not."""
    try:
        library()
    except OSError:
        return False
    return True


def reason() -> str:
    """Why the C kernel is not available ('' when it is)."""
    return "" if available() else _state.get("reason", "")


def _values(kind: str, params: dict) -> np.ndarray:
    names = [p.name for p in MODEL_PARAMETERS[kind]]
    full = {p.name: p.default for p in MODEL_PARAMETERS[kind]}
    unknown = set(params) - set(full)
    if unknown:
        raise ValueError(f"unknown parameter(s) for model '{kind}': {', '.join(sorted(unknown))}")
    full.update(params)
    return np.ascontiguousarray([float(full[n]) for n in names], dtype=float)


def _ptr(a):
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double)) if a is not None else None


def simulate(kind: str, params: dict, t, x, v, *, solver: SolverOptions, temperature=None) -> np.ndarray:
    """Force [N] at every sample of a stroke (time [s], stroke [m], velocity [m/s]; temperature
    [degC] or None) stepped as ``solver`` says (largest internal step [s], tolerance, input mode), as
    ``damper_fmu.simulate``; raises ValueError with the kernel's message."""
    lib = library()
    p = _values(kind, params)
    t, x, v = (np.ascontiguousarray(a, dtype=float) for a in (t, x, v))
    temp = None if temperature is None else np.ascontiguousarray(temperature, dtype=float)
    out = np.empty(t.size)
    msg = ctypes.create_string_buffer(512)
    st = lib.dk_simulate(KINDS[kind], _ptr(p), p.size, float(solver.max_step), float(solver.tolerance),
                         int(solver.input_mode), t.size, _ptr(t), _ptr(x), _ptr(v), _ptr(temp), _ptr(out), msg,
                         len(msg))
    if st != 0:
        text = msg.value.decode()
        raise (ConvergenceError if "converge" in text or "internal step" in text or "Jacobian" in text
               else ValueError)(text)
    return out
