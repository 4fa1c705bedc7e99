"""Time integration of the damper models: L-stable SDIRK2 with error-controlled sub-steps.

This is the readable reference of the integrator. The C kernel (``damper_fmu/c/damper_kernel.c``,
used by the native FMU and by ``simulate`` when it is compiled) implements the same algorithm
operation for operation; tests/test_native.py holds the two equal to 1e-9 relative.

Scheme: Alexander's two-stage, second-order, stiffly accurate SDIRK (gamma = 1 - 1/sqrt(2)),
which is L-stable: the microsecond modes of the silent blocks (m / c_B ~ 4 us with the paper's
Table 2) are damped out at any step, while the slow dynamics is second-order accurate.

Internal steps (``tolerance`` > 0, the default): step doubling. Each trial sub-step H is taken
once whole and once as two halves; their difference, measured as the silent-block forces it
implies [N], must stay below ``tolerance`` x the model's force scale (largest |Fc,O| ordinate),
else H shrinks (by 5 when a stage's Newton solve fails: a smaller step is an easier solve);
the next H follows the usual third-root rule (local error ~ H^3), capped by ``max_step``. The two-halves result is kept. ``tolerance = 0`` gives fixed sub-steps of at most
``max_step`` (used for step-refinement studies and the identification); a sub-step whose stage
solve fails is taken as two halves, up to ``MAX_SPLITS`` times.

Inputs within a communication step [t, t + h] (``input_mode``): the stroke the damper sees is a
cubic Hermite curve (stroke and velocity consistent, the stroke continuous across communication
points) from the stroke at the end of the previous step to a target at t + h:

* ``EXTRAPOLATE`` (0, FMI co-simulation default): the stroke x1 [m] and velocity v1 [m/s] set
  before ``step`` are the values at t (start of the step), as a multibody master sets them. The
  target is x1 + v1 h + a h^2/2, v1 + a h with the stroke acceleration a [m/s^2] given by the
  master (``accel``, from fmi2SetRealInputDerivatives) or estimated from the last three velocity
  samples (``velocity_extrapolation``: a cubic through the last four where they are smooth, else a
  quadratic or a limited difference, so a velocity jump is not extrapolated into an overshoot). The curve
  starts with the master's velocity: a jump in it is a kink in the stroke.
* ``REPLAY`` (1): the values set before ``step`` are those at t + h (a known stroke history being
  replayed, as on a rig or by ``tuner.identification.runner``): the target is (x1, v1) itself, no input lag;
  the curve starts with the velocity reached at the end of the previous step.

The force returned by ``step`` is the output force at the end of the step [N], tension positive.
"""
from __future__ import annotations

import math

import numpy as np

from . import native
from .effects import Effects
from .models import ConvergenceError, make_model
from .parameters import EFFECT_MODELS, EFFECTS_INSIDE
from .solver_options import DEFAULT_MAX_STEP, DEFAULT_TOLERANCE, EXTRAPOLATE, REPLAY, SolverOptions

__all__ = ["EXTRAPOLATE", "REPLAY", "GAMMA", "DEFAULT_MAX_STEP", "DEFAULT_TOLERANCE", "INPUT_INTERPOLATION_DESCRIPTION", "Simulator",
           "SolverOptions", "simulate", "velocity_extrapolation"]

GAMMA = 1.0 - 1.0 / math.sqrt(2.0)
_C21 = (1.0 - GAMMA) / GAMMA
#: What the FMU parameter ``input_interpolation`` means (shared by the Python and native FMUs).
INPUT_INTERPOLATION_DESCRIPTION = (
    "0 (co-simulation, default): stroke and stroke_velocity are the values at the START of each "
    "communication step, as a multibody master or fmpy's simulate_fmu sets them; the stroke is "
    "extrapolated over the step with the acceleration given by fmi2SetRealInputDerivatives or "
    "estimated from the last velocity samples. 1 (replay): the values are those at the END of the "
    "step, for a runner that sets them ahead (tuner.identification.runner); with simulate_fmu it lags one step.")
