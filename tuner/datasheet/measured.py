"""The measured datasheet points of a rig's sine tests, and the model's points at the same frequency and amplitude.

A rig test is a sine test when its stroke is one: the frequency f [Hz] is the one whose sine fits the stroke best
(the spectrum's peak, refined by least squares, on the whole record and again on its steady part), and over the
analysis window the stroke departs from its fundamental by less than ``SINE_TOLERANCE`` of its rms. The window:
the longest run of whole periods, after the first period and the settling of the lab's declared filter
(``tuner.data.prefilter``), whose fundamental amplitude stays within ``STEADY_TOLERANCE`` of the median period's
(a rig fades its stroke in and out), less its first period where more remain (the damper settles after the fade-in),
at least ``MIN_PERIODS`` periods. The
measured quantities are read off the window exactly as the simulated ones (``tuner.datasheet.loop``).

The model's twin of each measured point: the FMU driven by a sine of the test's frequency and amplitude until
settled (``tuner.datasheet.sine_runs``); when the lab filtered its channels, the sine's amplitude is the measured
one with the filter's gain at f undone and the simulated stroke and force pass the same filter before they are
read, as the data were made (a filter on both channels cancels in K* = F_1 / X_1, not in the distortion or the
forces at peak velocity). The model's error at each point is model minus measured: in % of the measured value
for stiffnesses, damping and forces, in degrees for the loss angle, in percentage points for the distortion.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from tuner.data.prefilter import Prefilter
from tuner.data.reading import RigTest
from tuner.datasheet.loop import LoopQuantities, harmonics, loop_quantities
from tuner.datasheet.sine_runs import SineDriver

__all__ = ["SINE_TOLERANCE", "MIN_PERIODS", "SineTest", "NotSine", "sine_test", "model_point", "point_errors"]

#: rms of the stroke beyond its fundamental, of the stroke's rms, up to which a test is a sine test
SINE_TOLERANCE = 0.05
#: whole periods a sine test's analysis window needs at least
MIN_PERIODS = 2
#: relative departure of a period's fundamental amplitude from the median period's up to which it is steady
STEADY_TOLERANCE = 0.02
#: relative errors [%] (model - measured) / |measured| of these quantities; differences of the others
RELATIVE = ("storage_n_m", "loss_n_m", "dynamic_stiffness_n_m", "maxwell_k_n_m", "maxwell_c_n_s_m",
            "force_extension_n", "force_compression_n")


@dataclass(frozen=True)
class SineTest:
    """A rig test read as a sine test: ``name``, ``source`` (its file), the ``quantities`` measured over the
    window ``start_s`` .. ``end_s`` [s], the lab's filter ``prefilter`` (None: none declared), ``rate_hz`` [Hz]."""

    name: str
    source: str | None
    quantities: LoopQuantities
    start_s: float
    end_s: float
    prefilter: Prefilter | None
    rate_hz: float

    def to_dict(self) -> dict:
        return {"test": self.name, "file": self.source, **self.quantities.to_dict(),
                "window_s": [self.start_s, self.end_s],
                "prefilter": self.prefilter.spec if self.prefilter else None, "source": "measured"}


@dataclass(frozen=True)
class NotSine:
    """A rig test that is not a sine test, and why (``reason``)."""

    name: str
    reason: str

    def to_dict(self) -> dict:
        return {"test": self.name, "reason": self.reason}


def _frequency(t: np.ndarray, x: np.ndarray) -> float:
    """The frequency [Hz] of the sine that fits ``x`` best: the spectrum's peak (4 x zero-padded), refined within
    a bin by least squares (offset, cosine and sine at each trial frequency)."""
    dt = (t[-1] - t[0]) / (t.size - 1)
    pad = 4 * t.size
    spec = np.abs(np.fft.rfft(x - x.mean(), pad))
    k = int(np.argmax(spec[1:])) + 1
    f0, df = k / (pad * dt), 1.0 / (pad * dt)

    def misfit(f):
        basis = np.column_stack([np.ones_like(t), np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t)])
        coef, *_ = np.linalg.lstsq(basis, x, rcond=None)
        return float(np.sum((x - basis @ coef) ** 2))

    return float(minimize_scalar(misfit, bounds=(max(f0 - df, 0.5 * f0), f0 + df), method="bounded",
                                 options={"xatol": 1e-7 * f0}).x)


def _prefilter(test: RigTest) -> Prefilter | None:
    """The lab's filter the test was read with (``metadata['read']['prefilter']``), None without."""
    d = (test.metadata.get("read") or {}).get("prefilter")
    if not d:
        return None
    keep = ("kind", "window_s", "lab_rate_hz", "order", "cutoff_hz", "zero_phase", "force_only")
    return Prefilter(**{k: d[k] for k in keep if k in d})


