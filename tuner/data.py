"""Measured damper-rig data: file format, reader, checks, resampling, differentiator.

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

Preprocessing (:func:`prepare`)
-------------------------------
* Stroke velocity: Savitzky-Golay differentiator (cubic least-squares fit over
  a centred window, first derivative at the centre; ``scipy.signal.savgol_filter``
  with ``deriv=1``), applied at the source sample rate. It is a symmetric FIR,
  hence zero-phase. Its gain relative to the ideal ``j 2 pi f`` is 1 - O(f^4);
  the window is the longest odd one whose gain error stays within 0.5 % (design
  margin under the 1 % requirement) for every frequency up to 20 Hz. At 1 kHz
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
"""
from __future__ import annotations

import gzip
import importlib.util
import io
import json
import re
import warnings
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import signal

FORMAT_ID = "damper-rig-dataset/1"
MANIFEST_NAME = "manifest.json"
ROLES = ("identification", "validation")
REQUIRED_COLUMNS = ("time", "stroke", "force")
MIN_SAMPLES = 100
MAX_STROKE_RANGE_M = 2.0
MIN_FORCE_PEAK_N = 1.0
MIN_SAMPLE_RATE_HZ = 10.0

TIME_UNITS = {"s": 1.0, "ms": 1e-3}
STROKE_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6}
FORCE_UNITS = {"N": 1.0, "daN": 10.0, "kN": 1e3}
TEMPERATURE_UNITS = {"degC": 0.0, "K": -273.15}  # offset to degC
MANIFEST_TEST_KEYS = ("name", "file", "role", "scenario", "sample_rate_hz")


class DataError(ValueError):
    """Measured data that cannot be used; the message names the file and the problem."""


@dataclass
class RigTest:
    """One rig test in SI units.

    time [s], stroke [m, + extension], force [N, + tension]: 1-D float arrays of
    equal length; channels: name -> array in ``channel_units[name]`` (temperature
    in degC); sample_rate [Hz]; source: file read; metadata: free extra keys.
    """

    name: str
    role: str | None
    scenario: str
    time: np.ndarray
    stroke: np.ndarray
    force: np.ndarray
    channels: dict = field(default_factory=dict)
    sample_rate: float = 0.0
    source: Path | None = None
    metadata: dict = field(default_factory=dict)
    channel_units: dict = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """Duration [s] from the first to the last sample."""
        return float(self.time[-1] - self.time[0])


# --------------------------------------------------------------------------- checks

def _unit_factor(table: dict, unit: str, what: str, source) -> float:
    if unit not in table:
        raise DataError(f"{source}: unknown {what} unit {unit!r}; accepted: {', '.join(table)}")
    return table[unit]


def _suggest(table: dict, unit: str, ok) -> str:
    """Units of ``table`` (other than ``unit``) under which ``ok(factor ratio)`` holds."""
    cands = [u for u, f in table.items() if u != unit and ok(f / table[unit])]
    return f" Is it in {' or '.join(repr(u) for u in cands)}?" if cands else ""


