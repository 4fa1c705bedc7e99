"""Time integration of the damper models: L-stable SDIRK2 with internal sub-stepping.

Scheme: Alexander's two-stage, second-order, stiffly accurate SDIRK (gamma = 1 - 1/sqrt(2)),
which is L-stable: the microsecond modes of the silent blocks (m / c_B ~ 4 us with the paper's
Table 2) are damped out at any step, while the slow dynamics is second-order accurate.
A communication step h is split into ceil(h / max_step) equal sub-steps.

Inputs within a communication step (``input_mode``):

* ``EXTRAPOLATE`` (0, FMI co-simulation default): the stroke x1 [m] and velocity v1 [m/s] set
  before ``step`` are the values at the start of the step; x1 is extrapolated with v1, v1 is held.
* ``REPLAY`` (1): the values set before ``step`` are those at the END of the step (a known
  stroke history being replayed, as on a rig); x1 and v1 are interpolated linearly from the
  previous step's values. This removes the one-step input lag of EXTRAPOLATE.

The force returned by ``step`` is the output force at the end of the step [N], tension positive.
"""
from __future__ import annotations

import math

import numpy as np

from .effects import Effects
from .models import make_model

__all__ = ["EXTRAPOLATE", "REPLAY", "GAMMA", "DEFAULT_MAX_STEP", "Simulator", "simulate"]

EXTRAPOLATE = 0
REPLAY = 1
GAMMA = 1.0 - 1.0 / math.sqrt(2.0)
_C21 = (1.0 - GAMMA) / GAMMA
#: Default largest internal step [s] (accuracy vs step refinement: see tests/test_integrator.py).
DEFAULT_MAX_STEP = 1e-3


class Simulator:
    """Steps one damper model in time; the engine behind the FMUs and the in-process runs."""

    def __init__(self, model, max_step: float = DEFAULT_MAX_STEP, input_mode: int = EXTRAPOLATE):
        if not (max_step > 0.0 and math.isfinite(max_step)):
            raise ValueError(f"max_step must be a positive number of seconds, got {max_step}")
        if input_mode not in (EXTRAPOLATE, REPLAY):
            raise ValueError(f"input_mode must be {EXTRAPOLATE} (extrapolate) or {REPLAY} (replay)")
        self.model = model
        self.max_step = float(max_step)
        self.input_mode = input_mode
        self.y: list[float] = []
        self.x1 = self.v1 = 0.0
        self.force = 0.0
        #: effect elements (lumped model only); None or inactive: the base model alone
        self.effects = Effects(model.params) if model.kind == "lumped" else None
        #: measured oil temperature [degC] for the thermal drift element (None: internal balance)
        self.temperature_input: float | None = None

    def set_model(self, model) -> None:
        """Replace the model (new parameter values) keeping the state, effect states included."""
        old = self.effects
        self.model = model
        self.effects = Effects(model.params) if model.kind == "lumped" else None
        if old is not None and old.active and self.effects is not None and self.effects.active:
            self.effects.set_state(old.get_state())

    def initialize(self, x1: float, v1: float) -> float:
        """Start in the model's force-free state at stroke x1 [m], velocity v1 [m/s]."""
        _check_input(x1, v1)
        self.y = self.model.initial_state(x1, v1)
        self.x1, self.v1 = x1, v1
        self.force = self.model.force(self.y, x1, v1)
        e = self.effects
        if e is not None and e.active:
            e.initialize(x1, self.force)
            self.force += e.f0 + (e.ff * math.tanh(v1 / e.v_eps) if e.ff else 0.0)
        return self.force

    def step(self, h: float, x1: float, v1: float) -> float:
        """Advance by h [s] with inputs x1 [m], v1 [m/s] (meaning per ``input_mode``); return F [N]."""
        if not (math.isfinite(x1) and math.isfinite(v1)):
            raise ValueError(f"non-finite input: stroke={x1}, stroke_velocity={v1}")
        if not (h > 0.0):
            raise ValueError(f"step size must be positive, got {h}")
        if self.input_mode == EXTRAPOLATE:
            xa, va, xe, ve = x1, v1, x1 + v1 * h, v1
        else:
            xa, va, xe, ve = self.x1, self.v1, x1, v1
        if self.effects is not None and self.effects.active:
            return self._step_with_effects(h, xa, va, xe, ve)
        stage = self.model.stage
        y = self.y
        if h <= self.max_step:  # the usual case: one sub-step
            g = GAMMA * h
            y1 = stage(y, g, xa + GAMMA * (xe - xa), va + GAMMA * (ve - va))
            y = stage([a + _C21 * (b - a) for a, b in zip(y, y1)], g, xe, ve)
        else:
            n = math.ceil(h / self.max_step - 1e-9)
            g = GAMMA * h / n
            dx, dv = (xe - xa) / n, (ve - va) / n
            for k in range(n):
                x0, u0 = xa + k * dx, va + k * dv
                y1 = stage(y, g, x0 + GAMMA * dx, u0 + GAMMA * dv)
                y = stage([a + _C21 * (b - a) for a, b in zip(y, y1)], g, x0 + dx, u0 + dv)
        self.y = y
        self.x1, self.v1 = xe, ve
        self.force = f = self.model.force(y, xe, ve)
        if not math.isfinite(f):
            raise FloatingPointError("damper force became non-finite")
        return f

    def _step_with_effects(self, h: float, xa: float, va: float, xe: float, ve: float) -> float:
        """Step with the effect elements of ``damper_fmu.effects`` (same SDIRK2 scheme)."""
        e, model = self.effects, self.model
        model.damping_scale = e.damping_scale()
        stage, play = model.stage, e.play
        y = self.y
        n = max(1, math.ceil(h / self.max_step - 1e-9))
        g = GAMMA * h / n
        dx, dv = (xe - xa) / n, (ve - va) / n
        xs = vs = 0.0
        for k in range(n):
            x0, u0 = xa + k * dx, va + k * dv
            y1 = stage(y, g, *play(x0 + GAMMA * dx, u0 + GAMMA * dv))
            xs, vs = play(x0 + dx, u0 + dv)
            y = stage([a + _C21 * (b - a) for a, b in zip(y, y1)], g, xs, vs)
        self.y = y
        self.x1, self.v1 = xe, ve
        f = e.output(model.force(y, xs, vs), h, vs, (ve - va) / h,
                     model.valve_gain(vs) if e.tau else 0.0, self.temperature_input)
        if not math.isfinite(f):
            raise FloatingPointError("damper force became non-finite")
        self.force = f
        return f

    def get_state(self) -> list[float]:
        """Complete integrator state (model state, last inputs, force, effect states) as floats."""
        extra = self.effects.get_state() if self.effects is not None and self.effects.active else []
        return [*self.y, self.x1, self.v1, self.force, *extra]

    def set_state(self, state) -> None:
        n = self.model.n_state
        extra = len(state) - (n + 3)
        active = self.effects is not None and self.effects.active
        if extra < 0 or (extra > 0) != active:
            raise ValueError(f"state of length {len(state)} does not fit this model and its effects")
        self.y = [float(v) for v in state[:n]]
        self.x1, self.v1, self.force = (float(v) for v in state[n:n + 3])
        if active:
            self.effects.set_state(state[n + 3:])