#: Smallest internal step [s] before the integrator gives up.
MIN_STEP = 1e-12
#: Relative slack of the step division. Masters pass the step as (k+1)h - kh, which differs from h
#: by float jitter (1e-12 relative after seconds, growing with the time); the force must not depend
#: on those last bits. A communication step within STEP_RTOL (relative) of a whole number n of
#: ``max_step`` is taken as exactly n max_step (the model time then differs from the master's by at
#: most that fraction of a step, far below the integration error); the last adaptive sub-step is
#: stretched by up to STEP_RTOL rather than followed by a sliver sub-step. A sliver of 1e-15 s changed
#: the force by up to 4e-4 of its peak.
STEP_RTOL = 1e-6
#: Internal step attempts in one communication step beyond which it fails: every loop is bounded.
MAX_ATTEMPTS = 100_000
#: Communication steps longer than this many ``max_step`` are refused.
MAX_STEP_RATIO = 1e8
#: Fixed steps (tolerance 0): how many times a sub-step whose stage solve fails is halved.
MAX_SPLITS = 8


def velocity_extrapolation(samples) -> tuple[float, float, float]:
    """Taylor coefficients (a [m/s^2], j [m/s^3], s [m/s^4]) of the stroke velocity after the
    newest sample, v(t0 + tau) = v0 + a tau + j tau^2 / 2 + s tau^3, from the master's velocity
    samples ``[(t0, v0), (t1, v1), ...]`` (newest first, up to four).

    The highest-order polynomial through the samples whose differences look smooth: the cubic
    through four samples if their third differences agree in sign and within a factor 2, else the
    quadratic through three if their backward differences do, else the smaller of the last two
    differences as the acceleration if they agree in sign, else zero. A velocity jump or noise
    therefore falls back to a low order, never to an overshoot.
    """
    if len(samples) < 3:
        return 0.0, 0.0, 0.0
    (t0, v0), (t1, v1), (t2, v2) = samples[:3]
    d01 = (v0 - v1) / (t0 - t1)
    d12 = (v1 - v2) / (t1 - t2)
    d012 = (d01 - d12) / (t0 - t2)
    if len(samples) == 4:
        t3, v3 = samples[3]
        d23 = (v2 - v3) / (t2 - t3)
        j1, j2 = d01 - d12, d12 - d23
        if j1 * j2 > 0.0 and abs(j1 - j2) <= 0.5 * max(abs(j1), abs(j2)):
            d0123 = (d012 - (d12 - d23) / (t1 - t3)) / (t0 - t3)
            a = d01 + d012 * (t0 - t1) + d0123 * (t0 - t1) * (t0 - t2)
            j = 2.0 * d012 + 2.0 * d0123 * ((t0 - t1) + (t0 - t2))
            return a, j, d0123
    if d01 * d12 <= 0.0:
        return 0.0, 0.0, 0.0
    if abs(d01 - d12) <= 0.5 * max(abs(d01), abs(d12)):
        return d01 + d012 * (t0 - t1), 2.0 * d012, 0.0
    return (d01 if abs(d01) <= abs(d12) else d12), 0.0, 0.0


