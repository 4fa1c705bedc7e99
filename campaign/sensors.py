"""Sensor chain of the virtual rig: noise, anti-alias filter, decimation, ADC.

Order (per channel, on the internal grid ``oversampling x sample_rate``):

1. transducer noise: white Gaussian, scaled so that its rms AFTER the anti-alias filter
   is ``force_noise`` [N] / ``stroke_noise`` [m] (the numbers a rig data sheet quotes);
2. anti-alias filter: linear-phase FIR low-pass (Kaiser window, cut-off ``cutoff`` x
   sample_rate), applied with its group delay compensated, as a delta-sigma ADC's
   decimation filter does; the SAME filter acts on both channels, so it creates no skew
   between stroke and force;
3. decimation to ``sample_rate`` [Hz];
4. quantisation: ``adc_bits`` over +-``force_range`` [N] / +-``stroke_range`` [m]
   (mid-tread rounding, saturating at full scale).

The temperature channel [degC] is sampled and rounded to ``temperature_resolution``.
Everything random comes from ``numpy.random.default_rng(seed)``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import firwin


@dataclass(frozen=True)
class SensorChain:
    """Rig sensor chain parameters (SI units, temperature in degC)."""

    force_noise: float = 20.0  # N rms, load cell
    stroke_noise: float = 2e-6  # m rms, stroke transducer
    force_range: float = 50e3  # N, +- full scale
    stroke_range: float = 0.1  # m, +- full scale
    adc_bits: int = 16
    oversampling: int = 4  # internal rate / sample rate
    cutoff: float = 0.4  # anti-alias cut-off / sample rate
    kaiser_beta: float = 6.0
    taps_per_oversampling: int = 16  # FIR length = taps_per_oversampling * oversampling + 1
    temperature_resolution: float = 0.01  # degC

    def __post_init__(self):
        for name in ("force_noise", "stroke_noise"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"SensorChain.{name} must be finite and >= 0, got {v}")
        for name in ("force_range", "stroke_range", "temperature_resolution"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"SensorChain.{name} must be finite and > 0, got {v}")
        if not (isinstance(self.adc_bits, int) and 2 <= self.adc_bits <= 32):
            raise ValueError(f"SensorChain.adc_bits must be an int in [2, 32], got {self.adc_bits}")
        if not (isinstance(self.oversampling, int) and self.oversampling >= 1):
            raise ValueError(f"SensorChain.oversampling must be an int >= 1, got {self.oversampling}")
        if not (0 < self.cutoff < 0.5):
            raise ValueError(f"SensorChain.cutoff must be in (0, 0.5) x sample rate, got {self.cutoff}")

    @classmethod
    def ideal(cls, oversampling: int = 4) -> "SensorChain":
        """No noise, 32-bit ADC over generous ranges: filter and decimation only."""
        return cls(force_noise=0.0, stroke_noise=0.0, adc_bits=32, force_range=1e6,
                   stroke_range=1.0, oversampling=oversampling)

    def lsb(self, full_range: float) -> float:
        """Quantisation step [unit of the channel] for a +-full_range channel."""
        return 2.0 * full_range / 2**self.adc_bits

    def fir(self) -> np.ndarray:
        """Anti-alias FIR taps (unit DC gain), designed at the internal rate."""
        os_ = self.oversampling
        if os_ == 1:
            return np.ones(1)
        n = self.taps_per_oversampling * os_ + 1
        return firwin(n, self.cutoff / os_ * 2.0, window=("kaiser", self.kaiser_beta))

    def filter_decimate(self, x: np.ndarray) -> np.ndarray:
        """Zero-phase (group-delay compensated) FIR filter on the internal grid, then keep
        every ``oversampling``-th sample starting with the first. Ends padded with the end
        values."""
        h = self.fir()
        half = (len(h) - 1) // 2
        xp = np.pad(np.asarray(x, dtype=float), half, mode="edge")
        y = np.convolve(xp, h, mode="valid")
        return y[:: self.oversampling]

    def quantise(self, x: np.ndarray, full_range: float) -> np.ndarray:
        """Mid-tread quantiser, saturating at the ends of the +-full_range scale."""
        q = self.lsb(full_range)
        top = 2 ** (self.adc_bits - 1)
        return np.clip(np.round(x / q), -top, top - 1) * q

    def _noise(self, rng: np.random.Generator, n: int, rms: float) -> np.ndarray:
        h = self.fir()
        return rng.standard_normal(n) * (rms / math.sqrt(float(np.sum(h * h))))

    def acquire(self, stroke: np.ndarray, force: np.ndarray, temperature: np.ndarray,
                seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Internal-grid signals (stroke [m], force [N], temperature [degC], equal length
        ``oversampling * (n - 1) + 1``) -> n samples per channel at the rig rate."""
        stroke = np.asarray(stroke, dtype=float)
        force = np.asarray(force, dtype=float)
        temperature = np.asarray(temperature, dtype=float)
        n_int = stroke.size
        if force.size != n_int or temperature.size != n_int or (n_int - 1) % self.oversampling:
            raise ValueError("acquire needs equal-length internal signals of length "
                             "oversampling * (n - 1) + 1")
        rng = np.random.default_rng(seed)
        f_noisy = force + self._noise(rng, n_int, self.force_noise)
        s_noisy = stroke + self._noise(rng, n_int, self.stroke_noise)
        f_out = self.quantise(self.filter_decimate(f_noisy), self.force_range)
        s_out = self.quantise(self.filter_decimate(s_noisy), self.stroke_range)
        res = self.temperature_resolution
        t_out = np.round(temperature[:: self.oversampling] / res) * res
        return s_out, f_out, t_out
