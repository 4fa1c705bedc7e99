"""Fast fmpy runner: simulate a damper FMU under a sampled stroke history.

One FMU instance is extracted, loaded and instantiated once and reused across runs (FMI reset,
then parameters re-applied). The per-sample loop makes the raw FMI calls (fmi2SetReal /
fmi2DoStep / fmi2GetReal on preallocated buffers): in C (``tuner/identification/c/fmi2_stepper.c``, the same
calls on the FMU's own function pointers, without the interpreter's cost per call) where a C
compiler is found, else through ctypes from Python; nothing is re-read or re-extracted per run.

Time convention: the FMU is stepped from sample k-1 to sample k with the stroke and velocity of
sample k (``input_interpolation = 1``, replay of a known history, no input lag) unless
``input_mode=0`` is asked for, in which case sample k-1 inputs are used (plain co-simulation).
The returned force at sample 0 is the FMU's initial output.
"""
from __future__ import annotations

import atexit
import ctypes
import multiprocessing.util
import os
import shutil
import tempfile
import weakref
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2Integer

from damper_fmu.native import compile_library
from tuner.worker_processes import on_orphan_exit

__all__ = ["FmuRunner", "SimulationError", "as_stroke_arrays", "stepper"]

_REPLAY = 1
_STEPPER: dict = {}
#: the runners whose FMU instance is alive: freed at interpreter exit, before finalisation collects the
#: objects in arbitrary order (a native FMU freed then - its logger callback or library already torn
#: down - corrupted the heap; the processes used to skip their teardown with os._exit instead)
_LIVE: "weakref.WeakSet[FmuRunner]" = weakref.WeakSet()


#: the process in which ``_close_live_runners`` is registered with multiprocessing's exit finalizers
_FINALIZED_PID: list = [None]


@atexit.register
def _close_live_runners() -> None:
    for runner in list(_LIVE):
        runner.close()


def _remove_extracted_folders() -> None:
    """The extracted FMU folders of this process's live runners deleted, the instances left alone: what a worker
    whose run was killed does before it ends (``tuner.worker_processes.on_orphan_exit``; its main thread may be
    inside the FMU, whose loaded library stays mapped after its file is gone)."""
    for runner in list(_LIVE):
        shutil.rmtree(getattr(runner, "_unzip", ""), ignore_errors=True)


def _close_at_process_exit() -> None:
    """``_close_live_runners`` at this process's exit also when it ends without running ``atexit``: a worker
    forked from the fork server (``tuner.worker_processes``) ends with os._exit after multiprocessing's own
    exit finalizers, which are cleared when a worker starts, so they are registered in the process itself
    (without this each worker left its extracted FMU in the temporary folder: 334 in an hour)."""
    if _FINALIZED_PID[0] != os.getpid():
        multiprocessing.util.Finalize(None, _close_live_runners, exitpriority=0)
        _FINALIZED_PID[0] = os.getpid()


def stepper():
    """The compiled C stepping loop (ctypes library), or None without a C compiler."""
    if "lib" not in _STEPPER:
        try:
            lib = ctypes.CDLL(str(compile_library(Path(__file__).resolve().parent / "c" / "fmi2_stepper.c",
                                                  "fmi2_stepper")))
            dp, up = ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_uint)
            lib.fmi2_run.argtypes = [ctypes.c_void_p] * 4 + [ctypes.c_int, dp, dp, dp, dp, up, ctypes.c_int, up,
                                                             ctypes.c_int, ctypes.c_int, dp,
                                                             ctypes.POINTER(ctypes.c_int)]
            lib.fmi2_run.restype = ctypes.c_int
        except OSError:
            lib = None
        _STEPPER["lib"] = lib
    return _STEPPER["lib"]


class SimulationError(RuntimeError):
    """The FMU returned an error status; the message carries what the FMU logged."""


