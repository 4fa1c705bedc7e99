"""A damper test programme in one run, as damper suppliers drive their rigs: a stepped sine.

Each step is a sine of its own frequency and amplitude, faded in over ``ramp_cycles`` cycles (raised
cosine of the amplitude), held for ``cycles`` full cycles, faded out alike and followed by ``pause_s`` at
rest; the steps follow each other in one stroke history, which :func:`programme_test` drives through
the virtual rig (``campaign.rig.measure``) into one recorded test.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from campaign.rig import Acquisition, measure

__all__ = ["Step", "stepped_sine", "programme_test"]


@dataclass(frozen=True)
class Step:
    """One step of a stepped sine: frequency [Hz] > 0, amplitude [m] > 0 (half the peak-to-peak stroke),
    the number of full-amplitude cycles held (>= 1)."""

    frequency_hz: float
    amplitude_m: float
    cycles: int = 8

    def __post_init__(self):
        if not (math.isfinite(self.frequency_hz) and self.frequency_hz > 0):
            raise ValueError(f"step frequency must be a positive number [Hz], got {self.frequency_hz!r}")
        if not (math.isfinite(self.amplitude_m) and 0 < self.amplitude_m <= 0.075):
            raise ValueError(f"step amplitude must be in (0, 0.075] m (the rig's stroke), got {self.amplitude_m!r}")
        if int(self.cycles) != self.cycles or self.cycles < 1:
            raise ValueError(f"step cycles must be a whole number >= 1, got {self.cycles!r}")


def stepped_sine(steps, fs: float = 1000.0, ramp_cycles: int = 1, pause_s: float = 0.5,
                 lead_s: float = 0.5) -> tuple[np.ndarray, np.ndarray, list[dict]]:
    """(time [s], stroke [m, + extension], the steps' spans) of a stepped sine at ``fs`` [Hz]: ``lead_s``
    [s] at rest, then per ``Step`` a fade-in over ``ramp_cycles`` cycles, its full-amplitude cycles, a
    fade-out and ``pause_s`` [s] at rest. Spans: per step {'frequency_hz', 'amplitude_m', 'cycles',
    't_start_s', 't_end_s'} of its full-amplitude cycles (the truth a programme's cutter is checked on)."""
    steps = [s if isinstance(s, Step) else Step(*s) for s in steps]
    if not steps:
        raise ValueError("a stepped sine needs at least one step")
    pieces, spans, t0 = [np.zeros(int(round(lead_s * fs)))], [], lead_s
    for s in steps:
        period = 1.0 / s.frequency_hz
        n_cyc = s.cycles + 2 * ramp_cycles
        n = int(round(n_cyc * period * fs))
        tau = np.arange(n) / fs
        ramp = ramp_cycles * period
        env = np.ones(n)
        if ramp > 0:
            up, down = tau < ramp, tau > n_cyc * period - ramp
            env[up] = 0.5 - 0.5 * np.cos(np.pi * tau[up] / ramp)
            env[down] = 0.5 - 0.5 * np.cos(np.pi * (n_cyc * period - tau[down]) / ramp)
        pieces.append(s.amplitude_m * env * np.sin(2 * np.pi * s.frequency_hz * tau))
        spans.append({"frequency_hz": s.frequency_hz, "amplitude_m": s.amplitude_m, "cycles": s.cycles,
                      "t_start_s": t0 + ramp, "t_end_s": t0 + ramp + s.cycles * period})
        pieces.append(np.zeros(int(round(pause_s * fs))))
        t0 += n / fs + pause_s
    x = np.concatenate(pieces)
    return np.arange(x.size) / fs, x, spans


def programme_test(steps, *, seed: int = 0, sample_rate: float = 1000.0, damper: str = "twin-tube",
                   **shape) -> tuple[pd.DataFrame, list[dict]]:
    """The stepped sine of ``steps`` (``Step`` or (frequency [Hz], amplitude [m], cycles)) driven through the
    virtual rig: (the recorded test, ``campaign.rig.measure``'s columns time [s], stroke [m], force [N],
    temperature [degC]; the steps' spans, :func:`stepped_sine`). ``shape``: ``stepped_sine``'s ramp_cycles,
    pause_s, lead_s. The stroke is imposed at 2x ``sample_rate``; ``seed``: the sensor noise's."""
    t, x, spans = stepped_sine(steps, fs=2 * sample_rate, **shape)
    df = measure(t, x, acquisition=Acquisition(sample_rate=sample_rate, seed=seed), damper=damper)
    return df, spans