def check_signals(source, time, stroke, force, channels=None, *, dt_tol=0.01,
                  lines=None, units=None) -> float:
    """Check SI signals of one test; return the sample rate [Hz].

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
        bad = ~np.isfinite(x)
        if bad.any():
            i = int(np.argmax(bad))
            kind = "NaN (missing value)" if np.isnan(x[i]) else f"{x[i]} (infinite value)"
            raise DataError(f"{source}: column {name!r} is {kind} at {where(i)}")
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
        raise DataError(f"{source}: implausible sample rate {rate:.4g} Hz (< "
                        f"{MIN_SAMPLE_RATE_HZ:g} Hz) with time in {tu!r}."
                        + _suggest(TIME_UNITS, tu, lambda r: rate / r >= MIN_SAMPLE_RATE_HZ))
    su = units.get("stroke", "m")
    srange = float(np.ptp(stroke))
    if srange > MAX_STROKE_RANGE_M:
        raise DataError(f"{source}: implausible stroke range {srange:.4g} m (> "
                        f"{MAX_STROKE_RANGE_M:g} m) with stroke in {su!r}."
                        + _suggest(STROKE_UNITS, su,
                                   lambda r: 1e-4 <= srange * r <= MAX_STROKE_RANGE_M))
    fu = units.get("force", "N")
    fpeak = float(np.max(np.abs(force)))
    if fpeak < MIN_FORCE_PEAK_N:
        raise DataError(f"{source}: implausible force: peak |force| {fpeak:.4g} N (< "
                        f"{MIN_FORCE_PEAK_N:g} N) with force in {fu!r}."
                        + _suggest(FORCE_UNITS, fu, lambda r: fpeak * r >= MIN_FORCE_PEAK_N)
                        + " Or the load signal is missing.")
    return rate


# --------------------------------------------------------------------------- reading

def _read_csv(path: Path, source: str):
    opener = gzip.open if path.name.lower().endswith(".gz") else open
    try:
        with opener(path, "rt", encoding="utf-8-sig", newline="") as fh:
            raw = fh.read().splitlines()
    except (OSError, UnicodeDecodeError, EOFError) as exc:
        raise DataError(f"{source}: cannot read file: {exc}") from exc
    kept, lines = [], []
    for k, line in enumerate(raw, start=1):
        s = line.strip()
        if s and not s.startswith("#"):
            kept.append(line)
            lines.append(k)
    if not kept:
        raise DataError(f"{source}: file is empty (no header line and no data)")
    header = [c.strip() for c in kept[0].split(",")]
    if len(header) == 1 and (";" in kept[0] or "\t" in kept[0]):
        raise DataError(f"{source}: header {kept[0]!r} has a single column: "
                        f"columns must be separated by commas")
    if len(kept) == 1:
        raise DataError(f"{source}: file is empty: header {header} but no data rows")
    try:
        df = pd.read_csv(io.StringIO("\n".join(kept)), skipinitialspace=True)
    except (pd.errors.ParserError, ValueError) as exc:
        raise DataError(f"{source}: malformed CSV: {exc}") from exc
    df.columns = [str(c).strip() for c in df.columns]
    return df, lines[1:]


def _read_table(path: Path, source: str):
    """Return (DataFrame, data-row -> file-line list or None)."""
    if not path.exists():
        raise DataError(f"{source}: file not found")
    if not path.is_file():
        raise DataError(f"{source}: not a file")
    name = path.name.lower()
    if name.endswith((".parquet", ".pq")):
        if importlib.util.find_spec("pyarrow") is None:
            raise DataError(f"{source}: reading Parquet needs pyarrow "
                            f"(pip install pyarrow), or convert the file to CSV")
        if path.stat().st_size == 0:
            raise DataError(f"{source}: file is empty")
        try:
            df = pd.read_parquet(path)
        except Exception as exc:  # pyarrow raises several exception types
            raise DataError(f"{source}: cannot read Parquet: {exc}") from exc
        if len(df) == 0:
            raise DataError(f"{source}: file is empty: columns {list(df.columns)} but no rows")
        df.columns = [str(c).strip() for c in df.columns]
        return df, None
    if name.endswith((".csv", ".csv.gz")):
        return _read_csv(path, source)
    raise DataError(f"{source}: unsupported file type; use .csv, .csv.gz or .parquet")


def _numeric(df: pd.DataFrame, col: str, source: str, lines) -> np.ndarray:
    s = df[col]
    if s.dtype.kind in "fiu":
        return s.to_numpy(dtype=float)
    num = pd.to_numeric(s, errors="coerce")
    bad = num.isna() & s.notna()
    if s.dtype.kind == "b":
        bad[:] = True
    if bad.any():
        i = int(np.argmax(bad.to_numpy()))
        line = f" (line {lines[i]})" if lines is not None else ""
        raise DataError(f"{source}: non-numeric value {s.iloc[i]!r} in column {col!r} "
                        f"at data row {i + 1}{line}")
    return num.to_numpy(dtype=float)


def load_test(path, *, time_col="time", stroke_col="stroke", force_col="force",
              stroke_unit="m", force_unit="N", time_unit="s", extra_cols=None,
              channel_units=None, name=None, role=None, scenario=None,
              sample_rate_hz=None, metadata=None, dt_tol=0.01, temperature_col=None,
              temperature_unit="degC") -> RigTest:
    """Read and check one rig-test file; return it in SI units.

    Column names and units (time s/ms, stroke m/cm/mm/um, force N/daN/kN) are
    those of the file. ``extra_cols``: channel columns to load (None: every
    other column). ``channel_units``: channel -> unit (``temperature`` defaults
    to degC; degC/K are converted to degC, other units are kept as given).
    ``sample_rate_hz`` [Hz], if given, must match the time column within
    ``dt_tol``. name defaults to the file stem; role (identification/validation
    or None) and scenario are labels. ``temperature_col``: the column holding the
    oil temperature (in ``temperature_unit``, degC or K), loaded as the channel
    ``temperature`` that the thermal drift element and the diagnosis use; without
    it a column named ``temperature`` is that channel, and another column that
    looks like a temperature is reported in ``metadata['warnings']``. Raises
    DataError on any problem.
    """
    path = Path(path)
    source = str(path)
    tf = _unit_factor(TIME_UNITS, time_unit, "time", source)
    sf = _unit_factor(STROKE_UNITS, stroke_unit, "stroke", source)
    ff = _unit_factor(FORCE_UNITS, force_unit, "force", source)
    if role is not None and role not in ROLES:
        raise DataError(f"{source}: unknown role {role!r}; expected one of {ROLES}")
    df, lines = _read_table(path, source)
    found = list(df.columns)
    warnings = []
    if temperature_col is not None:
        if temperature_col not in found:
            raise DataError(f"{source}: temperature column {temperature_col!r} not found; columns found: {found}")
        if temperature_col != "temperature":
            if "temperature" in found:
                raise DataError(f"{source}: --temperature-col {temperature_col!r} given but the file also has a "
                                f"column 'temperature': rename one of them")
            df = df.rename(columns={temperature_col: "temperature"})
            found = list(df.columns)
        channel_units = {**(channel_units or {}), "temperature": temperature_unit}
    elif "temperature" not in found:
        looks = [c for c in found if c not in (time_col, stroke_col, force_col)
                 and re.search(r"temp|oil|°c|degc|\(c\)|\[c\]", c, flags=re.IGNORECASE)]
        if looks:
            warnings.append(f"{source}: column(s) {looks} look like a temperature but are not used as the oil "
                            f"temperature; give --temperature-col NAME to use one (the thermal analysis needs it)")
    wanted = [time_col, stroke_col, force_col]
    if extra_cols is None:
        extra_cols = [c for c in found if c not in wanted]
    missing = [c for c in [*wanted, *extra_cols] if c not in found]
    if missing:
        raise DataError(f"{source}: missing column(s) {missing}; columns found: {found}")
    if len(df) == 0:
        raise DataError(f"{source}: file is empty: header {found} but no data rows")
    units_in = {**({"temperature": "degC"}), **(channel_units or {})}
    t = _numeric(df, time_col, source, lines) * tf
    x = _numeric(df, stroke_col, source, lines) * sf
    f = _numeric(df, force_col, source, lines) * ff
    channels, ch_units = {}, {}
    for c in extra_cols:
        v = _numeric(df, c, source, lines)
        u = units_in.get(c, "")
        if c == "temperature" or u in TEMPERATURE_UNITS:
            v = v + _unit_factor(TEMPERATURE_UNITS, u, f"{c!r}", source)
            u = "degC"
        channels[c], ch_units[c] = v, u
    rate = check_signals(source, t, x, f, channels, dt_tol=dt_tol, lines=lines,
                         units={"time": time_unit, "stroke": stroke_unit, "force": force_unit})
    if sample_rate_hz is not None and abs(rate / float(sample_rate_hz) - 1.0) > dt_tol:
        raise DataError(f"{source}: time column gives {rate:.6g} Hz but the manifest "
                        f"says sample_rate_hz = {sample_rate_hz}")
    stem = re.sub(r"\.(csv|csv\.gz|parquet|pq)$", "", path.name, flags=re.IGNORECASE)
    return RigTest(name=name or stem, role=role,
                   scenario="" if scenario is None else str(scenario),
                   time=t, stroke=x, force=f, channels=channels,
                   sample_rate=float(sample_rate_hz) if sample_rate_hz else rate,
                   source=path, metadata={**dict(metadata or {}), **({"warnings": warnings} if warnings else {})},
                   channel_units=ch_units)


def load_files(paths, role, **column_options) -> list[RigTest]:
    """Read loose files (no manifest), all with ``role``; options as in :func:`load_test`."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
    return [load_test(p, role=role, **column_options) for p in paths]


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


