"""Hunting of the Cooperrider car (:mod:`campaign.cooperrider`) on straight track, computed as the
DTU group computes it: at each speed the car starts from a small lateral offset of its leading
wheelset and runs for a while; the leading wheelset's response either decays (stable) or grows
into a limit cycle. Also the linear critical speed from the eigenvalues of the linearised car.

Time integration: classical Runge-Kutta (RK4) at a fixed step ``dt`` (default 0.25 ms: the stiffest
modes, the wheelsets' vertical/roll on the contact at about 1670 rad/s and the creep damping at
low speed, about -5000 1/s at 20 m/s, stay inside RK4's stability region, |lambda dt| < 2.8; 0.5 ms
does from about 25 m/s up and is what the DYTSI benchmark uses: over 1 s at 110 m/s it follows
DYTSI's stored response to 7e-10 m), states stored every ``store`` seconds (default 0.01 s). Several
speeds run together as one batch (one car per column).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .contact_table import ContactTable
from .cooperrider import LEADING_WHEELSET, N_POS, N_STATES, CooperriderCar, state_index
from .cooperrider_params import CooperriderParams

__all__ = ["CarRun", "SweepResult", "run_speeds", "response_growth", "cycle_amplitude", "sweep_result", "offset_state", "equilibrium", "jacobian", "hunting_eigenvalue",
           "linear_critical_speed", "DEFAULT_DT", "DEFAULT_OFFSET"]

DEFAULT_DT = 2.5e-4
"""RK4 step [s]."""
DEFAULT_OFFSET = 1e-4
"""Initial lateral offset [m] of the leading wheelset (the simulator's straight-track case)."""


@dataclass(frozen=True)
class CarRun:
    """Stored states of a batch of runs: ``t`` (nt,) [s], ``speeds`` (m,) [m/s], ``states``
    (nt, 66, m) SI units (layout of :mod:`campaign.cooperrider`)."""

    t: np.ndarray
    speeds: np.ndarray
    states: np.ndarray

    def signal(self, body: int = LEADING_WHEELSET, coord: str = "y") -> np.ndarray:
        """One coordinate (nt, m) of one body for every speed (default: leading wheelset's y [m])."""
        return self.states[:, state_index(body, coord), :]

    @property
    def final(self) -> np.ndarray:
        """The last stored states (66, m)."""
        return self.states[-1]


def offset_state(offset: float = DEFAULT_OFFSET, m: int = 1) -> np.ndarray:
    """States (66, m): all zero but the leading wheelset's lateral displacement ``offset`` [m]."""
    x = np.zeros((N_STATES, m))
    x[state_index(LEADING_WHEELSET, "y")] = offset
    return x


def run_speeds(params: CooperriderParams, table: ContactTable, speeds, x0: np.ndarray, t_end: float, *,
               dt: float = DEFAULT_DT, store: float = 0.01) -> CarRun:
    """Integrate the car at each of ``speeds`` [m/s] from ``x0`` (66, m) (or (66,) for all) for
    ``t_end`` [s] by RK4 with step ``dt`` [s], storing every ``store`` [s] (a multiple of ``dt``).
    A wheelset leaving the contact table raises :class:`campaign.contact_table.ContactTableError`."""
    speeds = np.atleast_1d(np.asarray(speeds, dtype=float))
    x = np.array(x0, dtype=float)
    x = np.repeat(x[:, None], speeds.size, axis=1) if x.ndim == 1 else x
    if x.shape != (N_STATES, speeds.size):
        raise ValueError(f"x0 must have shape (66,) or (66, {speeds.size}), got {x.shape}")
    every = int(round(store / dt))
    if every < 1 or abs(every * dt - store) > 1e-9 * store:
        raise ValueError(f"store={store} s must be a multiple of dt={dt} s")
    n_out = int(round(t_end / store))
    car = CooperriderCar(params, table, speeds)
    f = car.rhs
    out = np.empty((n_out + 1, N_STATES, speeds.size))
    out[0] = x
    h = dt
    for k in range(1, n_out + 1):
        for _ in range(every):
            k1 = f(0.0, x)
            k2 = f(0.0, x + 0.5 * h * k1)
            k3 = f(0.0, x + 0.5 * h * k2)
            k4 = f(0.0, x + h * k3)
            x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        out[k] = x
    return CarRun(t=np.arange(n_out + 1) * store, speeds=speeds, states=out)


def equilibrium(car: CooperriderCar) -> np.ndarray:
    """The car's equilibrium on straight track (66,): zero rates, positions where the accelerations
    vanish (the wheelsets settle a few 1e-8 m into the rails; everything else stays at zero), by
    Newton's method on the positions."""
    x = np.zeros(N_STATES)
    for _ in range(20):
        acc = car.rhs(0.0, x)[N_POS:2 * N_POS]
        if np.max(np.abs(acc)) < 1e-10:
            return x
        J = jacobian(car, x)[N_POS:2 * N_POS, :N_POS]
        x[:N_POS] -= np.linalg.lstsq(J, acc, rcond=None)[0]
    raise RuntimeError(f"no equilibrium found at {car.speed} m/s: residual acceleration {np.max(np.abs(acc)):.3g}")


def jacobian(car: CooperriderCar, x: np.ndarray, h: float = 1e-7) -> np.ndarray:
    """Central-difference Jacobian (66, 66) of ``car.rhs`` at ``x`` (66,), step ``h`` in every state."""
    E = np.eye(N_STATES) * h
    return (car.rhs(0.0, x[:, None] + E) - car.rhs(0.0, x[:, None] - E)) / (2.0 * h)


def _lateral_rows() -> np.ndarray:
    """State indices of the lateral family (y, roll, yaw of every body and their rates)."""
    rows = []
    for body in range(7):
        for coord in ("y", "phi", "psi"):
            rows += [state_index(body, coord), state_index(body, coord, rate=True)]
    return np.array(rows)


def hunting_eigenvalue(params: CooperriderParams, table: ContactTable, speed: float) -> complex:
    """The hunting eigenvalue [1/s] of the car linearised at its equilibrium at ``speed`` [m/s]: the
    oscillating eigenvalue with the largest real part among those whose eigenvector lies mostly (more
    than half its norm) in the lateral family (y, roll, yaw). The vertical family (bounce, pitch,
    spin) decouples on straight track and holds undamped modes (no primary vertical damping)."""
    car = CooperriderCar(params, table, float(speed))
    ev, vec = np.linalg.eig(jacobian(car, equilibrium(car)))
    lateral = np.linalg.norm(vec[_lateral_rows()], axis=0) / np.linalg.norm(vec, axis=0)
    candidates = ev[(np.abs(ev.imag) > 1e-3) & (lateral > 0.5)]
    return complex(candidates[np.argmax(candidates.real)])


def linear_critical_speed(params: CooperriderParams, table: ContactTable, low: float, high: float, *,
                          tol: float = 0.01) -> float:
    """Speed [m/s] in (``low``, ``high``) where the hunting eigenvalue's real part crosses zero,
    by bisection to ``tol`` [m/s]; ``low`` must be stable and ``high`` unstable."""
    s_low = hunting_eigenvalue(params, table, low).real
    s_high = hunting_eigenvalue(params, table, high).real
    if not (s_low < 0.0 < s_high):
        raise ValueError(f"no stability change between {low} m/s (real part {s_low:.4g} 1/s) and "
                         f"{high} m/s ({s_high:.4g} 1/s)")
    while high - low > tol:
        mid = 0.5 * (low + high)
        if hunting_eigenvalue(params, table, mid).real < 0.0:
            low = mid
        else:
            high = mid
    return 0.5 * (low + high)


@dataclass(frozen=True)
class SweepResult:
    """Decay or growth of the response at each speed of a sweep: ``speeds`` [m/s], ``growth``
    [1/s] (:func:`response_growth`), ``amplitude`` [m] at the end (:func:`cycle_amplitude`); the
    linear critical speed: ``bracket`` (last decaying, first growing speed) [m/s] and
    ``critical_speed`` [m/s], the zero of the growth rate interpolated linearly in that bracket
    (None, None if the response never turns from decay to growth)."""

    speeds: np.ndarray
    growth: np.ndarray
    amplitude: np.ndarray
    bracket: tuple | None
    critical_speed: float | None


def response_growth(t: np.ndarray, y: np.ndarray, early: tuple = (4.0, 6.0), late: tuple = (8.0, 10.0)) -> float:
    """Growth rate [1/s] of a response ``y(t)`` (``t`` [s], ``y`` any unit): the logarithm of the
    ratio of the largest |y| in the window ``late`` to that in ``early`` (seconds, both inside
    ``t``), over the time between the windows' starts. Negative: decay."""
    a = np.max(np.abs(y[(t >= early[0]) & (t <= early[1])]))
    b = np.max(np.abs(y[(t >= late[0]) & (t <= late[1])]))
    if not (a > 0.0 and b > 0.0):
        raise ValueError("response identically zero in a window: no growth rate")
    return float(np.log(b / a) / (late[0] - early[0]))


def cycle_amplitude(t: np.ndarray, y: np.ndarray, window: float = 2.0) -> float:
    """Half the peak-to-peak value of ``y`` over the last ``window`` [s] of ``t``: the amplitude of a
    limit cycle (same unit as ``y``)."""
    last = y[t >= t[-1] - window]
    return float(0.5 * (np.max(last) - np.min(last)))


def sweep_result(speeds, t: np.ndarray, responses: np.ndarray, **windows) -> SweepResult:
    """:class:`SweepResult` of responses (nt, m) at ``speeds`` (m,) sampled at ``t`` (nt,);
    ``windows``: ``early``/``late`` of :func:`response_growth`."""
    speeds = np.asarray(speeds, dtype=float)
    growth = np.array([response_growth(t, responses[:, j], **windows) for j in range(speeds.size)])
    amplitude = np.array([cycle_amplitude(t, responses[:, j]) for j in range(speeds.size)])
    bracket, critical = None, None
    for j in range(1, speeds.size):
        if growth[j - 1] <= 0.0 < growth[j]:
            bracket = (float(speeds[j - 1]), float(speeds[j]))
            critical = float(speeds[j - 1] - growth[j - 1] * (speeds[j] - speeds[j - 1]) / (growth[j] - growth[j - 1]))
            break
    return SweepResult(speeds=speeds, growth=growth, amplitude=amplitude, bracket=bracket, critical_speed=critical)
