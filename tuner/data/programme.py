"""A test programme in one file: the steps of a stepped sine (several frequencies or amplitudes in a row),
cut into one test each, and the syntax that picks some of them (``FILE@2``, ``FILE@1Hz``).

Cutting (:func:`cut_programme`): the stroke's cycles are found between its upward crossings of its median
(with a hysteresis of 5 noise levels, at least 0.1 % of its half range, so that noise gives no crossings);
each cycle has its frequency (1 / its period, crossings interpolated between samples) and amplitude (half
its peak-to-peak). Consecutive cycles within ``FREQUENCY_TOL`` in frequency and ``AMPLITUDE_TOL`` in
amplitude of the run they join form a steady step; the others (fade-ins, fade-outs, transitions, rest) are
left out. Of each step the first ``SETTLING_CYCLES`` cycles are left out too (the damper settles after
the change: its oil column, valves and temperature), fewer on a short step so that it keeps
``MIN_CYCLES`` whole cycles, but always one; a run of fewer than ``MIN_CYCLES + 1`` cycles is no step.
A step's test spans its kept whole cycles; its frequency is their number over their duration, its
amplitude their median amplitude.

Picking (:func:`select_steps`): ``SEL`` after the file's name and ``@``, items separated by commas: a
step's 1-based number (``FILE@2``, ``FILE@1,3``), a frequency (``FILE@1Hz``, ``FILE@0.5Hz``: within 2 %),
an amplitude (``FILE@10mm``, ``FILE@0.5in``: within 3 %) or both (``FILE@1Hz:10mm``).
"""
from __future__ import annotations

import re
from dataclasses import asdict, dataclass

import numpy as np

from damper_dataset.format import DataError
from tuner.data.units import STROKE

__all__ = ["ProgrammeStep", "cut_programme", "select_steps", "split_selection", "FREQUENCY_TOL", "AMPLITUDE_TOL",
           "SETTLING_CYCLES", "MIN_CYCLES"]

#: relative spread of frequency and amplitude among a step's cycles
FREQUENCY_TOL, AMPLITUDE_TOL = 0.02, 0.03
#: cycles left out at the start of each step (the damper settles after the change); at least one
SETTLING_CYCLES = 2
#: whole cycles a step keeps at least (a supplier's low-frequency steps hold few cycles)
MIN_CYCLES = 2
#: how close a selection's frequency and amplitude must be to a step's [relative]
_PICK_FREQUENCY, _PICK_AMPLITUDE = 0.02, 0.03


@dataclass(frozen=True)
class ProgrammeStep:
    """One step of a programme: its 1-based number, frequency [Hz], amplitude [m] (half peak-to-peak),
    the rows [first, last) of the file it spans (its whole cycles), their number, its span [s from the
    file's first sample] and the settling cycles left out before it, of how many steps found (``of``)."""

    index: int
    of: int
    frequency_hz: float
    amplitude_m: float
    rows: tuple
    cycles: int
    t_start_s: float
    t_end_s: float
    settling_cycles: int

    @property
    def label(self) -> str:
        """``'1Hz-15mm'``: the step's frequency and amplitude, for the test's name."""
        return f"{self.frequency_hz:.3g}Hz-{self.amplitude_m * 1e3:.3g}mm"

    def to_dict(self) -> dict:
        """The step as JSON-ready figures (SI)."""
        return {**asdict(self), "rows": list(self.rows)}