def load_dataset(folder, *, dt_tol=0.01) -> list[RigTest]:
    """Read every test of a dataset folder (manifest order) in SI units. Raises DataError."""
    folder = Path(folder)
    man = read_manifest(folder)
    units = man.get("units", {})
    known = {"time", "stroke", "force"}
    out = []
    for e in man["tests"]:
        out.append(load_test(
            folder / e["file"], stroke_unit=units.get("stroke", "m"),
            force_unit=units.get("force", "N"), time_unit=units.get("time", "s"),
            channel_units={k: v for k, v in units.items() if k not in known},
            name=e["name"], role=e["role"], scenario=e["scenario"],
            sample_rate_hz=e["sample_rate_hz"], dt_tol=dt_tol,
            metadata={k: v for k, v in e.items() if k not in MANIFEST_TEST_KEYS}))
    return out


# --------------------------------------------------------------------------- differentiator

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


# --------------------------------------------------------------------------- resampling

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

    @classmethod
    def design(cls, rate_in: float, rate_out: float, attenuation_db: float = 60.0,
               max_denominator: int = 1000) -> "Resampler":
        """FIR flat to 0.8 x and >= attenuation_db from 1.0 x the lower Nyquist [Hz]."""
        if not rate_in > 0 or not rate_out > 0:
            raise ValueError(f"sample rates must be positive, got {rate_in} -> {rate_out} Hz")
        ratio = Fraction(rate_out / rate_in).limit_denominator(max_denominator)
        if ratio == 0 or abs(float(ratio) * rate_in / rate_out - 1.0) > 1e-6:
            raise ValueError(f"cannot resample {rate_in:g} Hz to {rate_out:g} Hz with a ratio "
                             f"of integers <= {max_denominator}")
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
    differentiator and resampler (None when not resampled) document the processing.
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

    def describe(self) -> str:
        """Plain-text statement of the preprocessing, for the report."""
        res = (self.resampler.describe() if self.resampler is not None
               else f"not resampled (fit rate = sample rate = {self.sample_rate:g} Hz)")
        return (f"Test {self.name!r}: {len(self.time)} samples at {self.sample_rate:g} Hz. "
                f"Stroke velocity from the stroke at {self.source_rate:g} Hz by a "
                f"{self.differentiator.describe()}. All channels {res}.")