def _steady_periods(t: np.ndarray, x: np.ndarray, f: float, start: float, end: float) -> tuple[float, int]:
    """(start [s], count) of the longest run of whole periods of ``f`` [Hz] within ``start`` .. ``end`` [s] whose
    fundamental amplitude is within ``STEADY_TOLERANCE`` of the median period's: the rig's steady sine, without
    the fade-in and fade-out a rig ramps its stroke through."""
    count = math.floor((end - start) * f + 1e-9)
    if count < 1:
        return start, 0
    amps = []
    for k in range(count):
        keep = (t >= start + k / f) & (t < start + (k + 1) / f)
        amps.append(abs(harmonics(t[keep], x[keep], f, count=1).first) if keep.sum() >= 4 else 0.0)
    steady = np.abs(np.array(amps) - np.median(amps)) <= STEADY_TOLERANCE * np.median(amps)
    best, run, first = (0, 0), 0, 0
    for k, ok in enumerate(steady):
        run, first = (run + 1, first) if ok else (0, k + 1)
        if run > best[1]:
            best = (first, run)
    return start + best[0] / f, best[1]


def sine_test(test: RigTest) -> SineTest | NotSine:
    """``test`` read as a sine test (module docstring), or why it is not one."""
    t, x, force = (np.asarray(a, dtype=float) for a in (test.time, test.stroke, test.force))
    if t.size < 64:
        return NotSine(test.name, f"{t.size} samples: too few for a sine test")
    f = _frequency(t, x)
    lab = _prefilter(test)
    settle = lab.settling_s if lab else 0.0
    end_limit = t[-1] - (settle if lab and lab.zero_phase else 0.0)
    start, periods = _steady_periods(t, x, f, t[0] + max(1.0 / f, settle), end_limit)
    if periods >= MIN_PERIODS:  # the frequency of the steady part, and its periods again
        keep = (t >= start) & (t < start + periods / f)
        f = _frequency(t[keep], x[keep])
        start, periods = _steady_periods(t, x, f, start, end_limit)
    if periods > MIN_PERIODS:  # the damper settles after the fade-in: the steady stroke's first period left out
        start, periods = start + 1.0 / f, periods - 1
    if periods < MIN_PERIODS:
        return NotSine(test.name, f"no steady sine: the best-fitting sine ({f:.4g} Hz) holds its amplitude for "
                                  f"{periods} whole period(s) after the first (and the filter's settling); a sine "
                                  f"test needs {MIN_PERIODS}")
    end = start + periods / f
    keep = (t >= start) & (t < end)
    h = harmonics(t[keep], x[keep], f, count=1)
    fundamental = np.real(h.first * np.exp(2j * np.pi * f * t[keep]))
    rms = float(np.sqrt(np.mean((x[keep] - h.offset) ** 2)))
    departs = float(np.sqrt(np.mean((x[keep] - h.offset - fundamental) ** 2))) / rms if rms > 0 else math.inf
    if departs > SINE_TOLERANCE:
        return NotSine(test.name, f"the stroke departs from a sine of {f:.4g} Hz by {100 * departs:.0f} % of its rms "
                                  f"(a sine test: below {100 * SINE_TOLERANCE:.0f} %)")
    q = loop_quantities(t[keep], x[keep], force[keep], f)
    rate = 1.0 / float(np.mean(np.diff(t)))
    return SineTest(test.name, str(test.source) if test.source else None, q, float(start), float(end), lab, rate)


def model_point(driver: SineDriver, sine: SineTest) -> tuple[LoopQuantities, bool]:
    """(the quantities of the FMU on ``driver`` at ``sine``'s frequency and amplitude, settled) as the module
    docstring says: through the lab's filter when the test declares one."""
    q, lab = sine.quantities, sine.prefilter
    f = q.frequency_hz
    if lab is None:
        loop = driver.settled(f, q.amplitude_m)
        return loop.quantities, loop.settled
    gain = 1.0 if lab.force_only else abs(complex(lab.response(np.array([f]), sine.rate_hz)[0]))
    amplitude = q.amplitude_m / gain
    loop = driver.settled(f, amplitude)
    extra = math.ceil(lab.settling_s * f)
    periods = loop.periods + 2 * extra + 1
    t, x, force = driver.stroke_run(f, amplitude, periods)
    rate = 1.0 / (t[1] - t[0])
    xf = x if lab.force_only else lab.apply(x, rate)
    ff = lab.apply(force, rate)
    n = driver.settings.samples_per_period(f)
    last = slice((loop.periods + extra - 1) * n, (loop.periods + extra) * n)
    return loop_quantities(t[last], xf[last], ff[last], f), loop.settled


def point_errors(model: LoopQuantities, measured: LoopQuantities) -> dict:
    """The model's error at a measured point (module docstring): ``<quantity>_pct`` for ``RELATIVE``,
    ``loss_angle_deg`` and ``distortion_pct_points``; nan where the measured value is 0 or not finite."""
    m, d = model.to_dict(), measured.to_dict()
    out = {}
    for key in RELATIVE:
        ok = math.isfinite(d[key]) and math.isfinite(m[key]) and d[key] != 0
        out[f"{key}_pct"] = 100 * (m[key] - d[key]) / abs(d[key]) if ok else math.nan
    out["loss_angle_deg"] = m["loss_angle_deg"] - d["loss_angle_deg"]
    out["distortion_pct_points"] = 100 * (m["distortion"] - d["distortion"])
    return out