class Simulator:
    """Steps one damper model in time; the engine behind the Python FMUs and in-process runs.

    max_step [s]: largest internal step; input_mode: EXTRAPOLATE or REPLAY (module docstring);
    tolerance [-]: local error tolerance relative to the model's force scale (0: fixed steps).
    """

    def __init__(self, model, max_step: float = DEFAULT_MAX_STEP, input_mode: int = EXTRAPOLATE,
                 tolerance: float = DEFAULT_TOLERANCE):
        if not (max_step > 0.0 and math.isfinite(max_step)):
            raise ValueError(f"max_step must be a positive number of seconds, got {max_step}")
        if input_mode not in (EXTRAPOLATE, REPLAY):
            raise ValueError(f"input_mode must be {EXTRAPOLATE} (extrapolate) or {REPLAY} (replay)")
        if not (tolerance >= 0.0 and math.isfinite(tolerance)):
            raise ValueError(f"tolerance must be a non-negative number, got {tolerance}")
        self.model = model
        self.max_step = float(max_step)
        self.input_mode = input_mode
        self.tolerance = float(tolerance)
        self.y: list[float] = []
        self.x1 = self.v1 = 0.0  # stroke [m] and velocity [m/s] the integrator reached
        self.force = 0.0
        self.time = 0.0
        self.h_next = self.max_step
        self.samples: list[tuple[float, float]] = []  # master's (time, velocity), newest first
        #: effect elements (lumped and two-chamber models); None or inactive: the base model alone
        self.effects = _effects(model)
        #: measured oil temperature [degC] for the thermal drift element (None: internal balance)
        self.temperature_input: float | None = None

    def set_model(self, model) -> None:
        """Replace the model (new parameter values) keeping the state, effect states included. Effects
        switched on here start at the present stroke (free play engaged, no hysteresis force, the
        bypass seen there), as in the C FMUs (fmu_common.c: build)."""
        old = self.effects
        self.model = model
        self.effects = _effects(model)
        if self.effects is not None and self.effects.active:
            if old is not None and old.active:
                self.effects.set_state(old.get_state())
            else:
                self.effects.x_eff = self.effects.x_seen = self.x1
                self.effects.v_seen = self.v1

    def initialize(self, x1: float, v1: float, t0: float = 0.0) -> float:
        """Start in the model's force-free state at stroke x1 [m], velocity v1 [m/s], time t0 [s]."""
        _check_input(x1, v1)
        self.y = self.model.initial_state(x1, v1)
        self.x1, self.v1 = x1, v1
        self.time = t0
        self.h_next = self.max_step
        self.samples = []
        self.force = self.model.force(self.y, x1, v1)
        e = self.effects
        if e is not None and e.active:
            e.initialize(x1, self.force, v1)
            self.force += e.f0 + (e.ff * math.tanh(v1 / e.v_eps) if e.ff and not e.inside else 0.0)
        return self.force

    def step(self, h: float, x1: float, v1: float, accel: float | None = None) -> float:
        """Advance by h [s] with inputs x1 [m], v1 [m/s] (meaning per ``input_mode``) and, in
        EXTRAPOLATE mode, the optional stroke acceleration accel [m/s^2]; return the force [N]."""
        _check_input(x1, v1)
        if not (h > 0.0 and math.isfinite(h)):
            raise ValueError(f"step size must be a positive finite number, got {h}")
        # a step within STEP_RTOL of a whole number of max_step is taken as exactly that
        hn = max(1, math.ceil(h / (self.max_step * (1.0 + STEP_RTOL)))) * self.max_step
        if abs(h - hn) <= STEP_RTOL * hn:
            h = hn
        if h / self.max_step > MAX_STEP_RATIO:
            raise ValueError(f"communication step {h:g} s is more than {MAX_STEP_RATIO:g} internal steps of "
                             f"{self.max_step:g} s")
        if self.input_mode == EXTRAPOLATE:
            self.samples = [(self.time, v1), *self.samples[:3]]
            if accel is not None and math.isfinite(accel):
                a, j, sn = accel, 0.0, 0.0
            else:
                a, j, sn = velocity_extrapolation(self.samples)
            xh = x1 + h * (v1 + h * (0.5 * a + h * (j / 6.0 + 0.25 * sn * h)))
            vh = v1 + h * (a + h * (0.5 * j + sn * h))
        else:
            xh, vh = x1, v1
        # cubic Hermite stroke from (x0, v0) at 0 to (xh, vh) at h: the stroke is continuous; in
        # EXTRAPOLATE mode the velocity starts at the master's (a jump in its velocity is a kink in
        # the stroke, not an overshoot of the velocity)
        x0, v0 = self.x1, (v1 if self.input_mode == EXTRAPOLATE else self.v1)
        d = (xh - x0) / h
        c2 = (3.0 * d - 2.0 * v0 - vh) / h
        c3 = (v0 + vh - 2.0 * d) / (h * h)
        e = self.effects
        with_effects = e is not None and e.active
        if with_effects:
            self.model.damping_scale = e.damping_scale()
            pstate = (e.x_eff, e.engaged)
            play = e.play
        else:
            pstate, play = None, None
        stage, model = self.model.stage, self.model

        def sdirk(y, ps, tau, H):
            """One SDIRK2 step of size H from tau; returns (y, play state, x, v seen at the end)."""
            g = GAMMA * H
            t1 = tau + g
            xa, va = x0 + t1 * (v0 + t1 * (c2 + t1 * c3)), v0 + t1 * (2.0 * c2 + 3.0 * c3 * t1)
            if play is not None:
                ps, xa, va = play(ps, xa, va)
            y1 = stage(y, g, xa, va)
            t2 = tau + H
            xb, vb = x0 + t2 * (v0 + t2 * (c2 + t2 * c3)), v0 + t2 * (2.0 * c2 + 3.0 * c3 * t2)
            if play is not None:
                ps, xb, vb = play(ps, xb, vb)
            return stage([a + _C21 * (b - a) for a, b in zip(y, y1)], g, xb, vb), ps, xb, vb

        y = self.y
        xs, vs = xh, vh
        def split(y, ps, tau, H, depth):
            """A fixed sub-step; one whose stage solve fails is taken as two halves (recursively)."""
            try:
                return sdirk(y, ps, tau, H)
            except ConvergenceError:
                if depth >= MAX_SPLITS:
                    raise
                ym, pm, _, _ = split(y, ps, tau, 0.5 * H, depth + 1)
                return split(ym, pm, tau + 0.5 * H, 0.5 * H, depth + 1)

        if self.tolerance == 0.0:
            n = max(1, math.ceil(h / (self.max_step * (1.0 + STEP_RTOL))))
            H = h / n
            for k in range(n):
                y, pstate, xs, vs = split(y, pstate, k * H, H, 0)
        else:
            tol = self.tolerance * model.force_scale()
            tau = 0.0
            H = min(self.h_next, self.max_step)
            failure = None
            for attempt in range(MAX_ATTEMPTS + 1):
                if attempt == MAX_ATTEMPTS:
                    raise ConvergenceError(f"more than {MAX_ATTEMPTS} internal step attempts in one communication "
                                           f"step at t = {self.time + tau:.9g} s (last internal step {H:.3g} s)")
                proposed = H
                last = tau + H * (1.0 + STEP_RTOL) >= h
                if last:
                    H = h - tau
                try:
                    yf, _, _, _ = sdirk(y, pstate, tau, H)
                    ym, pm, _, _ = sdirk(y, pstate, tau, 0.5 * H)
                    y2, p2, x2, v2 = sdirk(ym, pm, tau + 0.5 * H, 0.5 * H)
                    err = model.error_norm(yf, y2)
                except ConvergenceError as exc:  # a stage solve failed: retry with a smaller step
                    err, failure = math.inf, exc
                else:
                    failure = None
                fac = 4.0 if err == 0.0 else min(4.0, max(0.2, 0.9 * (tol / err) ** (1.0 / 3.0)))
                if err <= tol:
                    y, pstate, xs, vs = y2, p2, x2, v2
                    if last:
                        self.h_next = min(self.max_step, max(H * fac, proposed))
                        break
                    tau += H
                    H = min(self.max_step, H * fac)
                else:
                    H *= fac
                    if H < MIN_STEP:
                        why = (f"last: {failure}" if failure is not None and err == math.inf else
                               f"error {err:.3g} N, tolerance {tol:.3g} N")
                        raise ConvergenceError(f"internal step fell below {MIN_STEP:g} s at t = "
                                               f"{self.time + tau:.9g} s ({why})")
        self.y = y
        self.time += h
        self.x1, self.v1 = xh, vh
        if with_effects:
            e.x_eff, e.engaged = pstate
            f = e.output(model.force(y, xs, vs), h, xs, vs, (vh - v0) / h,
                         model.valve_gain(vs) if e.tau else 0.0, self.temperature_input)
        else:
            f = model.force(y, xs, vs)
        if not math.isfinite(f):
            raise FloatingPointError("damper force became non-finite")
        self.force = f
        return f

    def get_state(self) -> list[float]:
        """Complete integrator state (model state, stroke, force, time, step, velocity samples,
        effect states) as floats."""
        s = [*self.samples, *[(0.0, 0.0)] * 4][:4]
        extra = self.effects.get_state() if self.effects is not None and self.effects.active else []
        return [*self.y, self.x1, self.v1, self.force, self.time, self.h_next, float(len(self.samples)),
                *[v for pair in s for v in pair], *extra]

    def set_state(self, state) -> None:
        n = self.model.n_state
        base = n + 14
        extra = len(state) - base
        active = self.effects is not None and self.effects.active
        if extra < 0 or (extra > 0) != active:
            raise ValueError(f"state of length {len(state)} does not fit this model and its effects")
        st = [float(v) for v in state]
        self.y = st[:n]
        self.x1, self.v1, self.force, self.time, self.h_next = st[n:n + 5]
        count = int(st[n + 5])
        self.samples = [(st[n + 6 + 2 * i], st[n + 7 + 2 * i]) for i in range(count)]
        if active:
            self.effects.set_state(st[base:])