def prepare(test: RigTest, fit_rate_hz: float, *, diff_band_hz: float = 20.0,
            diff_tol: float = 0.005) -> PreparedTest:
    """Differentiate the stroke and resample every channel to ``fit_rate_hz`` [Hz].

    The velocity [m/s] is computed at the source rate (see module docstring),
    then stroke, velocity, force and channels pass through the same resampler,
    which drops the incomplete filter outputs at both ends (so ``time[0]`` may
    be later than the test's first sample). Raises DataError when fewer than
    100 samples would remain, ValueError for a fit rate that is not a ratio of
    small integers of the sample rate.
    """
    rate = float(test.sample_rate)
    fit_rate_hz = float(fit_rate_hz)
    if not fit_rate_hz > 0:
        raise ValueError(f"fit_rate_hz must be positive, got {fit_rate_hz}")
    diff = Differentiator.design(rate, diff_band_hz, diff_tol, max_window=len(test.stroke))
    vel = diff.apply(test.stroke)
    if abs(fit_rate_hz / rate - 1.0) <= 1e-9:
        return PreparedTest(test.name, test.role, test.scenario, test.time.copy(),
                            test.stroke.copy(), vel, test.force.copy(),
                            {k: v.copy() for k, v in test.channels.items()}, rate, rate,
                            diff, None, dict(test.metadata), dict(test.channel_units),
                            test.source)
    rs = Resampler.design(rate, fit_rate_hz)
    if rs.output_length(len(test.time)) < MIN_SAMPLES:
        raise DataError(f"{test.source or test.name}: too short to resample {rate:g} Hz -> "
                        f"{rs.rate_out:g} Hz: fewer than {MIN_SAMPLES} samples remain after "
                        f"dropping {1e3 * rs.trim_s:.0f} ms of filter edge at each end")
    stroke = rs.apply(test.stroke)
    time = test.time[0] + (rs.first_index() + np.arange(len(stroke))) / rs.rate_out
    return PreparedTest(test.name, test.role, test.scenario, time, stroke, rs.apply(vel),
                        rs.apply(test.force), {k: rs.apply(v) for k, v in test.channels.items()},
                        rs.rate_out, rate, diff, rs, dict(test.metadata),
                        dict(test.channel_units), test.source)
