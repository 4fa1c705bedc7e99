"""A rig file's time base: stamps repaired to a regular clock, and the sample rate a logger's preamble declares
checked against the time column."""
from __future__ import annotations

import re

import numpy as np

from damper_dataset.format import DataError
from tuner.data.raw_table import split_unit

__all__ = ["regularise", "declared_rates", "rate_check"]


def regularise(source, t: np.ndarray, cols: dict, dt_tol: float, lines, gap_limit: float = 5.0):
    """Uniform time base for samples written with duplicated or irregular stamps.

    Returns (t, cols, note). Duplicated stamps: the later rows are dropped. Stamps within half a
    step of a regular clock (e.g. a 300 Hz clock stamped to the millisecond) are taken as that
    clock. Otherwise (missing samples, jitter) every column is interpolated linearly to the
    median step; a gap over ``gap_limit`` steps is refused (it would be invented data), as is
    time going backwards. ``note`` says what was done (None: nothing)."""
    def where(i):
        return f"data row {i + 1}" + (f" (line {lines[i]})" if lines is not None and i < len(lines) else "")

    dt = np.diff(t)
    back = dt < 0
    if back.any():
        i = int(np.argmax(back)) + 1
        raise DataError(f"{source}: time is not increasing: {t[i]:.9g} s at {where(i)} after {t[i - 1]:.9g} s; "
                        f"the file mixes records or its clock was reset: split it or use --t-start/--t-end")
    notes = []
    dup = np.concatenate([[False], dt == 0])
    if dup.any():
        keep = ~dup
        notes.append(f"{int(dup.sum())} duplicated time stamp(s) dropped (first at {where(int(np.argmax(dup)))})")
        t = t[keep]
        cols = {k: v[keep] for k, v in cols.items()}
        if lines is not None:
            lines = [ln for ln, k in zip(lines, keep) if k]
        dt = np.diff(t)
    if len(t) < 2:
        return t, cols, "; ".join(notes) or None
    n = len(t)
    dt_mean = (t[-1] - t[0]) / (n - 1)
    dev = np.abs(dt / dt_mean - 1.0)
    if dev.max() <= dt_tol:
        return t, cols, "; ".join(notes) or None
    k = np.arange(n)
    slope, intercept = np.polyfit(k, t - t[0], 1)  # the clock, least squares (rounded stamps)
    grid = intercept + slope * k
    if np.max(np.abs(t - t[0] - grid)) <= 0.5 * slope:
        notes.append(f"time stamps jitter up to {np.max(np.abs(t - t[0] - grid)) * 1e3:.3g} ms around a regular "
                     f"{1 / slope:.6g} Hz clock (stamp resolution): taken as that clock")
        return grid - grid[0] + t[0], cols, "; ".join(notes)
    step = float(np.median(dt))
    if dt.max() > gap_limit * step:
        i = int(np.argmax(dt)) + 1
        raise DataError(f"{source}: gap of {dt[i - 1]:.6g} s ({dt[i - 1] / step:.0f} samples) in the time "
                        f"column before {where(i)}: interpolating it would invent data; split the file "
                        f"or select a segment with --t-start/--t-end")
    m = int(np.floor((t[-1] - t[0]) / step + 1e-9)) + 1
    new_t = t[0] + step * np.arange(m)
    irregular = int(np.sum(np.abs(dt / step - 1.0) > dt_tol))
    notes.append(f"{irregular} irregular time step(s) (largest {dt.max() * 1e3:.4g} ms against "
                 f"{step * 1e3:.4g} ms): {n} samples interpolated linearly to {m} at {1 / step:.6g} Hz")
    return new_t, {k: np.interp(new_t, t, v) for k, v in cols.items()}, "; ".join(notes)

_RATE_KEYS = {"sampling rate": "Hz", "sample rate": "Hz", "sampling frequency": "Hz", "sample frequency": "Hz",
              "sampling interval": "s", "sample interval": "s", "sampling period": "s", "sample period": "s"}


def declared_rates(preamble: dict) -> list[tuple[str, float]]:
    """(key, rate [Hz]) of each sample rate or interval a logger's preamble declares: ``Sampling Rate:
    1000`` [Hz, or kHz when so written], ``Sampling Interval:  0.001`` [s, or ms/us when so written]."""
    out = []
    for key, value in preamble.items():
        name, key_unit = split_unit(key)
        kind = _RATE_KEYS.get(name.strip().lower())
        m = re.match(r"\s*(\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)\s*([a-zA-Zµ]*)", value)
        if kind is None or not m or not float(m.group(1)) > 0:
            continue
        x, unit = float(m.group(1)), (m.group(2) or key_unit or kind).lower()
        if kind == "Hz":
            out.append((key, x * (1e3 if unit == "khz" else 1.0)))
        else:
            out.append((key, 1.0 / (x * {"ms": 1e-3, "us": 1e-6, "µs": 1e-6}.get(unit, 1.0))))
    return out


def rate_check(label: str, preamble: dict, rate: float, dt_tol: float) -> tuple[dict | None, str | None]:
    """The time column's sample rate [Hz] against the rates the preamble declares: ({key: declared Hz,
    'time_column_hz', 'agrees'} or None when none is declared, a warning when one differs by more than
    ``dt_tol``)."""
    declared = declared_rates(preamble)
    if not declared:
        return None, None
    off = [(key, hz) for key, hz in declared if abs(rate / hz - 1.0) > dt_tol]
    check = {"declared_hz": dict(declared), "time_column_hz": rate, "agrees": not off}
    if not off:
        return check, None
    key, hz = off[0]
    return check, (f"{label}: the preamble declares '{key}: {preamble[key]}' ({hz:.6g} Hz) but the time column "
                   f"gives {rate:.6g} Hz; check --time-col/--time-unit, or the logger's settings")
