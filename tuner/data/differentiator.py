"""Stroke velocity: a zero-phase Savitzky-Golay differentiator designed for a band.

Cubic least-squares fit over a centred window, first derivative at the centre
(``scipy.signal.savgol_filter`` with ``deriv=1``); a symmetric FIR, hence zero-phase. Its gain
relative to the ideal ``j 2 pi f`` is 1 - O(f^4); ``Differentiator.design`` picks the longest odd
window whose gain error stays within the tolerance for every frequency up to the band. Used by
the preprocessing (``tuner.data.preprocess``) and the plausibility checks (``tuner.data.reading``).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy import signal

def _savgol_gain(window: int, polyorder: int, rate: float, f) -> np.ndarray:
    """Complex gain of the SG differentiator divided by the ideal j 2 pi f (f [Hz] > 0)."""
    c = signal.savgol_coeffs(window, polyorder, deriv=1, delta=1.0 / rate, use="dot")
    k = np.arange(window) - (window - 1) // 2
    f = np.atleast_1d(np.asarray(f, dtype=float))
    h = np.exp(2j * np.pi * np.outer(f, k) / rate) @ c
    return h / (2j * np.pi * f)


@dataclass(frozen=True)
class Differentiator:
    """Zero-phase Savitzky-Golay first-derivative filter (see module docstring).

    sample_rate [Hz]; window [samples, odd]; polyorder; band_hz [Hz] and tol:
    the design requirement |gain/(j 2 pi f) - 1| <= tol for f <= band_hz.
    """

    sample_rate: float
    window: int
    polyorder: int = 3
    band_hz: float = 20.0
    tol: float = 0.005

    @classmethod
    def design(cls, sample_rate: float, band_hz: float = 20.0, tol: float = 0.005,
               max_window: int | None = None) -> "Differentiator":
        """Longest odd window meeting the requirement at ``sample_rate`` [Hz]."""
        if not sample_rate > 0 or not band_hz > 0 or not tol > 0:
            raise ValueError("sample_rate, band_hz and tol must be positive")
        f = np.linspace(band_hz / 200, band_hz, 200)

        def err(w):
            return np.max(np.abs(np.abs(_savgol_gain(w, 3, sample_rate, f)) - 1.0))

        w = 5
        if err(w) > tol:
            warnings.warn(f"sample rate {sample_rate:g} Hz too low for a {100 * tol:g} % "
                          f"accurate derivative up to {band_hz:g} Hz; using the shortest "
                          f"window (5 samples)", stacklevel=2)
        else:
            lo, hi = 5, 7
            while err(hi) <= tol:  # bracket, then bisect over odd windows
                lo, hi = hi, 2 * hi + 1
            while hi - lo > 2:
                mid = lo + 2 * ((hi - lo) // 4)
                lo, hi = (mid, hi) if err(mid) <= tol else (lo, mid)
            w = lo
        if max_window is not None and w > max_window:
            w = max(5, max_window - (1 - max_window % 2))
        return cls(float(sample_rate), int(w), 3, float(band_hz), float(tol))

    def gain(self, f) -> np.ndarray:
        """Complex gain relative to the ideal differentiator at f [Hz] (1 = exact)."""
        return _savgol_gain(self.window, self.polyorder, self.sample_rate, f)

    @property
    def cutoff_hz(self) -> float:
        """Frequency [Hz] where the relative gain falls to 1/sqrt(2) (-3 dB)."""
        f = np.linspace(self.sample_rate / 2e4, self.sample_rate / 2, 20001)
        g = np.abs(self.gain(f))
        i = int(np.argmax(g < 1 / np.sqrt(2)))
        return float(np.interp(1 / np.sqrt(2), [g[i], g[i - 1]], [f[i], f[i - 1]]))

    def apply(self, x) -> np.ndarray:
        """Derivative [unit/s] of samples ``x`` taken at ``sample_rate``."""
        x = np.asarray(x, dtype=float)
        if len(x) < self.window:
            raise ValueError(f"signal of {len(x)} samples is shorter than the "
                             f"differentiator window ({self.window})")
        return signal.savgol_filter(x, self.window, self.polyorder, deriv=1,
                                    delta=1.0 / self.sample_rate, mode="interp")

    def describe(self) -> str:
        g = abs(self.gain(self.band_hz)[0])
        return (f"Savitzky-Golay differentiator (zero-phase, polyorder {self.polyorder}, "
                f"window {self.window} samples = {1e3 * self.window / self.sample_rate:.1f} ms "
                f"at {self.sample_rate:g} Hz): gain {g:.4f} of ideal at {self.band_hz:g} Hz "
                f"(design error <= {100 * self.tol:g} % up to {self.band_hz:g} Hz), "
                f"-3 dB at {self.cutoff_hz:.0f} Hz")
