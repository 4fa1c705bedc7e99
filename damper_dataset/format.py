"""The rig dataset format, in one place: what the campaign's writer (``damper_dataset.writer``)
writes and the tuner's reader (``tuner.data.reading``) reads.

Data format ``damper-rig-dataset/1``
------------------------------------
One file per rig test. CSV (``.csv`` or gzip-compressed ``.csv.gz``, UTF-8,
comma-separated, ``.`` as decimal mark) or Parquet (``.parquet``/``.pq``, read
only when ``pyarrow`` is importable). Lines whose first non-blank character is
``#`` are comments and blank lines are ignored. The first other line is the
header. Required columns:

* ``time``   -- time [s], strictly increasing and uniformly sampled;
* ``stroke`` -- damper stroke [m], positive in extension;
* ``force``  -- damper force [N], positive in tension.

Any further column is an optional channel, e.g. ``temperature`` [degC]. Every
value must be a finite number. A test has at least 100 samples.

A dataset is a folder holding those files and ``manifest.json``::

    {"format": "damper-rig-dataset/1",
     "description": str, "created_by": str,
     "generator": {...free dict, e.g. seed and effects...},
     "units": {"time": "s", "stroke": "m", "force": "N", "temperature": "degC"},
     "tests": [{"name": str, "file": str (relative to the folder),
                "role": "identification" | "validation",
                "scenario": str, "sample_rate_hz": float,
                ...free extra keys such as "speed_kmh"...}]}

``units`` applies to every file of the dataset. Accepted units: time ``s``,
``ms``; stroke ``m``, ``cm``, ``mm``, ``um``; force ``N``, ``daN``, ``kN``;
temperature ``degC``, ``K``. Other channels keep their values and their
manifest unit string unchanged. The reader converts to SI (temperature to
degC) and checks ``sample_rate_hz`` against the file's time column.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

__all__ = ["FORMAT_ID", "MANIFEST_NAME", "ROLES", "REQUIRED_COLUMNS", "MANIFEST_TEST_KEYS", "MIN_SAMPLES",
           "MIN_SAMPLE_RATE_HZ", "TIME_UNITS", "STROKE_UNITS", "FORCE_UNITS", "VELOCITY_UNITS", "TEMPERATURE_UNITS",
           "DataError", "check_finite", "check_signals", "read_manifest", "suggest_unit"]

FORMAT_ID = "damper-rig-dataset/1"
MANIFEST_NAME = "manifest.json"
ROLES = ("identification", "validation")
REQUIRED_COLUMNS = ("time", "stroke", "force")
MIN_SAMPLES = 100
MIN_SAMPLE_RATE_HZ = 10.0
TIME_UNITS = {"s": 1.0, "ms": 1e-3}
STROKE_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6}
FORCE_UNITS = {"N": 1.0, "daN": 10.0, "kN": 1e3}
VELOCITY_UNITS = {"m/s": 1.0, "cm/s": 1e-2, "mm/s": 1e-3, "um/s": 1e-6}
TEMPERATURE_UNITS = {"degC": 0.0, "K": -273.15}  # offset to degC
MANIFEST_TEST_KEYS = ("name", "file", "role", "scenario", "sample_rate_hz")


class DataError(ValueError):
    """Measured data that cannot be used; the message names the file and the problem."""


def suggest_unit(table: dict, unit: str, ok) -> str:
    """Units of ``table`` (other than ``unit``) under which ``ok(factor ratio)`` holds."""
    cands = [u for u, f in table.items() if u != unit and ok(f / table[unit])]
    return f" Is it in {' or '.join(repr(u) for u in cands)}?" if cands else ""


def check_finite(source, name: str, x, lines=None) -> None:
    """Raise DataError naming the first NaN or infinite value of column ``name``."""
    bad = ~np.isfinite(x)
    if bad.any():
        i = int(np.argmax(bad))
        kind = "NaN (missing value)" if np.isnan(x[i]) else f"{x[i]} (infinite value)"
        line = f" (line {lines[i]})" if lines is not None and i < len(lines) else ""
        raise DataError(f"{source}: column {name!r} is {kind} at data row {i + 1}{line}")


def check_signals(source, time, stroke, force, channels=None, *, dt_tol=0.01,
                  lines=None, units=None) -> float:
    """Check SI signals of one test (length, finite values, uniform increasing time, a
    plausible sample rate); return the sample rate [Hz].

    time [s], stroke [m], force [N], channels: name -> array. ``dt_tol`` is the
    tolerated relative deviation of any time step from the nominal one.
    ``lines`` maps data rows to file lines for messages; ``units`` gives the
    units the file was read in, for unit suggestions. Raises DataError.
    """
    units = units or {}

    def where(i):
        s = f"data row {i + 1}"
        return s + (f" (line {lines[i]})" if lines is not None and i < len(lines) else "")

    n = len(time)
    if n < MIN_SAMPLES:
        raise DataError(f"{source}: too short: {n} samples, need at least {MIN_SAMPLES}")
    cols = {"time": time, "stroke": stroke, "force": force, **(channels or {})}
    for name, x in cols.items():
        if len(x) != n:
            raise DataError(f"{source}: column {name!r} has {len(x)} values, time has {n}")
        check_finite(source, name, x, lines)
    dt = np.diff(time)
    bad = dt <= 0
    if bad.any():
        i = int(np.argmax(bad)) + 1
        if dt[i - 1] == 0:
            raise DataError(f"{source}: duplicated time {time[i]:.9g} s at {where(i)} "
                            f"(same as the previous row)")
        raise DataError(f"{source}: time is not increasing: {time[i]:.9g} s at {where(i)} "
                        f"after {time[i - 1]:.9g} s")
    dt_nom = (time[-1] - time[0]) / (n - 1)
    dev = np.abs(dt / dt_nom - 1.0)
    if dev.max() > dt_tol:
        i = int(np.argmax(dev)) + 1
        raise DataError(f"{source}: irregular sampling: time step {dt[i - 1]:.6g} s before "
                        f"{where(i)} deviates {100 * dev[i - 1]:.3g} % from the nominal "
                        f"{dt_nom:.6g} s (tolerance {100 * dt_tol:.3g} %); gaps or jitter "
                        f"must be repaired (resampled) before use")
    rate = 1.0 / dt_nom
    tu = units.get("time", "s")
    if rate < MIN_SAMPLE_RATE_HZ:
        hint = (suggest_unit(TIME_UNITS, tu, lambda r: rate / r >= MIN_SAMPLE_RATE_HZ)
                if tu in TIME_UNITS else "")
        raise DataError(f"{source}: implausible sample rate {rate:.4g} Hz (< "
                        f"{MIN_SAMPLE_RATE_HZ:g} Hz) with time in {tu!r}." + hint)
    return rate


def read_manifest(folder) -> dict:
    """Read and validate ``folder/manifest.json``; return it as a dict. Raises DataError."""
    folder = Path(folder)
    mpath = folder / MANIFEST_NAME
    if not folder.is_dir():
        raise DataError(f"{folder}: dataset folder not found")
    if not mpath.is_file():
        raise DataError(f"{mpath}: manifest not found (use load_files for loose files)")
    try:
        man = json.loads(mpath.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DataError(f"{mpath}: invalid JSON: {exc}") from exc
    if not isinstance(man, dict) or man.get("format") != FORMAT_ID:
        got = man.get("format") if isinstance(man, dict) else type(man).__name__
        raise DataError(f"{mpath}: format is {got!r}, expected {FORMAT_ID!r}")
    units = man.get("units", {})
    if not isinstance(units, dict):
        raise DataError(f"{mpath}: 'units' must be an object")
    tests = man.get("tests")
    if not isinstance(tests, list) or not tests:
        raise DataError(f"{mpath}: 'tests' must be a non-empty list")
    names = set()
    for k, entry in enumerate(tests):
        label = f"{mpath}: tests[{k}]"
        if not isinstance(entry, dict):
            raise DataError(f"{label} is not an object")
        miss = [key for key in MANIFEST_TEST_KEYS if key not in entry]
        if miss:
            raise DataError(f"{label} lacks key(s) {miss}")
        label = f"{mpath}: test {entry['name']!r}"
        if entry["role"] not in ROLES:
            raise DataError(f"{label}: unknown role {entry['role']!r}; expected one of {ROLES}")
        if entry["name"] in names:
            raise DataError(f"{label}: duplicated test name")
        names.add(entry["name"])
        try:
            ok = float(entry["sample_rate_hz"]) > 0
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise DataError(f"{label}: sample_rate_hz must be a positive number")
        if not (folder / entry["file"]).is_file():
            raise DataError(f"{label}: file {entry['file']!r} listed in the manifest "
                            f"does not exist in {folder}")
    return man
