"""Simulation engines for identification: the built FMU through fmpy (default), the C kernel
directly (``native``: one call per test, the same code the native FMU runs), or the Python
reference in-process (``inprocess``).

Evaluations run in worker processes (``tuner.worker_processes``), each holding ONE FMU instance reused for every
candidate (reset + parameters re-applied, see ``tuner.identification.runner``) and the identification strokes,
sent once at start-up. A generation is evaluated as one batch (``sse_batch``), so evaluations
run in parallel and are counted exactly. The other engines run the same equations without FMI;
tests/test_fmu.py and tests/test_native.py prove all give the same forces.

Objective pieces per candidate: SSE [N^2] over all identification samples after the warm-up
of each test, and N (number of samples): the paper's fitness is G = N / SSE (eq. 5).

Band-limited comparison (``Signals.oversample``): the measured force reaches the fit rate through
an anti-aliasing low-pass (``tuner.data.preprocess.Resampler``), i.e. it is filter(F(x)). Sampling the
model's force at the fit rate instead gives F(filter(x)), which keeps the harmonics of the
characteristic's kinks above the fit band, aliased: on lumped-model data with 20 N noise at 1 kHz
the TRUE parameters scored 21.6 N RMSE at 200 Hz against 8.9 N of noise in the band. So the model
is simulated on a grid ``oversample`` times finer (stroke by cubic Hermite through the samples'
stroke and velocity) and its force is passed through the same kind of low-pass back to the
samples: the true parameters then score 8.6 N (``simulate_signals``, the one place for this).
"""
from __future__ import annotations

import math
import multiprocessing.util
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.interpolate import CubicHermiteSpline
from threadpoolctl import threadpool_limits

from damper_fmu import native, simulate
from damper_fmu.fmu import ensure_fmu
from damper_fmu.integrator import DEFAULT_MAX_STEP, DEFAULT_TOLERANCE, SolverOptions
from damper_fmu.models import ConvergenceError
from tuner.data.prefilter import Prefilter
from tuner.data.preprocess import Resampler
from tuner.identification.runner import FmuRunner, SimulationError
from tuner.worker_processes import exit_with_parent, pool_context

__all__ = ["Signals", "Engine", "ENGINES", "fastest_engine", "oversampling", "simulate_signals",
           "IDENTIFICATION_STEP", "IDENTIFICATION_TOLERANCE"]

ENGINES = ("fmu", "native", "inprocess")
#: Internal steps of identification runs: fixed sub-steps (tolerance 0) of at most 1 ms [s].
#: Fixed steps keep the objective a smooth function of the parameters; error-controlled steps
#: make it jump by up to the local tolerance wherever a trial step is accepted or rejected, which
#: stalls the finite-difference Jacobians of the polish (measured on tests/test_recovery.py data:
#: 31.8 N identification RMSE, against 26.3 N with fixed steps, which is what the true parameters
#: give there). The validation runs through the FMU at its defaults (error-controlled).
IDENTIFICATION_STEP = 1e-3
IDENTIFICATION_TOLERANCE = 0.0


def fastest_engine() -> str:
    """'native' where the C kernel is compiled, else 'inprocess' (same results, slower)."""
    return "native" if native.available() else "inprocess"


@dataclass
class Signals:
    """One test as the engine needs it: time [s], stroke [m], stroke_velocity [m/s], force [N],
    and ``mask``: samples that count in the objective (False during the warm-up)."""

    name: str
    time: np.ndarray
    stroke: np.ndarray
    stroke_velocity: np.ndarray
    force: np.ndarray
    mask: np.ndarray
    temperature: np.ndarray | None = None  # measured oil temperature [degC], if the data has it
    #: the model runs on a grid this many times finer and its force is low-passed back to these
    #: samples (module docstring); 1: simulated at these samples
    oversample: int = 1
    #: the filter the lab applied to the measured channels (``tuner.data.prefilter``), applied to the
    #: simulated force on the fine grid before the low-pass; None: none declared
    prefilter: Prefilter | None = None

    @cached_property
    def fine(self) -> tuple:
        """(time [s], stroke [m], velocity [m/s], temperature [degC] or None) on the fine grid:
        cubic Hermite through (stroke, velocity) samples, temperature linear."""
        m = int(self.oversample)
        t = self.time
        tf = np.append((t[:-1, None] + np.diff(t)[:, None] * (np.arange(m) / m)).ravel(), t[-1])
        h = CubicHermiteSpline(self.time, self.stroke, self.stroke_velocity)
        temp = None if self.temperature is None else np.interp(tf, self.time, self.temperature)
        return tf, h(tf), h(tf, 1), temp

    @cached_property
    def low_pass(self):
        """The anti-aliasing resampler fine grid -> these samples (``tuner.data.preprocess.Resampler``)."""
        rate = (len(self.time) - 1) / (self.time[-1] - self.time[0])
        return Resampler.design(rate * self.oversample, rate)

    def band_limit(self, fine_force: np.ndarray) -> np.ndarray:
        """Force [N] at these samples from the force on the fine grid, as the measured force was made:
        through the lab's declared ``prefilter`` (on the fine grid), then low-passed where the
        filter's support lies inside the test (``band_limited_span``), plain samples elsewhere
        (those are outside the mask). The one place where a simulated force is made comparable."""
        if self.prefilter is not None:
            rate = (len(self.time) - 1) / (self.time[-1] - self.time[0]) * self.oversample
            fine_force = self.prefilter.apply(fine_force, rate)
        if self.oversample == 1:
            return np.asarray(fine_force, dtype=float)
        out = np.array(fine_force[::self.oversample], dtype=float)
        k0, n = self.band_limited_span()
        out[k0:k0 + n] = self.low_pass.apply(fine_force)
        return out

    def band_limited_span(self) -> tuple[int, int]:
        """(first sample, count) of the samples that the low-pass fully covers."""
        if self.oversample == 1:
            return 0, len(self.time)
        rs = self.low_pass
        return rs.first_index(), rs.output_length((len(self.time) - 1) * self.oversample + 1)