def as_stroke_arrays(time=None, stroke=None, stroke_velocity=None, frame=None):
    """Return (time [s], stroke [m], stroke_velocity [m/s]) float arrays from arrays or a frame.

    A pandas frame must have columns ``time``, ``stroke`` and ``stroke_velocity`` (SI units).
    """
    if frame is not None:
        missing = [c for c in ("time", "stroke", "stroke_velocity") if c not in frame.columns]
        if missing:
            raise ValueError(f"stroke frame lacks column(s) {missing}; has {list(frame.columns)}")
        time, stroke, stroke_velocity = frame["time"], frame["stroke"], frame["stroke_velocity"]
    t = np.ascontiguousarray(time, dtype=float)
    x = np.ascontiguousarray(stroke, dtype=float)
    v = np.ascontiguousarray(stroke_velocity, dtype=float)
    if not (t.ndim == 1 and t.shape == x.shape == v.shape and t.size >= 2):
        raise ValueError("time, stroke and stroke_velocity must be 1-D arrays of equal length >= 2")
    if not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)):
        raise ValueError("time must be finite and strictly increasing")
    return t, x, v


class FmuRunner:
    """Reusable runner for one damper FMU (``.fmu`` path) in this process.

    ``input_mode``: 1 (default) replay with end-of-step inputs, 0 co-simulation convention.
    ``max_internal_step``: optional override of the FMU's internal step cap [s];
    ``tolerance``: optional override of its ``internal_tolerance`` (0: fixed steps).
    """

    def __init__(self, fmu_path, *, input_mode: int = _REPLAY, max_internal_step: float | None = None,
                 tolerance: float | None = None, instance_name: str = "damper", c_loop: bool = True):
        self.path = Path(fmu_path)
        if not self.path.is_file():
            raise FileNotFoundError(f"FMU not found: {self.path} (build it with: python build_fmu.py)")
        self.md = read_model_description(str(self.path))
        self.variables = {v.name: v for v in self.md.modelVariables}
        self.parameter_names = [v.name for v in self.md.modelVariables if v.causality == "parameter"]
        self.output_names = [v.name for v in self.md.modelVariables if v.causality == "output"]
        for name in ("stroke", "stroke_velocity", "force"):
            if name not in self.variables:
                raise ValueError(f"{self.path.name} is not a damper FMU: no variable '{name}'")
        self.input_mode = int(input_mode)
        self.max_internal_step = max_internal_step
        self.tolerance = tolerance
        self._unzip = extract(str(self.path), tempfile.mkdtemp(prefix="damper_runner_"))
        on_orphan_exit(_remove_extracted_folders)
        self.messages: list[str] = []

        def _log(env, instance, status, category, message):
            self.messages.append(message.decode("utf-8", "replace") if message else "")

        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(_log)
        self._callbacks.allocateMemory = defaultCallbacks.allocateMemory
        self._callbacks.freeMemory = defaultCallbacks.freeMemory
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self._unzip,
                             modelIdentifier=self.md.coSimulation.modelIdentifier,
                             instanceName=instance_name)
        self.fmu.instantiate(callbacks=self._callbacks, loggingOn=True)
        _LIVE.add(self)
        _close_at_process_exit()
        self._fresh = True
        dll = self.fmu.dll
        self._set_real, self._do_step, self._get_real = dll.fmi2SetReal, dll.fmi2DoStep, dll.fmi2GetReal
        self._component = self.fmu.component
        vr = lambda n: self.variables[n].valueReference  # noqa: E731
        self._vr_in = (ctypes.c_uint * 2)(vr("stroke"), vr("stroke_velocity"))
        self._in = (ctypes.c_double * 2)()
        lib = stepper() if c_loop else None
        self._c_loop = lib.fmi2_run if lib is not None else None
        self._fn = [ctypes.cast(f, ctypes.c_void_p) for f in (self._set_real, self._do_step, self._get_real)]

    # -- helpers --------------------------------------------------------------------------
    def _check(self, status, what):
        if status > 1:  # worse than fmi2Warning
            detail = "; ".join(m for m in self.messages[-5:] if m) or "no message logged"
            raise SimulationError(f"{self.path.name}: {what} failed (FMI status {status}): {detail}")

    def _apply_parameters(self, params: dict | None):
        reals, ints = {}, {}
        if self.max_internal_step is not None:
            reals["max_internal_step"] = float(self.max_internal_step)
        if self.tolerance is not None:
            if "internal_tolerance" not in self.variables:
                raise ValueError(f"{self.path.name} has no internal_tolerance parameter (an FMU of an older build)")
            reals["internal_tolerance"] = float(self.tolerance)
        if "input_interpolation" in self.variables:
            ints["input_interpolation"] = self.input_mode
        for name, value in (params or {}).items():
            var = self.variables.get(name)
            if var is None or var.causality != "parameter":
                raise ValueError(f"{self.path.name} has no parameter '{name}'")
            if var.type == "Integer":
                ints[name] = int(value)
            else:
                reals[name] = float(value)
        if reals:
            vrs = [self.variables[n].valueReference for n in reals]
            self._check(self.fmu.dll.fmi2SetReal(self._component, (ctypes.c_uint * len(vrs))(*vrs), len(vrs),
                                             (ctypes.c_double * len(vrs))(*reals.values())), "setting parameters")
        if ints:
            vrs = [self.variables[n].valueReference for n in ints]
            self._check(self.fmu.dll.fmi2SetInteger(self._component, (ctypes.c_uint * len(vrs))(*vrs), len(vrs),
                                                (fmi2Integer * len(vrs))(*ints.values())), "setting parameters")

    def _start(self, t0: float, params: dict | None, vr_in, inp) -> None:
        """Reset (after the first run), set up, apply parameters and initial inputs, initialise."""
        dll, c = self.fmu.dll, self._component  # raw calls: statuses come back, messages are ours
        self.messages.clear()
        if not self._fresh:
            self._check(dll.fmi2Reset(c), "reset")
        self._fresh = False
        self._check(dll.fmi2SetupExperiment(c, 0, ctypes.c_double(0.0), ctypes.c_double(t0), 0,
                                            ctypes.c_double(0.0)), "setup experiment")
        self._check(dll.fmi2EnterInitializationMode(c), "enter initialization")
        self._apply_parameters(params)
        self._check(self._set_real(c, vr_in, len(inp), inp), "setting inputs")
        self._check(dll.fmi2ExitInitializationMode(c), "exit initialization")

    def _outputs(self, outputs):
        unknown = [o for o in outputs if o not in self.output_names]
        if unknown:
            raise ValueError(f"{self.path.name} has no output(s) {unknown}; outputs: {self.output_names}")
        nout = len(outputs)
        return nout, (ctypes.c_uint * nout)(*[self.variables[o].valueReference for o in outputs]), \
            (ctypes.c_double * nout)()

    # -- public ---------------------------------------------------------------------------
    def run(self, time, stroke, stroke_velocity, params: dict | None = None,
            outputs=("force",), temperature=None) -> np.ndarray:
        """Simulate and return the outputs at every sample: shape (n,) for one output, else (n, k).

        time [s] strictly increasing, stroke [m], stroke_velocity [m/s]; params: FMU parameter
        name -> SI value (the others keep their start values); temperature [degC]: optional
        measured oil temperature, fed to the ``oil_temperature`` input with ``thermal_source = 1``.
        Raises SimulationError if the FMU reports an error (e.g. non-finite stroke, failed solve).
        """
        t, x, v = as_stroke_arrays(time, stroke, stroke_velocity)
        if temperature is not None:
            if "oil_temperature" not in self.variables:
                raise ValueError(f"{self.path.name} has no oil_temperature input")
            temp = np.ascontiguousarray(temperature, dtype=float)
            if temp.shape != t.shape:
                raise ValueError("temperature must have the length of time")
            params = {**(params or {}), "thermal_source": 1}
            return self._run3(t, x, v, temp, params, outputs)
        nout, vr_out, buf = self._outputs(outputs)
        c = self._component
        inp, vr_in = self._in, self._vr_in
        inp[0], inp[1] = float(x[0]), float(v[0])
        self._start(float(t[0]), params, vr_in, inp)
        self._check(self._get_real(c, vr_out, nout, buf), "reading outputs")
        if self._c_loop is not None:
            return self._loop_in_c(t, x, v, None, vr_in, vr_out, nout, buf)
        result = np.empty((t.size, nout))
        set_real, do_step, get_real = self._set_real, self._do_step, self._get_real
        result[0] = buf[:]
        tl, xl, vl = t.tolist(), x.tolist(), v.tolist()
        shift = 0 if self.input_mode == _REPLAY else 1
        for k in range(1, t.size):
            j = k - shift
            inp[0] = xl[j]
            inp[1] = vl[j]
            st = set_real(c, vr_in, 2, inp) | do_step(c, tl[k - 1], tl[k] - tl[k - 1], 1) \
                | get_real(c, vr_out, nout, buf)
            if st > 1:
                self._check(st, f"step {k} (t = {tl[k - 1]:.6g} s)")
            if nout == 1:
                result[k, 0] = buf[0]
            else:
                result[k] = buf[:]
        return result[:, 0] if nout == 1 else result

    def _loop_in_c(self, t, x, v, temp, vr_in, vr_out, nout, buf) -> np.ndarray:
        """Samples 1.. through the C stepping loop (same FMI calls as the Python loop)."""
        result = np.empty((t.size, nout))
        result[0] = buf[:]
        dp = ctypes.POINTER(ctypes.c_double)
        failed = ctypes.c_int(0)
        ptr = lambda a: a.ctypes.data_as(dp) if a is not None else None  # noqa: E731
        st = self._c_loop(self._fn[0], self._fn[1], self._fn[2], self._component, t.size, ptr(t), ptr(x), ptr(v),
                          ptr(temp), vr_in, len(vr_in), vr_out, nout, 0 if self.input_mode == _REPLAY else 1,
                          ptr(result), ctypes.byref(failed))
        if st > 1:
            k = failed.value
            self._check(st, f"step {k} (t = {t[k - 1]:.6g} s)")
        return result[:, 0] if nout == 1 else result

    def _run3(self, t, x, v, temp, params, outputs) -> np.ndarray:
        """``run`` with the oil temperature as a third input (thermal drift element)."""
        nout, vr_out, buf = self._outputs(outputs)
        c = self._component
        vr_in = (ctypes.c_uint * 3)(self._vr_in[0], self._vr_in[1], self.variables["oil_temperature"].valueReference)
        inp = (ctypes.c_double * 3)(float(x[0]), float(v[0]), float(temp[0]))
        self._start(float(t[0]), params, vr_in, inp)
        self._check(self._get_real(c, vr_out, nout, buf), "reading outputs")
        if self._c_loop is not None:
            return self._loop_in_c(t, x, v, temp, vr_in, vr_out, nout, buf)
        result = np.empty((t.size, nout))
        result[0] = buf[:]
        shift = 0 if self.input_mode == _REPLAY else 1
        for k in range(1, t.size):
            j = k - shift
            inp[0], inp[1], inp[2] = x[j], v[j], temp[j]
            st = self._set_real(c, vr_in, 3, inp) | self._do_step(c, t[k - 1], t[k] - t[k - 1], 1) \
                | self._get_real(c, vr_out, nout, buf)
            if st > 1:
                self._check(st, f"step {k} (t = {t[k - 1]:.6g} s)")
            result[k] = buf[:]
        return result[:, 0] if nout == 1 else result

    def close(self):
        """Free the FMU instance and delete the extracted files."""
        if getattr(self, "fmu", None) is not None:
            try:
                self.fmu.terminate()
            except Exception:  # noqa: BLE001 - best effort on shutdown
                pass
            self.fmu.freeInstance()
            self.fmu = None
        _LIVE.discard(self)
        shutil.rmtree(getattr(self, "_unzip", ""), ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        try:
            self.close()
        except Exception:  # noqa: BLE001
            pass
