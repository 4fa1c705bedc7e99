"""Preprocessing of a rig test for the fit: stroke velocity and resampling to the fit rate.

Preprocessing (:func:`prepare`)
-------------------------------
* Stroke velocity: Savitzky-Golay differentiator (cubic least-squares fit over
  a centred window, first derivative at the centre; ``scipy.signal.savgol_filter``
  with ``deriv=1``), applied at the source sample rate. It is a symmetric FIR,
  hence zero-phase. Its gain relative to the ideal ``j 2 pi f`` is 1 - O(f^4);
  the window is the longest odd one whose gain error stays within 0.5 % (design
  margin under the 1 % requirement) for every frequency up to the band
  (``stroke_band_hz``: where the stroke's velocity content ends - 99 % of its
  power, and a PSD at least 1 % of the peak - between 20 Hz and min(0.4 x the fit
  rate, 0.1 x the sample rate); ``--diff-band`` sets it; a rig's measured velocity
  replaces it). For a 20 Hz band at 1 kHz
  that is 19 samples (19 ms): gain 0.9998 at 10 Hz, 0.9963 at 20 Hz, 0.948 at
  40 Hz, -3 dB at about 66 Hz, and above 100 Hz the output never exceeds that of
  an ideal differentiator at 18 Hz (white stroke noise sigma [m] gives velocity
  noise 106 sigma [m/s], against 707 sigma for a central difference). The window
  scales with the sample rate so the same holds at any rate >= ~200 Hz.
  Within half a window of either end the fit is one-sided and less accurate.
* Resampling to the fit rate (rational ratio up/down): linear-phase Kaiser
  FIR low-pass (``scipy.signal.resample_poly`` with its delay compensated, so
  zero-phase), pass band flat within 0.1 % up to 0.8 x and stop band >= 60 dB
  from 1.0 x the lower Nyquist frequency. Only complete filter outputs are
  kept (no edge transients): the output grid is t0 + k / fit_rate and about
  half the filter length is dropped at each end (95 ms for 1 kHz -> 200 Hz),
  so the prepared test starts after t0. Stroke, velocity, force and channels
  go through the same filter, so their mutual phase is untouched. When the fit
  rate equals the sample rate nothing is resampled or trimmed.
* A source rate that is no ratio of integers <= 1000 of the fit rate (a logger's
  3004.8 Hz clock for 200 Hz: 125/1878) is first interpolated (cubic spline, every
  channel alike) onto the nearest integer multiple of the fit rate at or above it
  (3200 Hz), then decimated as above. The spline's gain error at f is about
  (2 pi f / rate)^4 / 384 -- below 1e-6 for 100 Hz at 3 kHz -- and its images
  above the source Nyquist fall in the filter's stop band.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import numpy as np
from scipy import signal
from scipy.interpolate import CubicSpline

from tuner.data.differentiator import Differentiator
from damper_dataset.format import MIN_SAMPLES, DataError
from tuner.data.reading import RigTest

# --------------------------------------------------------------------------- resampling

#: largest integer of the up/down ratio of the resampler (filter length grows with ``up``)
MAX_DENOMINATOR = 1000

@dataclass(frozen=True)
class Resampler:
    """Zero-phase anti-aliased rational resampler rate_in -> rate_in * up / down [Hz]."""

    rate_in: float
    up: int
    down: int
    taps: np.ndarray
    passband_hz: float
    stopband_hz: float
    attenuation_db: float = 60.0

    @property
    def rate_out(self) -> float:
        return self.rate_in * self.up / self.down

    @staticmethod
    def ratio(rate_in: float, rate_out: float, max_denominator: int = MAX_DENOMINATOR) -> Fraction | None:
        """rate_out / rate_in as a ratio of integers <= max_denominator within 1e-6, or None."""
        ratio = Fraction(rate_out / rate_in).limit_denominator(max_denominator)
        if ratio == 0 or abs(float(ratio) * rate_in / rate_out - 1.0) > 1e-6:
            return None
        return ratio

    @classmethod
    def design(cls, rate_in: float, rate_out: float, attenuation_db: float = 60.0,
               max_denominator: int = MAX_DENOMINATOR) -> "Resampler":
        """FIR flat to 0.8 x and >= attenuation_db from 1.0 x the lower Nyquist [Hz]."""
        if not rate_in > 0 or not rate_out > 0:
            raise ValueError(f"sample rates must be positive, got {rate_in} -> {rate_out} Hz")
        ratio = cls.ratio(rate_in, rate_out, max_denominator)
        if ratio is None:
            raise ValueError(f"cannot resample {rate_in:g} Hz to {rate_out:g} Hz with a ratio "
                             f"of integers <= {max_denominator} (``prepare`` interpolates onto a grid first)")
        up, down = ratio.numerator, ratio.denominator
        nyq = 0.5 * min(rate_in, rate_in * up / down)
        f_pass, f_stop = 0.8 * nyq, nyq
        fs_up = rate_in * up
        numtaps, beta = signal.kaiserord(attenuation_db, 2 * (f_stop - f_pass) / fs_up)
        numtaps += 1 - numtaps % 2  # odd: integer delay, exactly compensated
        taps = signal.firwin(numtaps, 0.5 * (f_pass + f_stop), window=("kaiser", beta),
                             fs=fs_up)
        return cls(float(rate_in), up, down, taps, f_pass, f_stop, attenuation_db)

    def first_index(self) -> int:
        """Index, on the output grid t0 + k / rate_out, of the first complete output."""
        return -(-((len(self.taps) - 1) // 2) // self.down)

    def output_length(self, n: int) -> int:
        """Number of complete outputs for ``n`` input samples (may be <= 0)."""
        half = (len(self.taps) - 1) // 2
        return ((n - 1) * self.up - half) // self.down - self.first_index() + 1

    def apply(self, x) -> np.ndarray:
        """Resample ``x`` (input sample 0 at t0) to ``rate_out``.

        Returns only complete filter outputs, i.e. the samples k = first_index()
        ... on the grid t0 + k / rate_out whose whole filter support lies inside
        the data: no edge transients, at the price of about half the filter
        length (``trim_s``) lost at each end.
        """
        x = np.asarray(x, dtype=float)
        k0, n_out = self.first_index(), self.output_length(len(x))
        if n_out < 1:
            raise ValueError(f"{len(x)} samples are too few to resample {self.rate_in:g} Hz "
                             f"-> {self.rate_out:g} Hz (filter of {len(self.taps)} taps)")
        y = signal.resample_poly(x, self.up, self.down, window=self.taps)
        return y[k0:k0 + n_out]

    @property
    def trim_s(self) -> float:
        """Time [s] lost at each end (upper bound)."""
        return (self.first_index() + 1) / self.rate_out

    def describe(self) -> str:
        verb = "decimated" if self.down > self.up else "interpolated"
        return (f"{verb} {self.rate_in:g} Hz -> {self.rate_out:g} Hz (up {self.up}, down "
                f"{self.down}) through a zero-phase linear-phase Kaiser FIR low-pass "
                f"({len(self.taps)} taps at {self.rate_in * self.up:g} Hz): flat within 0.1 % "
                f"to {self.passband_hz:g} Hz, >= {self.attenuation_db:g} dB attenuation "
                f"from {self.stopband_hz:g} Hz; only complete filter outputs kept "
                f"(about {1e3 * self.trim_s:.0f} ms dropped at each end)")


# --------------------------------------------------------------------------- prepare

@dataclass
class PreparedTest:
    """A test ready for fitting, at the fit rate, SI units.

    time [s], stroke [m], stroke_velocity [m/s], force [N], channels (units in
    channel_units), sample_rate [Hz]; source_rate [Hz] of the file;
    differentiator and resampler (None when not resampled) document the processing;
    measured_velocity: the velocity is the rig's velocity column (not differentiated).
    """

    name: str
    role: str | None
    scenario: str
    time: np.ndarray
    stroke: np.ndarray
    stroke_velocity: np.ndarray
    force: np.ndarray
    channels: dict
    sample_rate: float
    source_rate: float
    differentiator: Differentiator
    resampler: Resampler | None
    metadata: dict = field(default_factory=dict)
    channel_units: dict = field(default_factory=dict)
    source: Path | None = None
    measured_velocity: bool = False
    #: how the source clock was put on a regular grid before the resampler ('' : it was not)
    regridded: str = ""

    def describe(self) -> str:
        """Plain-text statement of the preprocessing, for the report."""
        res = (self.regridded + self.resampler.describe() if self.resampler is not None
               else f"not resampled (fit rate = sample rate = {self.sample_rate:g} Hz)")
        vel = ("Stroke velocity measured by the rig (its velocity column)" if self.measured_velocity else
               f"Stroke velocity from the stroke at {self.source_rate:g} Hz by a {self.differentiator.describe()}")
        return f"Test {self.name!r}: {len(self.time)} samples at {self.sample_rate:g} Hz. {vel}. All channels {res}."


#: lowest differentiator band [Hz] (the design for 0.1-10 Hz railway strokes)
MIN_DIFF_BAND_HZ = 20.0
#: share of the stroke velocity's power (below the fit pass band) the differentiator band covers
DIFF_BAND_POWER = 0.99
#: lowest PSD, relative to its peak, of a frequency that counts as stroke content
DIFF_BAND_LEVEL = 1e-2


def stroke_band_hz(test: RigTest, fit_rate_hz: float) -> float:
    """Differentiator band [Hz] for a test resampled to ``fit_rate_hz``: where the stroke's
    velocity content ends, and at least ``MIN_DIFF_BAND_HZ``. Velocity by central difference,
    Welch PSD (0.25 Hz resolution), counted up to the fit's flat pass band (0.4 x the fit rate)
    or 0.1 x the sample rate (what the shortest, 5-sample window meets), whichever is lower.
    The content ends at the lower of (a) the frequency below which ``DIFF_BAND_POWER`` of the
    power lies and (b) the last frequency whose PSD is at least ``DIFF_BAND_LEVEL`` of the peak.
    Stroke noise rises as f^2 in the velocity and fools (a) alone (on the bundled quasi-static
    curves, counted to 100 Hz, it read 63-71 Hz for content ending near 7 Hz, where the noise
    PSD reaches 1e-3 of the peak at 100 Hz); (b) needs a noise of 1 % of the peak per bin."""
    rate = float(test.sample_rate)
    top = min(0.4 * float(fit_rate_hz), 0.1 * rate)
    v = np.gradient(np.asarray(test.stroke, dtype=float)) * rate
    f, p = signal.welch(v - v.mean(), fs=rate, nperseg=min(len(v), int(4 * rate)))
    sel = f <= top
    f, p = f[sel], p[sel]
    if not p.max() > 0:
        return MIN_DIFF_BAND_HZ
    c = np.cumsum(p)
    by_power = float(f[np.searchsorted(c / c[-1], DIFF_BAND_POWER)])
    by_level = float(f[np.flatnonzero(p >= DIFF_BAND_LEVEL * p.max())[-1]])
    return float(min(max(min(by_power, by_level), MIN_DIFF_BAND_HZ), max(top, MIN_DIFF_BAND_HZ)))


def prepare(test: RigTest, fit_rate_hz: float, *, diff_band_hz: float | None = None,
            diff_tol: float = 0.005) -> PreparedTest:
    """Differentiate the stroke and resample every channel to ``fit_rate_hz`` [Hz].

    ``diff_band_hz``: band [Hz] of the differentiator (None: ``stroke_band_hz`` when resampling,
    ``MIN_DIFF_BAND_HZ`` at the source rate).

    The velocity [m/s] is computed at the source rate (see module docstring),
    then stroke, velocity, force and channels pass through the same resampler,
    which drops the incomplete filter outputs at both ends (so ``time[0]`` may
    be later than the test's first sample). Raises DataError when fewer than
    100 samples would remain. A sample rate that is no ratio of small integers of the fit rate is
    put on a regular grid first (module docstring).
    """
    rate = float(test.sample_rate)
    fit_rate_hz = float(fit_rate_hz)
    if not fit_rate_hz > 0:
        raise ValueError(f"fit_rate_hz must be positive, got {fit_rate_hz}")
    if diff_band_hz is None:   # from the stroke when resampling to a fit rate, else the design band
        at_source = abs(fit_rate_hz / rate - 1.0) <= 1e-9 or test.velocity is not None
        diff_band_hz = MIN_DIFF_BAND_HZ if at_source else stroke_band_hz(test, fit_rate_hz)
    diff = Differentiator.design(rate, diff_band_hz, diff_tol, max_window=len(test.stroke))
    measured = test.velocity is not None
    vel = np.asarray(test.velocity, dtype=float).copy() if measured else diff.apply(test.stroke)
    if abs(fit_rate_hz / rate - 1.0) <= 1e-9:
        return PreparedTest(test.name, test.role, test.scenario, test.time.copy(),
                            test.stroke.copy(), vel, test.force.copy(),
                            {k: v.copy() for k, v in test.channels.items()}, rate, rate,
                            diff, None, dict(test.metadata), dict(test.channel_units),
                            test.source, measured)
    stroke_in, vel_in, force_in, channels_in, grid_note = test.stroke, vel, test.force, test.channels, ""
    if Resampler.ratio(rate, fit_rate_hz) is None:  # an odd logger clock: onto a regular grid first
        grid = fit_rate_hz * math.ceil(rate / fit_rate_hz - 1e-9)
        n_grid = int(math.floor((len(test.stroke) - 1) * grid / rate)) + 1
        k = np.arange(len(test.stroke)) / rate
        kg = np.arange(n_grid) / grid

        def regrid(x):
            return CubicSpline(k, np.asarray(x, dtype=float))(kg)

        stroke_in, vel_in, force_in = regrid(test.stroke), regrid(vel), regrid(test.force)
        channels_in = {name: regrid(v) for name, v in test.channels.items()}
        grid_note = (f"interpolated (cubic spline) from the {rate:g} Hz clock onto a {grid:g} Hz grid "
                     f"(no ratio of integers <= {MAX_DENOMINATOR} to {fit_rate_hz:g} Hz), then ")
        rate_grid = grid
    else:
        rate_grid = rate
    rs = Resampler.design(rate_grid, fit_rate_hz)
    if rs.output_length(len(stroke_in)) < MIN_SAMPLES:
        raise DataError(f"{test.source or test.name}: too short to resample {rate:g} Hz -> "
                        f"{rs.rate_out:g} Hz: fewer than {MIN_SAMPLES} samples remain after "
                        f"dropping {1e3 * rs.trim_s:.0f} ms of filter edge at each end")
    stroke = rs.apply(stroke_in)
    time = test.time[0] + (rs.first_index() + np.arange(len(stroke))) / rs.rate_out
    return PreparedTest(test.name, test.role, test.scenario, time, stroke, rs.apply(vel_in),
                        rs.apply(force_in), {k: rs.apply(v) for k, v in channels_in.items()},
                        rs.rate_out, rate, diff, rs, dict(test.metadata),
                        dict(test.channel_units), test.source, measured, grid_note)
