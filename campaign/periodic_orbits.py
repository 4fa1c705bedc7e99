"""Hunting limit cycles as periodic orbits found by shooting, stable or unstable, continued in amplitude.

A limit cycle of ``x' = f(V, x)`` at speed ``V`` [m/s] with period ``T`` [s] is a solution of
``phi_T(x0) = x0`` (``phi`` the flow). The amplitude ``A`` of a chosen displacement (the leading
wheelset's ``y`` [m]) fixes the orbit: the section is that displacement's maximum, ``x0[i_amp] = A`` and
``x0[i_phase] = 0`` (its rate). The unknowns are the other states, ``T`` and the speed ``V``: as many as
equations, so the branch is followed in amplitude and passes its fold (a turning point in speed, not in
amplitude) without special treatment. Newton's method with a finite-difference Jacobian (one flow per
unknown) solves it; the flow is fixed-step classical Runge-Kutta with ``n_steps`` steps per period (the
step count is fixed during a solve, so the map is smooth in ``T``).

Stability: the Floquet multipliers are the eigenvalues of the monodromy matrix ``d phi_T / d x0`` (finite
differences); one of them is 1 (the phase), the orbit is stable when all others lie inside the unit
circle. Between the fold and the linear critical speed of a subcritical hunting bifurcation the branch
of smaller amplitude is the unstable one: the boundary between disturbances that die out and those that
start hunting.

Non-smooth forces (flange dead band, damper blow-off) make the map only piecewise smooth; Newton still
converges where no kink sits exactly at the section. Units: SI, as the states of the system given.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .vehicle import VehicleParams
from .vehicle_nonlinear import LEADING_WHEELSET, N_DOF, ContactSettings, NonlinearVehicle

__all__ = ["PeriodicOrbit", "ShootingProblem", "solve_orbit", "floquet_multipliers", "continue_in_amplitude",
           "orbit_guess", "vehicle_shooting_problem"]


@dataclass
class ShootingProblem:
    """The system: ``rhs(speed, x) -> dx`` [SI], the state indices ``i_amp`` (the displacement whose maximum
    is the amplitude) and ``i_phase`` (its rate, zero at the section), ``scale`` (n,) typical magnitude
    of each state (finite differences and the Newton norm), ``steps_per_second`` of the RK4 flow."""

    rhs: object
    i_amp: int
    i_phase: int
    scale: np.ndarray
    steps_per_second: float = 1000.0

    def flow(self, speed: float, x0: np.ndarray, period: float, n_steps: int) -> np.ndarray:
        """State after ``period`` [s] from ``x0`` at ``speed`` [m/s], ``n_steps`` RK4 steps."""
        h = period / n_steps
        x = np.array(x0, dtype=float)
        f = self.rhs
        for _ in range(n_steps):
            k1 = f(speed, x)
            k2 = f(speed, x + 0.5 * h * k1)
            k3 = f(speed, x + 0.5 * h * k2)
            k4 = f(speed, x + h * k3)
            x = x + (h / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
        return x


@dataclass
class PeriodicOrbit:
    """A limit cycle: ``amplitude`` [m], ``speed`` [m/s], ``period`` [s], ``state`` at the section (the
    amplitude's maximum), ``residual`` (scaled norm of ``phi_T(x0) - x0``), ``multipliers`` (Floquet,
    complex; empty until computed) and ``stable`` (None until computed)."""

    amplitude: float
    speed: float
    period: float
    state: np.ndarray
    residual: float = math.nan
    multipliers: np.ndarray = None
    stable: bool | None = None


def _free(p: ShootingProblem, n: int) -> np.ndarray:
    return np.array([j for j in range(n) if j not in (p.i_amp, p.i_phase)], dtype=int)


def solve_orbit(p: ShootingProblem, amplitude: float, guess: PeriodicOrbit, *, tol: float = 1e-8,
                accept: float = 2e-3, max_iter: int = 20) -> PeriodicOrbit:
    """The periodic orbit of ``amplitude`` [m] near ``guess`` (state, period, speed) by damped Newton on
    ``phi_T(x0) - x0`` scaled by ``p.scale``, to ``tol``; where a kink of the forces (damper blow-off,
    flange) stalls Newton (no 10 % gain in three iterations) the orbit is accepted up to ``accept`` (a
    relative closure error). Raises ValueError naming the amplitude otherwise."""
    if not (math.isfinite(amplitude) and amplitude > 0.0):
        raise ValueError(f"amplitude must be > 0, got {amplitude}")
    x = np.array(guess.state, dtype=float)
    n = x.size
    x[p.i_amp], x[p.i_phase] = amplitude, 0.0
    free = _free(p, n)
    u = np.concatenate([x[free] / p.scale[free], [guess.period, guess.speed]])
    n_steps = max(8, int(round(guess.period * p.steps_per_second)))

    def residual(u):
        xx = x.copy()
        xx[free] = u[:-2] * p.scale[free]
        return (p.flow(u[-1], xx, u[-2], n_steps) - xx) / p.scale

    r = residual(u)
    history = [np.linalg.norm(r)]
    for _ in range(max_iter):
        if history[-1] < tol or (len(history) > 3 and history[-1] > 0.9 * history[-4]):
            break
        J = np.empty((n, u.size))
        for j in range(u.size):
            du = 1e-6 * max(1.0, abs(u[j])) if j < u.size - 2 else 1e-7 * abs(u[j])
            e = u.copy()
            e[j] += du
            J[:, j] = (residual(e) - r) / du
        step = np.linalg.lstsq(J, -r, rcond=None)[0]
        lam = 1.0
        while True:
            r_new = residual(u + lam * step)
            if np.linalg.norm(r_new) < np.linalg.norm(r) or lam < 1e-3:
                break
            lam *= 0.5
        u, r = u + lam * step, r_new
        history.append(np.linalg.norm(r))
    if not history[-1] < accept:
        raise ValueError(f"no periodic orbit of amplitude {amplitude} converged (residual {history[-1]:.3g})")
    x[free] = u[:-2] * p.scale[free]
    return PeriodicOrbit(float(amplitude), float(u[-1]), float(u[-2]), x, float(history[-1]))


def floquet_multipliers(p: ShootingProblem, orbit: PeriodicOrbit) -> PeriodicOrbit:
    """``orbit`` with its Floquet multipliers (finite-difference monodromy matrix) and stability: stable
    when every multiplier but the one closest to 1 (the phase) has modulus below 1."""
    x0 = orbit.state
    n = x0.size
    n_steps = max(8, int(round(orbit.period * p.steps_per_second)))
    base = p.flow(orbit.speed, x0, orbit.period, n_steps)
    M = np.empty((n, n))
    for j in range(n):
        dx = 1e-6 * p.scale[j]
        e = x0.copy()
        e[j] += dx
        M[:, j] = (p.flow(orbit.speed, e, orbit.period, n_steps) - base) / dx
    mu = np.linalg.eigvals(M)
    others = np.delete(mu, np.argmin(np.abs(mu - 1.0)))
    orbit.multipliers, orbit.stable = mu, bool(np.all(np.abs(others) < 1.0))
    return orbit


def _predict(out: list, start: PeriodicOrbit, a: float) -> PeriodicOrbit:
    """Guess at amplitude ``a``: the secant through the last two orbits, else the last (or ``start``)."""
    if len(out) < 2:
        return out[-1] if out else start
    o1, o2 = out[-2], out[-1]
    w = (a - o2.amplitude) / (o2.amplitude - o1.amplitude)
    return PeriodicOrbit(a, o2.speed + w * (o2.speed - o1.speed), o2.period + w * (o2.period - o1.period),
                         o2.state + w * (o2.state - o1.state))


def continue_in_amplitude(p: ShootingProblem, start: PeriodicOrbit, amplitudes, *, stability: bool = True,
                          log=None) -> list:
    """The branch through ``start`` at each of ``amplitudes`` [m] in turn (each solve from the secant
    through the two before; a step that does not converge is retried once through its midpoint); stops
    at the first amplitude that still does not converge. Returns the :class:`PeriodicOrbit` list."""
    out = []
    for a in amplitudes:
        last = out[-1].amplitude if out else start.amplitude
        targets, orbit = [float(a)], None
        for attempt in range(2):
            try:
                for t in targets:
                    orbit = solve_orbit(p, t, _predict(out, start, t))
                    if t != float(a):
                        out.append(orbit)
                break
            except ValueError as err:
                if attempt == 1:
                    if log is not None:
                        log(f"  stopped: {err}")
                    return out
                targets = [0.5 * (last + float(a)), float(a)]
        if stability:
            floquet_multipliers(p, orbit)
        if log is not None:
            log(f"  amplitude {a * 1e3:.2f} mm: {orbit.speed * 3.6:.1f} km/h, period {orbit.period:.4f} s"
                + ("" if orbit.stable is None else f", {'stable' if orbit.stable else 'unstable'}"))
        out.append(orbit)
    return out


def orbit_guess(t: np.ndarray, states: np.ndarray, speed: float, i_amp: int) -> PeriodicOrbit:
    """A starting guess from a simulated limit cycle (times ``t`` [s], ``states`` (n, m)): the state at the
    last maximum of ``states[:, i_amp]`` and the time to the maximum before as the period."""
    y = states[:, i_amp]
    peaks = np.nonzero((y[1:-1] > y[:-2]) & (y[1:-1] >= y[2:]) & (y[1:-1] > 0.5 * np.max(y)))[0] + 1
    if peaks.size < 2:
        raise ValueError("the run shows fewer than two maxima: no limit cycle to start from")
    k = peaks[-1]
    return PeriodicOrbit(float(y[k]), float(speed), float(t[k] - t[peaks[-2]]), states[k].copy())


def vehicle_shooting_problem(params: VehicleParams | None, settings: ContactSettings | None,
                             scale: np.ndarray, *, steps_per_second: float = 1000.0) -> ShootingProblem:
    """The nonlinear car with its built-in yaw dampers (:mod:`campaign.vehicle_nonlinear`) as a shooting
    problem on the leading wheelset's lateral displacement; ``scale``: typical magnitude of each state
    (e.g. the largest over a simulated cycle)."""
    model = NonlinearVehicle(params, 100.0, settings)  # the speed enters through the contact only
    return ShootingProblem(lambda v, x: model.derivative(x, v), LEADING_WHEELSET, N_DOF + LEADING_WHEELSET,
                           np.maximum(np.asarray(scale, dtype=float), 1e-12), steps_per_second)
