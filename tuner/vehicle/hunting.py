"""Hunting stability of the vehicle with damper FMUs: critical speed in the time domain, and by eigenvalues.

Time domain (any damper FMU, linear or not): on straight ideal track the wheelsets and bogies start
displaced laterally by ``kick`` [m] (a lateral kick; the carbody centred, everything at rest relative to
the track). The motion then decays or grows; its growth rate ``sigma`` [1/s] is the largest real part
of the modes still present in the second half of the run, found by dynamic mode decomposition
(:func:`dominant_rate`: a linear map fitted by least squares to the snapshots of the vehicle's 28 states
and the four damper forces, with time delays for the dampers' internal states). An envelope slope does
not do: the vehicle has two hunting modes (bogies in and out of phase) a few hundredths of a hertz
apart, whose beating (period 20-30 s) biased the envelope's slope by up to 0.15 1/s, 1 % of the
critical speed. ``sigma < 0``: stable at that speed.
The critical speed is bracketed by bisection on the speed [m/s] and, once the bracket is narrower than
``tol``, taken where the linear interpolation of ``sigma`` between the bracket ends crosses zero.
A run whose motion exceeds ``abort_ratio * kick`` is stopped early and counts as unstable.

With a nonlinear damper the result depends on the kick amplitude (the damper's stiffness and damping
change with amplitude): it is the speed above which a disturbance of that size grows.

Eigenvalues (linear Maxwell damper ``k_s``, ``c``): :func:`eigen_critical_speed`, the built-in model of
:mod:`campaign.vehicle` with a linear dashpot (no blow-off), the independent reference.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from campaign.track import Track, straight
from campaign.vehicle import VehicleParams, critical_speed

__all__ = ["kick_state", "dominant_rate", "HuntingSearch", "critical_speed_time_domain", "eigen_critical_speed",
           "DEFAULT_KICK", "WHEELSET_LATERAL"]

DEFAULT_KICK = 3e-3
"""Default lateral kick [m] of the wheelsets and bogies."""
WHEELSET_LATERAL = (3, 4, 5, 6)
"""State indices of the wheelsets' lateral displacements."""


def kick_state(kick: float = DEFAULT_KICK) -> np.ndarray:
    """Initial mechanical state (28,) on straight track: bogies and wheelsets displaced laterally by
    ``kick`` [m] (+y, to the left), carbody centred, no yaw, at rest."""
    if not (math.isfinite(kick) and kick > 0.0):
        raise ValueError(f"kick must be > 0 m, got {kick}")
    x = np.zeros(28)
    x[1:7] = kick
    return x


def dominant_rate(t: np.ndarray, Z: np.ndarray, *, sample: float = 5e-3, delays: int = 3,
                  start: float | None = None, rel: float = 1e-3) -> tuple[float, float]:
    """Growth rate [1/s] and frequency [Hz] of the least damped mode present in the signals ``Z`` (n, m)
    sampled at ``t`` [s] from ``start`` [s] (default half the run): dynamic mode decomposition of the
    snapshots taken every ``sample`` [s] (each channel scaled to unit RMS, ``delays`` time-delayed copies
    stacked), modes whose amplitude at the last snapshot is below ``rel`` times the largest ignored. For
    a linear system whose full state is in ``Z`` this is the largest real part of its excited eigenvalues.
    """
    t0 = t[-1] / 2.0 if start is None else start
    stride = max(1, int(round(sample / (t[1] - t[0]))))
    dt = stride * (t[1] - t[0])
    Y = Z[np.nonzero(t >= t0)[0][::stride]]
    n = Y.shape[0] - delays + 1
    if n < 4 * Y.shape[1] * delays // 3:
        raise ValueError(f"too few snapshots ({Y.shape[0]}) for {Y.shape[1]} signals: run longer or sample finer")
    Y = Y / np.maximum(np.sqrt(np.mean(Y ** 2, axis=0)), 1e-300)
    H = np.hstack([Y[j:j + n] for j in range(delays)]).T
    X1, X2 = H[:, :-1], H[:, 1:]
    # SVD of X1 through its small Gram matrix (a multithreaded SVD of the tall matrix crawls on a busy machine)
    w, U = np.linalg.eigh(X1 @ X1.T)
    w, U = w[::-1], U[:, ::-1]
    if not w[0] > 0.0:
        return -math.inf, 0.0
    r = int(np.sum(w > w[0] * 1e-14))
    s = np.sqrt(w[:r])
    U = U[:, :r]
    Vt = (U.T @ X1) / s[:, None]
    mu, W = np.linalg.eig(U.T @ X2 @ Vt.T / s)
    modes = X2 @ Vt.T / s @ W
    b = np.linalg.lstsq(modes, H[:, -1], rcond=None)[0]
    amp = np.abs(b) * np.linalg.norm(modes, axis=0)
    keep = amp > rel * amp.max()
    lam = np.log(mu[keep].astype(complex)) / dt
    i = int(np.argmax(lam.real))
    return float(lam[i].real), float(abs(lam[i].imag) / (2.0 * math.pi))


