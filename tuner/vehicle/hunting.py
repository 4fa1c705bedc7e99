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
:func:`critical_speed_near` finds it from a guess instead (the draws of ``tuner.vehicle.propagation``): a
bracket around the guess and the zero of a robust line through the growth rates of the decaying runs, not
swayed by the growth rates a nonlinear damper's growing motion gives on the unstable side.

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

__all__ = ["kick_state", "dominant_rate", "HuntingSearch", "critical_speed_time_domain", "critical_speed_near",
           "NearSearch",
           "eigen_critical_speed",
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
    return _bisect(sigma, (v_min, s_lo), (v_max, s_hi), tol, runs, kick)


def _bisect(sigma, low: tuple, high: tuple, tol: float, runs: list, kick: float) -> HuntingSearch:
    """Bisection of the bracket low = (speed [m/s], sigma < 0), high = (speed, sigma >= 0) down to ``tol``
    [m/s], then the zero of sigma's linear interpolation between the bracket ends (module docstring)."""
    (lo, s_lo), (hi, s_hi) = low, high
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        s = sigma(mid)
        if s < 0.0:
            lo, s_lo = mid, s
        else:
            hi, s_hi = mid, s
    speed = lo + (hi - lo) * (-s_lo) / (s_hi - s_lo) if math.isfinite(s_lo) and s_hi > s_lo else 0.5 * (lo + hi)
    return HuntingSearch(float(speed), (lo, hi), runs, kick)


@dataclass(frozen=True)
class NearSearch:
    """How ``critical_speed_near`` searches: the first bracket's ``half_width`` around the guess, within [``v_min``,
    ``v_max``] [m/s]; ``points`` kick runs of ``kick`` [m] and ``t_end`` [s] per stage, ``stages`` stages; a run
    stops once its motion grows ``abort_ratio`` x (``_sigma``)."""

    half_width: float = 30.0 / 3.6
    v_min: float = 100.0 / 3.6
    v_max: float = 1000.0 / 3.6
    kick: float = DEFAULT_KICK
    points: int = 3
    stages: int = 3
    t_end: float = 8.0
    abort_ratio: float = 20.0


def critical_speed_near(cosim, guess: float, *, search: NearSearch = NearSearch()) -> HuntingSearch:
    """Critical speed [m/s] of a vehicle whose critical speed is expected near ``guess`` [m/s] (a damper close
    to one whose critical speed is known), robust to a run whose growth rate is wrong; ``search``: the
    ``NearSearch`` below.

    Bracket: ``guess +- half_width`` [m/s]; when sigma has the same sign at both ends, the bracket moves away
    from ``guess`` in steps that double, never beyond [``v_min``, ``v_max``] [m/s]. Then sigma on ``points``
    speeds evenly inside the bracket and the zero of the straight line through the decaying runs (sigma < 0)
    in it, by the Theil-Sen estimator (median of the pairwise slopes: one run in four may be wrong without
    moving it); then ``stages - 1`` times again, each with ``points`` speeds below the last zero across a
    span a third of the previous one's, the line through the decaying runs within 1.5 spans below it.

    Why the decaying side and not bisection: with a nonlinear damper the motion after the kick grows, on the
    unstable side, into amplitudes where the damper's nonlinearity changes the dynamics within the run; the
    dynamic mode decomposition then reads growth rates that are not the small-amplitude ones (the lumped
    FMU of the bundled fit: -0.04 1/s at 802.8 km/h, +0.01 at 804.1, then +0.72 at 806.1 and +4 to +6
    between 810 and 814, +0.35 at 819), and one such sign decides a bisection. On the decaying side the
    motion stays small and the growth rate is a smooth function of speed. The critical speed is the zero of
    its extrapolation, from at most a third of the bracket's width / 3^(stages - 2) below. With the linear
    Maxwell FMU it agrees with the eigenvalues (``tests/test_vehicle_propagation.py``). ``bracket`` of the
    result: the runs' bracket [m/s]."""
    half_width, v_min, v_max, kick = search.half_width, search.v_min, search.v_max, search.kick
    points, stages, t_end, abort_ratio = search.points, search.stages, search.t_end, search.abort_ratio
    if not (0.0 < v_min < v_max and math.isfinite(v_max) and half_width > 0.0 and points >= 2 and stages >= 1):
        raise ValueError(f"need 0 < v_min < v_max, half_width > 0, points >= 2 and stages >= 1, got {v_min}, "
                         f"{v_max} m/s, {half_width} m/s, {points}, {stages}")
    runs = []

    def sigma(v):
        s, done = _sigma(cosim, v, kick=kick, t_end=t_end, abort_ratio=abort_ratio)
        runs.append((v, s, done))
        return s

    guess = min(max(guess, v_min), v_max)
    lo, hi, step = max(v_min, guess - half_width), min(v_max, guess + half_width), 2.0 * half_width
    s_lo, s_hi = sigma(lo), None
    while s_lo >= 0.0 and lo > v_min:  # unstable at the lower end: the critical speed lies below
        hi, s_hi, lo, step = lo, s_lo, max(v_min, lo - step), 2.0 * step
        s_lo = sigma(lo)
    if s_lo >= 0.0:
        return HuntingSearch(v_min, (0.0, v_min), runs, kick, unstable_at_min=True)
    if s_hi is None:
        s_hi = sigma(hi)
    while s_hi < 0.0 and hi < v_max:  # stable at the upper end: it lies above
        lo, s_lo, hi, step = hi, s_hi, min(v_max, hi + step), 2.0 * step
        s_hi = sigma(hi)
    if s_hi < 0.0:
        return HuntingSearch(math.inf, (v_max, math.inf), runs, kick)
    for v in lo + (hi - lo) * np.arange(1, points + 1) / (points + 1):
        sigma(float(v))
    while sum(1 for r in runs if lo <= r[0] <= hi and r[1] < 0.0) < 2:  # a line needs two decaying runs
        lo, hi = _shrink(sigma, lo, hi, runs)
    zero = _line_zero([r for r in runs if lo <= r[0] <= hi], (lo, hi))
    for k in range(1, stages):  # each stage a third as wide, approaching the zero from the stable side
        span = (hi - lo) / 3.0 ** k
        for v in zero - span * np.arange(points, 0, -1) / points:
            sigma(float(min(max(v, lo), hi)))
        zero = _line_zero([r for r in runs if lo <= r[0] <= hi and zero - 1.5 * span <= r[0] <= zero + span],
                          (lo, hi), [r for r in runs if lo <= r[0] <= hi])
    return HuntingSearch(zero, (lo, hi), runs, kick)


def _shrink(sigma, lo: float, hi: float, runs: list) -> tuple[float, float]:
    """The bracket [m/s] halved at the middle of its top decaying run and its lowest growing one above it."""
    below = max(r[0] for r in runs if lo <= r[0] <= hi and r[1] < 0.0)
    above = min(r[0] for r in runs if below < r[0] <= hi and r[1] >= 0.0)
    mid = 0.5 * (below + above)
    return (lo, hi) if sigma(mid) < 0.0 else (lo, mid)


def _line_zero(runs: list, bracket: tuple, fallback: list | None = None) -> float:
    """Zero [m/s] of the Theil-Sen line through the decaying runs (growth rate < 0) of ``runs`` (speed [m/s],
    growth rate [1/s], completed), kept in ``bracket``; with fewer than two such runs those of ``fallback``;
    the bracket's middle when the line does not rise."""
    stable = [r for r in runs if r[1] < 0.0]
    if len(stable) < 2 and fallback is not None:
        stable = [r for r in fallback if r[1] < 0.0]
    v = np.array([r[0] for r in stable])
    s = np.array([r[1] for r in stable])
    i, j = np.triu_indices(v.size, 1)
    ok = np.abs(v[j] - v[i]) > 0
    if not ok.any():
        return 0.5 * (bracket[0] + bracket[1])
    slope = float(np.median((s[j] - s[i])[ok] / (v[j] - v[i])[ok]))
    if not slope > 0.0:
        return 0.5 * (bracket[0] + bracket[1])
    intercept = float(np.median(s - slope * v))
    return float(min(max(-intercept / slope, bracket[0]), bracket[1]))


def eigen_critical_speed(k_s: float, c: float, params: VehicleParams | None = None, *, v_max: float = 300.0,
                         tol: float = 0.01) -> float:
    """Linear critical speed [m/s] (eigenvalues of :mod:`campaign.vehicle`) with linear Maxwell yaw dampers
    of series stiffness ``k_s`` [N/m] and damping ``c`` [N s/m]; ``inf`` if stable up to ``v_max`` [m/s]."""
    p = dataclasses.replace(params or VehicleParams(), yaw_series_stiffness=float(k_s), yaw_damping=float(c),
                            yaw_blowoff_velocity=math.inf)
    return critical_speed(p, v_max=v_max, dv=2.0, tol=tol)
