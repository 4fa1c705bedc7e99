"""A damper FMU driven by sine strokes through fmpy, as a user's co-simulation master drives it, until the loop
has settled.

One FMU instance per FMU (``tuner.identification.runner.FmuRunner``: fmpy's ``FMU2Slave``, reset between runs),
inputs set at the start of each communication step (``input_interpolation = 0``, the master's convention, as
``fmpy.simulate_fmu`` sets them): stroke A sin(w t) [m, extension +] and its derivative A w cos(w t) [m/s]
from rest at t = 0, the FMU's other inputs and parameters at their start values. The step divides the period
into a whole number of samples, a multiple of 4 (both peak velocities and both stroke ends fall on samples), at
most ``SineSettings.max_step_s`` (1 ms, the FMUs' accurate step) and at least ``min_samples`` per period. A run
is settled when the first harmonic and both peak-velocity forces of its last period differ from the period
before by less than ``settle_tolerance`` of the force's first harmonic; otherwise it is run again with twice
the periods, up to ``max_periods``, and said unsettled if it never is.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tuner.datasheet.loop import LoopQuantities, loop_quantities
from tuner.identification.runner import FmuRunner

__all__ = ["SineSettings", "SettledLoop", "SineDriver"]


@dataclass(frozen=True)
class SineSettings:
    """How the sines are run: ``max_step_s`` [s] communication step cap, ``min_samples`` per period, ``periods``
    run at first (the last one analysed, the one before it the settling check), ``max_periods`` the most,
    ``settle_tolerance`` [1] of |F_1| between the last two periods."""

    max_step_s: float = 1e-3
    min_samples: int = 200
    periods: int = 3
    max_periods: int = 48
    settle_tolerance: float = 1e-3

    def check(self) -> None:
        """ValueError naming the setting that cannot be used."""
        if not 0 < self.max_step_s <= 0.01:
            raise ValueError(f"sine runs: max_step_s {self.max_step_s} s must be in (0, 0.01]")
        if self.min_samples < 40 or self.periods < 2 or self.max_periods < self.periods:
            raise ValueError("sine runs: need min_samples >= 40, periods >= 2 and max_periods >= periods")
        if not 0 < self.settle_tolerance < 0.1:
            raise ValueError(f"sine runs: settle_tolerance {self.settle_tolerance} must be in (0, 0.1)")

    def samples_per_period(self, frequency_hz: float) -> int:
        """Samples per period: a multiple of 4, the step at most ``max_step_s``, at least ``min_samples``."""
        n = max(self.min_samples, math.ceil(1.0 / (frequency_hz * self.max_step_s)))
        return 4 * math.ceil(n / 4)


@dataclass(frozen=True)
class SettledLoop:
    """One sine run: the last period's samples (``time`` [s], ``stroke`` [m], ``force`` [N]; the phase of the
    stroke's sine is 0 at ``time[0]``), its ``quantities`` (``tuner.datasheet.loop``), the ``periods`` run,
    ``settled`` and the ``change`` [1] of the last period against the one before (of |F_1|)."""

    time: np.ndarray
    stroke: np.ndarray
    force: np.ndarray
    quantities: LoopQuantities
    periods: int
    settled: bool
    change: float


class SineDriver:
    """Sine strokes into one damper FMU (``path``), one fmpy instance reused (reset) for every run; close it
    (or use ``with``) when done."""

    def __init__(self, path: Path, settings: SineSettings = SineSettings()):
        settings.check()
        self.settings = settings
        self.runner = FmuRunner(path, input_mode=0)
        self.path = Path(path)

    def close(self) -> None:
        self.runner.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def stroke_run(self, frequency_hz: float, amplitude_m: float, periods: int) -> tuple:
        """(time [s], stroke [m], force [N]) of ``periods`` periods of A sin(w t) from rest, sampled as the module
        docstring says (samples 0 .. periods x N)."""
        n = self.settings.samples_per_period(frequency_hz)
        t = np.arange(periods * n + 1) / (n * frequency_hz)
        w = 2 * np.pi * frequency_hz
        x, v = amplitude_m * np.sin(w * t), amplitude_m * w * np.cos(w * t)
        return t, x, self.runner.run(t, x, v)

    def settled(self, frequency_hz: float, amplitude_m: float) -> SettledLoop:
        """The settled loop of a sine of ``frequency_hz`` [Hz] and ``amplitude_m`` [m] (module docstring)."""
        if not (frequency_hz > 0 and amplitude_m > 0):
            raise ValueError(f"sine run: frequency {frequency_hz} Hz and amplitude {amplitude_m} m must be positive")
        n, periods = self.settings.samples_per_period(frequency_hz), self.settings.periods
        while True:
            t, x, f = self.stroke_run(frequency_hz, amplitude_m, periods)
            last = slice((periods - 1) * n, periods * n)
            before = slice((periods - 2) * n, (periods - 1) * n)
            q = loop_quantities(t[last], x[last], f[last], frequency_hz)
            p = loop_quantities(t[before], x[before], f[before], frequency_hz)
            scale = q.dynamic_stiffness_n_m * q.amplitude_m
            change = max(abs(complex(q.storage_n_m, q.loss_n_m) - complex(p.storage_n_m, p.loss_n_m)) * q.amplitude_m,
                         abs(q.force_extension_n - p.force_extension_n),
                         abs(q.force_compression_n - p.force_compression_n)) / scale if scale > 0 else math.inf
            settled = change <= self.settings.settle_tolerance
            if settled or 2 * periods > self.settings.max_periods:
                return SettledLoop(time=t[last] - t[last][0], stroke=x[last], force=f[last], quantities=q,
                                   periods=periods, settled=settled, change=float(change))
            periods *= 2
