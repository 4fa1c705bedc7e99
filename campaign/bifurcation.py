"""Hunting limit cycles against speed: the bifurcation diagram by ramping the speed down, the fold of the
branch and the nonlinear critical speed, against equivalent conicity.

Method (path following by simulation, as in True's studies of Cooperrider's bogie): start above the
linear critical speed with a large lateral kick, let the motion settle on the large (stable) limit
cycle, then lower the speed in steps of ``dv``, each plateau starting from the last state of the one
before. On each plateau the amplitude ``A`` of the leading wheelset (largest ``|y|`` [m] in a window
of ``window`` s) is compared with the window before: the plateau holds a cycle of the branch when
``A`` changes by less than ``rel_tol`` and is at least half the amplitude at the speed before; the
motion has left the branch when ``A`` falls below ``floor`` [m] (below the linear critical speed, where
straight running is stable), or is below half the amplitude at the speed before and falling or
settled (on a small cycle near the linear critical speed); otherwise the plateau is extended up to
``max_time`` s (near the fold the motion lingers; the two bogies' hunting modes may beat slowly) and
then counts as on the branch when ``A`` is still at least half the amplitude before. The first speed off the branch and the last on it bracket the **fold** of the branch (the
lowest speed at which the large cycle exists), refined by bisection (each trial from the cycle at the
upper end) to ``tol``.

The **nonlinear critical speed** (the lowest speed at which a limit cycle exists) is the fold speed
when that is below the linear critical speed (a subcritical bifurcation: hunting survives down to the
fold once started); when the fold is above it, the branch born at the linear critical speed carries
small cycles from there on (supercritical, or a short subcritical piece), and the nonlinear critical
speed is the linear one: :attr:`BifurcationDiagram.nonlinear_critical_speed`. Small cycles near the
linear critical speed are not traced.

The unstable branch between the nonlinear and the linear critical speed (the disturbance needed to
start hunting) is not computed here.

The vehicle is given as a ``runner(speed [m/s], x0, duration [s]) -> run`` whose run has ``t`` [s],
``states`` (the leading wheelset's lateral displacement in column ``LEADING_WHEELSET``) and
``final_state`` (see :class:`campaign.vehicle_nonlinear.NonlinearRun`); :func:`builtin_runner` is the
nonlinear car with its built-in Maxwell yaw dampers, ``tuner.vehicle`` gives one with damper FMUs.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .vehicle import VehicleParams
from .vehicle_nonlinear import LEADING_WHEELSET, ContactSettings, NonlinearVehicle

__all__ = ["RampSettings", "LimitCycle", "BifurcationDiagram", "ConicityPoint", "ramp_down", "builtin_runner", "plateau",
           "start_speed", "conicity_sweep"]


@dataclass(frozen=True)
class RampSettings:
    """Settings of the ramp-down (SI units): speed step ``dv`` [m/s], bisection tolerance ``tol`` [m/s],
    ``settle`` [s] before the first window, ``window`` [s], ``max_time`` [s] per plateau, relative
    amplitude change ``rel_tol`` [-] of a converged cycle, ``floor`` [m] below which the motion has died
    out, ``kick`` [m] of the start."""

    dv: float = 20.0 / 3.6
    tol: float = 2.0 / 3.6
    settle: float = 6.0
    window: float = 2.0
    max_time: float = 40.0
    rel_tol: float = 0.02
    floor: float = 1e-4
    kick: float = 10e-3

    def __post_init__(self) -> None:
        for name in ("dv", "tol", "settle", "window", "max_time", "rel_tol", "floor", "kick"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0.0):
                raise ValueError(f"ramp setting {name} must be a finite number > 0, got {v!r}")
        if self.max_time < self.settle + 2.0 * self.window:
            raise ValueError("ramp setting max_time must be >= settle + 2 window")


@dataclass
class LimitCycle:
    """One plateau: ``speed`` [m/s], ``amplitude`` [m] of the leading wheelset (largest |y| in the last
    window), ``exists`` (the motion stayed on the branch's limit cycle), ``converged`` (the amplitude
    settled within ``rel_tol`` or clearly left, rather than judged by its trend at ``max_time``),
    ``duration`` [s] simulated, ``state`` at its end (the runner's state vector)."""

    speed: float
    amplitude: float
    exists: bool
    converged: bool
    duration: float
    state: np.ndarray = field(default=None, repr=False)


@dataclass
class BifurcationDiagram:
    """Ramp-down result: every plateau in the order run (``cycles``), the ``fold_speed`` [m/s] (lowest
    speed at which the followed branch exists; ``inf`` if there was no cycle at the start, the lowest
    speed tried if it persisted to ``v_stop``, then ``fold_below_stop``) and its ``bracket`` [m/s], the
    ``linear_critical_speed`` [m/s] (eigenvalues or small kicks, given)."""

    cycles: list
    fold_speed: float
    bracket: tuple
    linear_critical_speed: float = math.nan
    fold_below_stop: bool = False

    @property
    def cycle_reached(self) -> bool:
        """A limit cycle was reached at the start of the ramp."""
        return any(c.exists for c in self.cycles)

    @property
    def nonlinear_critical_speed(self) -> float:
        """Lowest speed [m/s] at which a limit cycle exists: the fold speed, or the linear critical speed
        where that is lower (module docstring); ``inf`` when no cycle was reached and straight running
        is stable up to the start (or the linear speed is unknown), ``nan`` when no cycle was reached
        although straight running is unstable there (not found)."""
        if math.isnan(self.linear_critical_speed):
            return self.fold_speed
        if not self.cycle_reached and math.isfinite(self.linear_critical_speed):
            return math.nan
        return min(self.fold_speed, self.linear_critical_speed)

    def branch(self):
        """The stable branch followed: (speeds [m/s], amplitudes [m]) of its plateaus, by speed."""
        c = sorted((p for p in self.cycles if p.exists), key=lambda p: p.speed)
        return np.array([p.speed for p in c]), np.array([p.amplitude for p in c])


def _amplitudes(run, window: float):
    """Largest |y| [m] of the leading wheelset in the last and the second-to-last ``window`` [s]."""
    t, y = run.t, np.abs(run.states[:, LEADING_WHEELSET])
    last = t >= t[-1] - window
    before = (t >= t[-1] - 2.0 * window) & ~last
    return float(np.max(y[last])), float(np.max(y[before]))


def plateau(runner, speed: float, x0, s: RampSettings, reference: float = 0.0, rest_stable: bool = True):
    """Run one plateau at ``speed`` [m/s] from ``x0`` and judge it (see the module docstring);
    ``reference`` [m]: the cycle amplitude at the speed before (0: none, the first plateau);
    ``rest_stable``: straight running is stable at this speed (below the linear critical speed), so a
    motion below ``floor`` has died out (above it, it must grow again). Returns (LimitCycle, final state)."""
    run = runner(speed, x0, s.settle + 2.0 * s.window)
    total = s.settle + 2.0 * s.window
    while True:
        a, before = _amplitudes(run, s.window)
        x = run.final_state
        if a < s.floor and rest_stable:
            return LimitCycle(speed, a, False, True, total, x), x
        off = a < max(0.5 * reference, s.floor)  # far below the branch: off it (to a small cycle or to rest)
        if abs(a - before) <= s.rel_tol * a and not (a < s.floor):
            return LimitCycle(speed, a, not off, True, total, x), x
        if a < before and off and reference > 0.0:
            return LimitCycle(speed, a, False, True, total, x), x
        if total + 2.0 * s.window > s.max_time:
            # still hunting at the branch's size (a slow beat of the two bogies' hunting modes) or not
            return LimitCycle(speed, a, not off, False, total, x), x
        run = runner(speed, x, 2.0 * s.window)
        total += 2.0 * s.window


def ramp_down(runner, v_start: float, v_stop: float, x_start, s: RampSettings | None = None, *,
              linear_critical_speed: float = math.nan, v_max: float = math.nan, log=None) -> BifurcationDiagram:
    """The stable branch from ``v_start`` down to ``v_stop`` [m/s] (``v_start > v_stop > 0``) starting
    from the state ``x_start`` (a large kick), its fold, and so the nonlinear critical speed with the
    ``linear_critical_speed`` [m/s] (module docstring). When the kick reaches no cycle at ``v_start``,
    up to three more starts, each 15 % faster, up to ``v_max`` [m/s].
    ``log``: callable taking one line per plateau."""
    s = s if s is not None else RampSettings()
    if not (math.isfinite(v_start) and 0.0 < v_stop < v_start):
        raise ValueError(f"need v_start > v_stop > 0 m/s, got v_start={v_start}, v_stop={v_stop}")
    cycles, x = [], np.array(x_start, dtype=float)

    def step(v, x0, reference):
        c, xe = plateau(runner, v, x0, s, reference, not v >= linear_critical_speed)
        cycles.append(c)
        if log is not None:
            log(f"  {v * 3.6:7.1f} km/h: {'on the branch' if c.exists else 'left the branch'}, amplitude "
                f"{c.amplitude * 1e3:.2f} mm{'' if c.converged else ' (trend)'} after {c.duration:.0f} s")
        return c, xe

    c, x = step(v_start, x, 0.0)
    for _ in range(3):
        if c.exists or not v_max > v_start:
            break
        v_start = min(1.15 * v_start, v_max)
        c, x = step(v_start, np.array(x_start, dtype=float), 0.0)
    if not c.exists:
        return BifurcationDiagram(cycles, math.inf, (v_start, math.inf), linear_critical_speed)
    hi, x_hi, ref, lo = v_start, x, c.amplitude, None
    for v in np.arange(v_start - s.dv, v_stop - 1e-9, -s.dv):
        c, xe = step(float(v), x_hi, ref)
        if not c.exists:
            lo = float(v)
            break
        hi, x_hi, ref = float(v), xe, c.amplitude
    if lo is None:
        return BifurcationDiagram(cycles, hi, (0.0, hi), linear_critical_speed, fold_below_stop=True)
    while hi - lo > s.tol:
        mid = 0.5 * (lo + hi)
        c, xe = step(mid, x_hi, ref)
        if c.exists:
            hi, x_hi, ref = mid, xe, c.amplitude
        else:
            lo = mid
    return BifurcationDiagram(cycles, hi, (lo, hi), linear_critical_speed)


def builtin_runner(params: VehicleParams | None = None, settings: ContactSettings | None = None, *,
                   step: float = 1e-3):
    """The runner of the nonlinear car with its built-in Maxwell yaw dampers (full 32-state vector)."""

    def run(speed, x0, duration):
        return NonlinearVehicle(params, speed, settings).simulate(x0, duration, step=step)

    return run


@dataclass
class ConicityPoint:
    """Critical speeds at one equivalent ``conicity`` [-]: the ``diagram`` of the ramp-down (its
    linear, fold and nonlinear critical speeds [m/s])."""

    conicity: float
    diagram: BifurcationDiagram

    @property
    def linear_critical_speed(self) -> float:
        return self.diagram.linear_critical_speed

    @property
    def nonlinear_critical_speed(self) -> float:
        return self.diagram.nonlinear_critical_speed


def start_speed(linear_critical_speed: float, v_max: float, factor: float = 1.15) -> float:
    """Speed [m/s] to start a ramp-down at: ``factor`` times the linear critical speed, at most ``v_max``."""
    if not (factor > 1.0 and v_max > 0.0):
        raise ValueError(f"need factor > 1 and v_max > 0, got {factor}, {v_max}")
    return min(factor * linear_critical_speed, v_max)


def conicity_sweep(conicities, make_runner, linear_speed, x_start, *, v_max: float, v_min: float,
                   settings: RampSettings | None = None, log=None) -> list:
    """Linear and nonlinear critical speeds against equivalent conicity: for each of ``conicities`` [-]
    the ``linear_speed(conicity)`` [m/s] and a ramp-down of ``make_runner(conicity)`` from
    :func:`start_speed` (at most ``v_max`` [m/s]) to ``v_min`` [m/s] from the state ``x_start``.
    Returns a list of :class:`ConicityPoint`."""
    out = []
    for lam in conicities:
        if not (math.isfinite(lam) and lam > 0.0):
            raise ValueError(f"conicity must be > 0, got {lam}")
        v_lin = float(linear_speed(lam))
        if log is not None:
            log(f"conicity {lam:.3f}: linear critical speed {v_lin * 3.6:.1f} km/h")
        d = ramp_down(make_runner(lam), start_speed(v_lin, v_max), v_min, x_start, settings,
                      linear_critical_speed=v_lin, v_max=v_max, log=log)
        out.append(ConicityPoint(float(lam), d))
    return out