@dataclass
class HuntingSearch:
    """Result of a time-domain critical speed search: ``speed`` [m/s] (``inf``: stable up to the top
    of the range; ``v_min`` or below: unstable already there, then ``unstable_at_min``), the final
    bracket [m/s] and every run as (speed [m/s], growth rate [1/s], completed)."""

    speed: float
    bracket: tuple[float, float]
    runs: list = field(default_factory=list)
    kick: float = DEFAULT_KICK
    unstable_at_min: bool = False

    @property
    def speed_kmh(self) -> float:
        return self.speed * 3.6


def _sigma(cosim, speed: float, *, kick: float, t_end: float, abort_ratio: float):
    """Growth rate [1/s] and completed flag of one kick run at ``speed`` [m/s]."""
    run = cosim.run(speed, Track([straight(1.0)]), None, t_end, x0=kick_state(kick),
                    abort_states=WHEELSET_LATERAL, abort_limit=abort_ratio * kick)
    if not run.completed:
        # grew past the limit: the rate from the kick to there (a lower bound of the growth)
        r = np.sqrt(np.sum(run.wheelset_lateral ** 2, axis=1))
        return max(math.log(r[-1] / (kick * 2.0)) / max(run.t[-1], 1e-9), 1e-6), False
    return dominant_rate(run.t, np.hstack([run.states, run.forces]))[0], True


def critical_speed_time_domain(cosim, v_min: float = 100.0 / 3.6, v_max: float = 800.0 / 3.6, *,
                               tol: float = 1.0 / 3.6, kick: float = DEFAULT_KICK, t_end: float = 8.0,
                               abort_ratio: float = 20.0, log=None) -> HuntingSearch:
    """Critical hunting speed [m/s] of the vehicle of ``cosim`` (a :class:`tuner.vehicle.cosim.VehicleCosim`)
    between ``v_min`` and ``v_max`` [m/s] to ``tol`` [m/s], from kick runs of ``t_end`` [s] (see the
    module docstring). ``log``: callable for one progress line per run."""
    if not (0.0 < v_min < v_max and math.isfinite(v_max)):
        raise ValueError(f"need 0 < v_min < v_max, got {v_min}, {v_max} m/s")
    if not tol > 0.0:
        raise ValueError(f"tol must be > 0 m/s, got {tol}")
    runs = []

    def sigma(v):
        s, done = _sigma(cosim, v, kick=kick, t_end=t_end, abort_ratio=abort_ratio)
        runs.append((v, s, done))
        if log is not None:
            log(f"  {v * 3.6:7.1f} km/h: growth rate {s:+.4f} 1/s ({'stable' if s < 0 else 'unstable'}"
                f"{'' if done else ', stopped at the amplitude limit'})")
        return s

    s_lo, s_hi = sigma(v_min), None
    if s_lo >= 0.0:
        return HuntingSearch(v_min, (0.0, v_min), runs, kick, unstable_at_min=True)
    s_hi = sigma(v_max)
    if s_hi < 0.0:
        return HuntingSearch(math.inf, (v_max, math.inf), runs, kick)
    lo, hi = v_min, v_max
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        s = sigma(mid)
        if s < 0.0:
            lo, s_lo = mid, s
        else:
            hi, s_hi = mid, s
    speed = lo + (hi - lo) * (-s_lo) / (s_hi - s_lo) if math.isfinite(s_lo) and s_hi > s_lo else 0.5 * (lo + hi)
    return HuntingSearch(float(speed), (lo, hi), runs, kick)


def eigen_critical_speed(k_s: float, c: float, params: VehicleParams | None = None, *, v_max: float = 300.0,
                         tol: float = 0.01) -> float:
    """Linear critical speed [m/s] (eigenvalues of :mod:`campaign.vehicle`) with linear Maxwell yaw dampers
    of series stiffness ``k_s`` [N/m] and damping ``c`` [N s/m]; ``inf`` if stable up to ``v_max`` [m/s]."""
    p = dataclasses.replace(params or VehicleParams(), yaw_series_stiffness=float(k_s), yaw_damping=float(c),
                            yaw_blowoff_velocity=math.inf)
    return critical_speed(p, v_max=v_max, dv=2.0, tol=tol)