def oversampling(rate_hz: float, step_s: float = IDENTIFICATION_STEP) -> int:
    """Oversampling factor that puts the simulation grid at ``step_s`` [s] (the identification step) or finer
    (>= 1). The fixed sub-steps of the identification runs are then that grid's intervals wherever the grid is
    finer than the ``Engine``'s ``max_internal_step`` (``IDENTIFICATION_STEP`` by default)."""
    if not (step_s > 0.0 and math.isfinite(step_s)):
        raise ValueError(f"the simulation step must be a positive number of seconds, got {step_s!r}")
    return max(1, int(math.ceil(1.0 / (step_s * rate_hz) - 1e-9)))


def simulate_signals(model: str, params: dict, s: Signals, *, engine: str = "fmu", fmu_path=None,
                     max_internal_step: float | None = IDENTIFICATION_STEP,
                     tolerance: float | None = IDENTIFICATION_TOLERANCE) -> np.ndarray:
    """Simulated force [N] at the samples of ``s`` (band-limited when ``s.oversample`` > 1), the
    way the identification objective computes it; steps as in ``Engine`` (None: the FMU's own
    defaults)."""
    if engine == "fmu" and fmu_path is None:
        fmu_path = ensure_fmu(model)
    sim = _Simulator(model, engine, str(fmu_path) if fmu_path else None, max_internal_step, tolerance)
    try:
        return sim.force(params, s)
    finally:
        sim.close()


class _Simulator:
    """Per-process simulator of one model kind: an FmuRunner or the in-process engine."""

    def __init__(self, model: str, engine: str, fmu_path: str | None, max_internal_step: float,
                 tolerance: float):
        self.model, self.engine = model, engine
        self.max_internal_step, self.tolerance = max_internal_step, tolerance
        self.runner = None
        if engine == "fmu":
            self.runner = FmuRunner(fmu_path, max_internal_step=max_internal_step, tolerance=tolerance)

    def force(self, params: dict, s: Signals) -> np.ndarray:
        """Simulated force [N] at the samples of ``s`` (band-limited when oversampled)."""
        if s.oversample == 1:
            return s.band_limit(self._run(params, s.time, s.stroke, s.stroke_velocity, s.temperature))
        return s.band_limit(self._run(params, *s.fine))

    def _run(self, params: dict, t, x, v, temperature) -> np.ndarray:
        # the measured temperature drives the thermal drift element when that element is on
        temp = temperature if params.get("thermal_beta", 0.0) and temperature is not None else None
        if self.runner is not None:
            return self.runner.run(t, x, v, params, temperature=temp)
        solver = SolverOptions(
            max_step=DEFAULT_MAX_STEP if self.max_internal_step is None else self.max_internal_step,
            tolerance=DEFAULT_TOLERANCE if self.tolerance is None else self.tolerance)
        return simulate(self.model, t, x, v, params=params, temperature=temp, solver=solver,
                        backend="native" if self.engine == "native" else "python")

    def residuals(self, params: dict, tests: list[Signals]) -> tuple[np.ndarray | None, str]:
        """(measured minus simulated force [N] over the counted samples of all tests, ''), or
        (None, the reason) when the candidate cannot be simulated (invalid parameters, a failed
        implicit solve, inputs the FMU refuses). Other exceptions are bugs and propagate."""
        try:
            r = np.concatenate([(s.force - self.force(params, s))[s.mask] for s in tests])
        except (SimulationError, ConvergenceError, ValueError, FloatingPointError) as err:
            return None, str(err)
        if not np.all(np.isfinite(r)):
            return None, "non-finite simulated force"
        return r, ""

    def sse(self, params: dict, tests: list[Signals]) -> tuple[float, str]:
        r, why = self.residuals(params, tests)
        return (math.inf if r is None else float(r @ r)), why

    def close(self):
        if self.runner is not None:
            self.runner.close()