def _crossings(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Times [s] of the upward crossings of ``x`` (stroke minus its median) through 0, with hysteresis: it
    must have been below -h since the last one (h: 5 x the noise from second differences, at least 0.1 %
    of the half range)."""
    half = 0.5 * float(np.ptp(x)) or 1.0
    noise = 1.4826 * float(np.median(np.abs(np.diff(x, 2)))) / np.sqrt(6.0)
    h = max(5.0 * noise, 1e-3 * half)
    state = np.where(x > h, 1, np.where(x < -h, -1, 0))
    nz = np.flatnonzero(state)
    if nz.size < 2:
        return np.zeros(0)
    held = state[nz]
    ups = nz[1:][(held[1:] == 1) & (held[:-1] == -1)]
    out = []
    for j in ups:  # the last sample below 0 before the first one above +h
        k = j - 1
        while k > 0 and x[k] >= 0:
            k -= 1
        out.append(t[k] + (t[k + 1] - t[k]) * (-x[k]) / (x[k + 1] - x[k]))
    return np.asarray(out)


def _runs(freq: np.ndarray, amp: np.ndarray) -> list[list[int]]:
    """Runs of consecutive cycles (indices) whose frequency and amplitude stay within the tolerances of
    the median of the run so far."""
    runs, cur = [], []
    for i in range(len(freq)):
        if cur:
            f0, a0 = np.median(freq[cur]), np.median(amp[cur])
            if abs(freq[i] / f0 - 1) > FREQUENCY_TOL or abs(amp[i] / a0 - 1) > AMPLITUDE_TOL:
                runs.append(cur)
                cur = []
        cur.append(i)
    return runs + ([cur] if cur else [])


def cut_programme(t: np.ndarray, stroke: np.ndarray, source: str) -> list[ProgrammeStep]:
    """The steps of a stepped sine (module docstring) in time [s] and stroke [m] (equal length, any clock);
    DataError naming the file when it holds no steady step."""
    x = np.asarray(stroke, dtype=float) - float(np.median(stroke))
    tc = _crossings(np.asarray(t, dtype=float), x)
    if tc.size < 2:
        raise DataError(f"{source}: no test programme found: the stroke does not cycle (fewer than two upward "
                        f"crossings of its median); read it without --programme or @ after the file name")
    idx = np.searchsorted(t, tc)  # the first sample after each crossing
    amp = np.array([0.5 * np.ptp(x[a:b]) if b > a else 0.0 for a, b in zip(idx[:-1], idx[1:])])
    freq = 1.0 / np.diff(tc)
    found = []
    for run in _runs(freq, amp):
        settle = max(min(SETTLING_CYCLES, len(run) - MIN_CYCLES), 1)
        keep = run[settle:]
        if len(keep) < MIN_CYCLES:
            continue
        a, b = keep[0], keep[-1] + 1  # cycles a .. b-1: crossings a .. b
        found.append((len(keep) / (tc[b] - tc[a]), float(np.median(amp[keep])), (int(idx[a]), int(idx[b])),
                      len(keep), float(tc[a] - t[0]), float(tc[b] - t[0]), settle))
    if not found:
        raise DataError(f"{source}: no test programme found: no run of {MIN_CYCLES + 1} or more cycles "
                        f"of one frequency (within {FREQUENCY_TOL:.0%}) and amplitude (within {AMPLITUDE_TOL:.0%}) "
                        f"among {len(freq)} cycles")
    return [ProgrammeStep(k + 1, len(found), *step) for k, step in enumerate(found)]


def split_selection(path: str) -> tuple[str, str | None]:
    """(file, selection) of ``FILE@SEL``; (path, None) without ``@`` or when the whole text names a file."""
    text = str(path)
    if "@" not in text:
        return text, None
    file, _, sel = text.rpartition("@")
    return (file, sel) if sel.strip() else (text, None)


_QUANTITY = re.compile(r"^\s*((?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?)\s*([a-zA-Z/]+)\s*$")


def _pick(item: str, steps: list[ProgrammeStep], source: str) -> list[ProgrammeStep]:
    """The steps one item of a selection names (module docstring)."""
    if item.strip().isdigit():
        k = int(item)
        if not 1 <= k <= len(steps):
            raise DataError(f"{source}: step {k} asked for, but the programme has {len(steps)} steps: {_listed(steps)}")
        return [steps[k - 1]]
    hits = list(steps)
    for part in item.split(":"):
        m = _QUANTITY.match(part)
        unit = m.group(2) if m else ""
        if not m or not (unit.lower() == "hz" or unit in STROKE):
            raise DataError(f"{source}: cannot read the step selection {item!r}: give a step number (2), a frequency "
                            f"(1Hz), an amplitude (10mm, 0.5in) or both (1Hz:10mm); steps: {_listed(steps)}")
        value = float(m.group(1))
        if unit.lower() == "hz":
            hits = [s for s in hits if abs(s.frequency_hz / value - 1) <= _PICK_FREQUENCY]
        else:
            hits = [s for s in hits if abs(s.amplitude_m / (value * STROKE[unit]) - 1) <= _PICK_AMPLITUDE]
    if not hits:
        raise DataError(f"{source}: no step at {item!r} (frequency within {_PICK_FREQUENCY:.0%}, amplitude within "
                        f"{_PICK_AMPLITUDE:.0%}); steps: {_listed(steps)}")
    return hits


def _listed(steps: list[ProgrammeStep]) -> str:
    """'1: 0.5 Hz 20 mm, 2: 1 Hz 15 mm, ...' for messages."""
    return ", ".join(f"{s.index}: {s.frequency_hz:.3g} Hz {s.amplitude_m * 1e3:.3g} mm" for s in steps)


def select_steps(steps: list[ProgrammeStep], selection: str | None, source: str) -> list[ProgrammeStep]:
    """The steps ``selection`` names (module docstring; None: all), in the programme's order, each once;
    DataError naming the file, the selection and the steps found."""
    if selection is None:
        return list(steps)
    picked = {s.index for item in selection.split(",") for s in _pick(item, steps, source)}
    return [s for s in steps if s.index in picked]
