"""Random track irregularity from the ERRI B176 power spectral density.

One-sided PSD [m^2/(rad/m)] of the spatial angular frequency W [rad/m]:

    S(W) = A Wc^2 / ((W^2 + Wr^2) (W^2 + Wc^2)),  Wc = 0.8246 rad/m, Wr = 0.0206 rad/m

with A [m rad] = 2.119e-7 (low level) or 6.125e-7 (high level) for lateral alignment and
4.032e-7 / 1.080e-6 for vertical level. The low level describes well-maintained track and is
the default here, because all scenarios run on high-speed (or high-quality) lines.

A profile is synthesised as a sum of harmonics ``sum a_k cos(W_k s + phi_k)`` with
``a_k = sqrt(2 S(W_k) dW)``, deterministic amplitudes and phases uniform in [0, 2 pi) from
``numpy.random.default_rng(seed)``, on the frequency grid ``W_k = k dW`` (``dW = 2 pi / P``,
P the profile period), restricted to wavelengths ``lambda_min <= 2 pi / W <= lambda_max``.
On the grid ``s_j = j ds`` the sum is exactly an inverse FFT, so synthesis is O(n log n);
between grid points the profile is interpolated linearly (``ds`` = 0.05 m is 60 points per
shortest wavelength, amplitude error < 0.15 %).
"""
from __future__ import annotations

import math

import numpy as np

W_C = 0.8246
"""ERRI B176 corner angular frequency Wc [rad/m]."""
W_R = 0.0206
"""ERRI B176 corner angular frequency Wr [rad/m]."""
A_LATERAL = {"low": 2.119e-7, "high": 6.125e-7}
"""ERRI B176 lateral alignment coefficient A [m rad] by level."""
A_VERTICAL = {"low": 4.032e-7, "high": 1.080e-6}
"""ERRI B176 vertical level coefficient A [m rad] by level."""


def erri_psd(W, A: float, Wc: float = W_C, Wr: float = W_R):
    """One-sided ERRI B176 PSD [m^2/(rad/m)] at angular frequency ``W`` [rad/m] for
    coefficient ``A`` [m rad]."""
    W = np.asarray(W, dtype=float)
    return A * Wc**2 / ((W**2 + Wr**2) * (W**2 + Wc**2))


def lateral_psd(W, level: str = "low"):
    """One-sided lateral alignment PSD [m^2/(rad/m)] at ``W`` [rad/m], level 'low'|'high'."""
    if level not in A_LATERAL:
        raise ValueError(f"irregularity level must be 'low' or 'high', got {level!r}")
    return erri_psd(W, A_LATERAL[level])


class IrregularityProfile:
    """Synthesised profile on a uniform grid; call it with positions ``s`` [m] to get the
    irregularity [m] (linear interpolation; zero outside [0, length])."""

    def __init__(self, s: np.ndarray, y: np.ndarray, wavenumbers: np.ndarray, amplitudes: np.ndarray):
        self.s = s
        self.y = y
        self.wavenumbers = wavenumbers
        """Angular frequencies W_k of the harmonics [rad/m]."""
        self.amplitudes = amplitudes
        """Amplitudes a_k of the harmonics [m]."""

    @property
    def ds(self) -> float:
        """Grid step [m]."""
        return float(self.s[1] - self.s[0])

    @property
    def length(self) -> float:
        """Length of the profile [m]."""
        return float(self.s[-1])

    def __call__(self, s):
        return np.interp(np.asarray(s, dtype=float), self.s, self.y, left=0.0, right=0.0)


def synthesize(
    length: float,
    seed=0,
    A: float = A_LATERAL["low"],
    lambda_min: float = 3.0,
    lambda_max: float = 200.0,
    ds: float = 0.05,
    min_period: float = 2000.0,
    taper: float = 0.0,
) -> IrregularityProfile:
    """Random-phase harmonic synthesis of an ERRI B176 profile.

    length [m]: profile covers s in [0, length]; seed: anything ``default_rng`` accepts
    (int or SeedSequence); A [m rad]: PSD coefficient; lambda_min, lambda_max [m]: band of
    wavelengths; ds [m]: grid step; min_period [m]: lower bound for the period P of the
    harmonic grid (P >= length, so the profile never repeats inside [0, length]; a long P
    gives a fine frequency grid dW = 2 pi / P); taper [m]: raised-cosine fade-in over
    [0, taper] so a vehicle can start from rest without a kick (0 = none).
    """
    for name, v in (("length", length), ("ds", ds), ("lambda_min", lambda_min), ("lambda_max", lambda_max)):
        if not (math.isfinite(v) and v > 0.0):
            raise ValueError(f"{name} must be finite and > 0, got {v}")
    if not lambda_min < lambda_max:
        raise ValueError(f"lambda_min ({lambda_min} m) must be < lambda_max ({lambda_max} m)")
    if lambda_min < 4.0 * ds:
        raise ValueError(f"ds = {ds} m is too coarse for lambda_min = {lambda_min} m (need ds <= lambda_min / 4)")
    if not (A > 0.0 and math.isfinite(A)):
        raise ValueError(f"PSD coefficient A must be > 0, got {A}")
    if taper < 0.0:
        raise ValueError(f"taper must be >= 0 m, got {taper}")
    rng = np.random.default_rng(seed)
    n_pts = int(math.ceil(length / ds)) + 1
    n_fft = 1 << int(math.ceil(math.log2(max(n_pts, min_period / ds, 2))))
    period = n_fft * ds
    dW = 2.0 * math.pi / period
    k = np.arange(n_fft // 2 + 1)
    W = k * dW
    band = (W >= 2.0 * math.pi / lambda_max) & (W <= 2.0 * math.pi / lambda_min)
    amp = np.sqrt(2.0 * erri_psd(W[band], A) * dW)
    phase = rng.uniform(0.0, 2.0 * math.pi, size=amp.size)
    spec = np.zeros(k.size, dtype=complex)
    spec[band] = amp * np.exp(1j * phase)
    # irfft computes (1/n) sum_k c_k e^{i 2 pi k j / n} with Hermitian symmetry (factor 2
    # for 0 < k < n/2); sum_k a_k cos(W_k s_j + phi_k) = Re sum_k c_k e^{i W_k s_j}.
    y = np.fft.irfft(spec, n=n_fft) * n_fft / 2.0
    y = y[:n_pts]
    s = np.arange(n_pts) * ds
    if taper > 0.0:
        ramp = s < taper
        y[ramp] *= 0.5 * (1.0 - np.cos(math.pi * s[ramp] / taper))
    return IrregularityProfile(s, y, W[band], amp)