_WORKER: dict = {}


def _close_worker() -> None:
    """Worker exit (a multiprocessing finalizer: a forked worker ends without atexit): free the worker's FMU
    while the interpreter is intact."""
    _WORKER["sim"].close()


def _init_worker(model, engine, fmu_path, max_internal_step, tolerance, tests):
    exit_with_parent()  # a killed run leaves no workers behind
    # one BLAS thread per worker: the workers already fill the cores, and OpenBLAS threads that spin
    # beside them oversubscribe the machine (measured: the form tests 20 % slower with 2 BLAS threads each)
    threadpool_limits(limits=1)
    _WORKER["sim"] = _Simulator(model, engine, fmu_path, max_internal_step, tolerance)
    _WORKER["tests"] = tests
    multiprocessing.util.Finalize(None, _close_worker, exitpriority=10)  # atexit does not run in a forked worker


def _worker_sse(params):
    return _WORKER["sim"].sse(params, _WORKER["tests"])


def _worker_residuals(params):
    return _WORKER["sim"].residuals(params, _WORKER["tests"])


class Engine:
    """Evaluates candidates of one model on the identification tests.

    model: a kind of damper_fmu.parameters.MODEL_KINDS; engine: 'fmu' | 'inprocess'; workers: number
    of worker processes (0: evaluate in this process); fmu_path: the model's FMU (engine 'fmu');
    ``after_batch``: None, or a function called after every batch (the diagnosis's progress tick).
    """

    def __init__(self, model: str, tests: list[Signals], *, engine: str = "fmu", workers: int = 2,
                 fmu_path=None, max_internal_step: float = IDENTIFICATION_STEP,
                 tolerance: float = IDENTIFICATION_TOLERANCE):
        if engine not in ENGINES:
            raise ValueError(f"unknown engine '{engine}', expected one of {ENGINES}")
        if engine == "fmu" and fmu_path is None:
            fmu_path = ensure_fmu(model)
        if workers < 0:
            raise ValueError("workers must be >= 0")
        self.model, self.engine, self.workers = model, engine, int(workers)
        self.tests = tests
        self.fmu_path = fmu_path  # the FMU of engine 'fmu' (None: the built one), for runs at other steps
        self.n_samples = int(sum(int(s.mask.sum()) for s in tests))
        self.evaluations = 0
        self.failures = 0  # candidates that could not be simulated
        self.last_failure = ""  # the reason the last of them gave
        self.after_batch = None  # called with no argument after every batch (a progress display's tick)
        args = (model, engine, str(fmu_path) if fmu_path else None, max_internal_step, tolerance, tests)
        if self.workers == 0:
            self._local = _Simulator(*args[:5])
            self._pool = None
        else:
            self._local = None
            self._pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=pool_context(),
                                             initializer=_init_worker, initargs=args)
        # while the workers fill the cores, this process's BLAS runs on one thread too (its spinning
        # threads slowed the workers: the form tests 9 % slower with the workers' limit alone); restored
        # by close()
        self._blas = threadpool_limits(limits=1) if self.workers else None

    def _record(self, results: list[tuple]) -> list:
        """Values of (value, reason) pairs; failures counted, the last reason kept; ``after_batch`` called."""
        for _, why in results:
            if why:
                self.failures += 1
                self.last_failure = why
        if self.after_batch is not None:
            self.after_batch()
        return [v for v, _ in results]

    def sse_batch(self, candidates: list[dict]) -> np.ndarray:
        """SSE [N^2] of each candidate parameter set (inf for a candidate that cannot be simulated:
        counted in ``failures``, its reason in ``last_failure``)."""
        self.evaluations += len(candidates)
        if self._pool is None:
            return np.array(self._record([self._local.sse(p, self.tests) for p in candidates]))
        return np.array(self._record(list(self._pool.map(_worker_sse, candidates, chunksize=1))))

    def residuals_batch(self, candidates: list[dict]) -> list[np.ndarray | None]:
        """Residual vector [N] of each candidate (None for a candidate that cannot be simulated,
        counted as in ``sse_batch``)."""
        self.evaluations += len(candidates)
        if self._pool is None:
            return self._record([self._local.residuals(p, self.tests) for p in candidates])
        return self._record(list(self._pool.map(_worker_residuals, candidates, chunksize=1)))

    def fitness_batch(self, candidates: list[dict]) -> np.ndarray:
        """Paper's fitness G = N / SSE [1/N^2] of each candidate (0 for a failed one)."""
        sse = self.sse_batch(candidates)
        with np.errstate(divide="ignore"):
            g = np.where(np.isfinite(sse), self.n_samples / np.maximum(sse, 1e-300), 0.0)
        return g

    def close(self):
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        if self._blas is not None:
            self._blas.restore_original_limits()
            self._blas = None
        if self._local is not None:
            self._local.close()
            self._local = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