def _effects(model) -> Effects | None:
    return Effects(model.params, model.kind in EFFECTS_INSIDE) if model.kind in EFFECT_MODELS else None


def _check_input(x1: float, v1: float) -> None:
    if not (math.isfinite(x1) and math.isfinite(v1)):
        raise ValueError(f"non-finite input: stroke={x1}, stroke_velocity={v1}")


def simulate(model, time, stroke, stroke_velocity, *, params=None, temperature=None,
             solver: SolverOptions = SolverOptions(), backend: str = "auto") -> np.ndarray:
    """In-process run of ``model`` (instance or kind name) under a sampled stroke.

    time [s] (strictly increasing), stroke [m], stroke_velocity [m/s]: arrays of equal length;
    temperature [degC]: optional measured oil temperature for the thermal drift element;
    solver: largest internal step [s], tolerance and input mode (``SolverOptions``).
    Returns the force [N] at every sample; sample 0 is the initial (force-free) state. With the
    default REPLAY mode, this is what the FMU computes when driven by ``tuner.identification.runner``.
    backend: 'python' (this module), 'native' (the C kernel; error if not compiled) or 'auto'
    (native when available). The kernel checks a kind name's ``params`` as ``make_model`` does (same
    messages), so it gets them without a Python model built first (5-8 % of an identification evaluation).
    """
    t = np.asarray(time, dtype=float)
    x = np.asarray(stroke, dtype=float)
    v = np.asarray(stroke_velocity, dtype=float)
    if not (t.shape == x.shape == v.shape and t.ndim == 1 and t.size >= 2):
        raise ValueError("time, stroke and stroke_velocity must be 1-D arrays of equal length >= 2")
    temp = None
    if temperature is not None:
        temp = np.asarray(temperature, dtype=float)
        if temp.shape != t.shape:
            raise ValueError("temperature must have the length of time")
    if backend not in ("auto", "python", "native"):
        raise ValueError(f"backend must be 'auto', 'python' or 'native', got {backend!r}")
    if backend != "python" and (native.available() or backend == "native"):
        kind, values = (model, params or {}) if isinstance(model, str) else (model.kind, model.params)
        if kind in native.KINDS:
            return native.simulate(kind, values, t, x, v, solver=solver, temperature=temp)
    if isinstance(model, str):
        model = make_model(model, params)  # ValueError naming an unknown kind or a bad parameter
    input_mode = solver.input_mode
    sim = Simulator(model, max_step=solver.max_step, input_mode=input_mode, tolerance=solver.tolerance)
    out = np.empty(t.size)
    tl, xl, vl = t.tolist(), x.tolist(), v.tolist()
    tk = temp.tolist() if temp is not None else None
    if tk is not None:
        sim.temperature_input = tk[0]
    out[0] = sim.initialize(xl[0], vl[0], tl[0])
    step = sim.step
    for k in range(1, t.size):
        j = k if input_mode == REPLAY else k - 1
        if tk is not None:
            sim.temperature_input = tk[j]
        out[k] = step(tl[k] - tl[k - 1], xl[j], vl[j])
    return out