def _check_input(x1: float, v1: float) -> None:
    if not (math.isfinite(x1) and math.isfinite(v1)):
        raise ValueError(f"non-finite input: stroke={x1}, stroke_velocity={v1}")


def simulate(model, time, stroke, stroke_velocity, *, params=None, max_step=DEFAULT_MAX_STEP,
             input_mode=REPLAY, temperature=None) -> np.ndarray:
    """In-process run of ``model`` (instance or kind name) under a sampled stroke.

    time [s] (strictly increasing), stroke [m], stroke_velocity [m/s]: arrays of equal length;
    temperature [degC]: optional measured oil temperature for the thermal drift element.
    Returns the force [N] at every sample; sample 0 is the initial (force-free) state. With the
    default REPLAY mode, this is exactly what the FMU computes when driven by ``tuner.runner``.
    """
    if isinstance(model, str):
        model = make_model(model, params)
    t = np.asarray(time, dtype=float)
    x = np.asarray(stroke, dtype=float)
    v = np.asarray(stroke_velocity, dtype=float)
    if not (t.shape == x.shape == v.shape and t.ndim == 1 and t.size >= 2):
        raise ValueError("time, stroke and stroke_velocity must be 1-D arrays of equal length >= 2")
    sim = Simulator(model, max_step=max_step, input_mode=input_mode)
    out = np.empty(t.size)
    tl, xl, vl = t.tolist(), x.tolist(), v.tolist()
    if temperature is not None:
        temp = np.asarray(temperature, dtype=float)
        if temp.shape != t.shape:
            raise ValueError("temperature must have the length of time")
        tk = temp.tolist()
        sim.temperature_input = tk[0]
        out[0] = sim.initialize(xl[0], vl[0])
        for k in range(1, t.size):
            j = k if input_mode == REPLAY else k - 1
            sim.temperature_input = tk[j]
            out[k] = sim.step(tl[k] - tl[k - 1], xl[j], vl[j])
        return out
    out[0] = sim.initialize(xl[0], vl[0])
    step = sim.step
    for k in range(1, t.size):
        if input_mode == REPLAY:
            out[k] = step(tl[k] - tl[k - 1], xl[k], vl[k])
        else:
            out[k] = step(tl[k] - tl[k - 1], xl[k - 1], vl[k - 1])
    return out
