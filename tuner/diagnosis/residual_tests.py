"""One rig test's residual for the diagnosis (``TestResidual``: r = measured - simulated force [N]; stroke [m] + in
extension, force [N] + in tension, time [s], temperature [degC]) and its derived signals (``PreparedTest``).

Derivatives use Savitzky-Golay filters over ~20 ms (as ``tuner.data.differentiator`` does for the velocity):
dF_sim/dt cubic (polyorder 3), stroke acceleration polyorder 4 (for a symmetric window that is the
second-derivative counterpart of the cubic first derivative: error O(f^4)). Samples within half a
window of either end are left out of every regression (``PreparedTest.use``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

__all__ = ["TestResidual", "PreparedTest", "dot", "pooled_samples", "ROLES", "DIFF_WINDOW_S", "GAP_WINDOW_S",
           "REVERSAL_ACC"]

ROLES = ("identification", "validation")
DIFF_WINDOW_S = 0.020            # Savitzky-Golay window [s]
GAP_WINDOW_S = 0.050             # free-play window after a velocity reversal [s]
REVERSAL_ACC = 0.2               # reversal counts if |a| > 0.2 x rms acceleration


@dataclass
class TestResidual:
    """One rig test on a uniform time grid: time [s], stroke [m], velocity [m/s], measured and
    simulated (base model) force [N], mask (bool, samples that count: warm-up excluded),
    optional temperature [degC]; role "identification" or "validation"."""
    __test__ = False  # not a pytest test class

    name: str
    role: str
    time: np.ndarray
    stroke: np.ndarray
    velocity: np.ndarray
    measured: np.ndarray
    simulated: np.ndarray
    mask: np.ndarray
    temperature: np.ndarray | None = None

    def __post_init__(self):
        def bad(msg):
            raise ValueError(f"test {self.name!r}: {msg}")
        if self.role not in ROLES:
            bad(f"role must be one of {ROLES}, got {self.role!r}")
        n = np.size(self.time)
        for k in ("time", "stroke", "velocity", "measured", "simulated", "temperature"):
            a = getattr(self, k)
            if a is None and k == "temperature":
                continue
            a = np.asarray(a, dtype=float)
            if a.shape != (n,):
                bad(f"{k} must be a 1-D array of {n} samples (as time), got shape {a.shape}")
            if not np.all(np.isfinite(a)):
                bad(f"{k} has non-finite values")
            setattr(self, k, a)
        m = np.asarray(self.mask)
        if m.dtype != bool or m.shape != (n,):
            bad(f"mask must be a boolean array of {n} samples")
        self.mask = m
        if n < 20:
            bad(f"{n} samples, at least 20 needed")
        dt = np.diff(self.time)
        if np.any(dt <= 0) or np.ptp(dt) > 0.01 * dt.mean():
            bad("time must be strictly increasing and uniformly sampled (1 % tolerance)")
        if m.sum() < 10:
            bad("mask selects fewer than 10 samples")


class PreparedTest:
    """Derived signals of one test: residual r [N], acceleration [m/s^2], dF_sim/dt [N/s],
    usable samples (mask without the filter edges), velocity reversals."""

    def __init__(self, t: TestResidual):
        self.t, n = t, t.time.size
        self.dt = float(np.mean(np.diff(t.time)))
        self.fs = 1.0 / self.dt
        w = max(5, int(round(DIFF_WINDOW_S * self.fs)) | 1)
        w = min(w, n - 1 + n % 2)
        self.acc = signal.savgol_filter(t.stroke, w, 4, deriv=2, delta=self.dt)
        self.dF = signal.savgol_filter(t.simulated, w, 3, deriv=1, delta=self.dt)
        self.r = t.measured - t.simulated
        self.use = t.mask.copy()
        self.use[:w // 2] = self.use[n - w // 2:] = False
        if self.use.sum() < 10:
            raise ValueError(f"test {t.name!r}: fewer than 10 masked samples away from the ends")
        v, a = t.velocity, self.acc
        i = np.flatnonzero(np.signbit(v[:-1]) != np.signbit(v[1:])) + 1   # first sample after
        thr = REVERSAL_ACC * np.sqrt(np.mean(a[self.use] ** 2))
        i = i[(np.abs(a[i]) > thr) & self.use[i]]
        keep, last = [], -np.inf
        for k in i:                           # one reversal per free-play window
            if k - last >= GAP_WINDOW_S * self.fs:
                keep.append(k)
                last = k
        self.rev = np.array(keep, dtype=int)
        self.rev_sign = np.where(np.signbit(v[self.rev]), -1.0, 1.0)

    def stack(self, tau):
        """Sample indices (reversals x tau [s]) fully inside the usable samples, and the sign of v after."""
        idx = self.rev[:, None] + np.rint(np.asarray(tau) * self.fs).astype(int)[None, :]
        ok = (idx.min(1) >= 0) & (idx.max(1) < self.t.time.size)
        ok[ok] = self.use[idx[ok]].all(1)
        return idx[ok], self.rev_sign[ok]


def dot(a, b) -> float:
    """The dot product of two 1-D arrays, not through BLAS."""
    return float(np.einsum("i,i", a, b))   # not BLAS: its threads stall on a loaded machine


def pooled_samples(preps, fn):
    """fn(prep) (full-length array or scalar) on the usable samples, concatenated over preps."""
    return np.concatenate([np.broadcast_to(fn(p), p.r.shape)[p.use] for p in preps])
