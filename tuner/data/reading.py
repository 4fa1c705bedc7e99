"""Measured damper-rig data: the reader (which column is which, units to SI, signs, one test or several).

Reads files as rigs write them (``tuner.data.rigfile`` picks the format's reader) and datasets in the
format of ``damper_dataset.format`` (the one definition, shared with the campaign's writer), converts to
SI and checks that the data is physically a damper on a rig (``tuner.data.plausibility``); the time base
is repaired and checked in ``tuner.data.time_base``, a test programme cut in ``tuner.data.programme``.

The options of a read travel in one record, ``ReadOptions`` (``tuner.data.read_options``, with the column
mapping file). Preprocessing (resampling, ``prepare``): ``tuner.data.preprocess``; the stroke differentiator:
``tuner.data.differentiator``.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from damper_dataset.format import (FORCE_UNITS, FORMAT_ID, MANIFEST_TEST_KEYS, ROLES, STROKE_UNITS, TIME_UNITS,
                                   DataError, check_finite, check_signals, read_manifest)
from tuner.data.calibration import apply as calibrate, calibration, force_zero as tare_force
from tuner.data.prefilter import parse_prefilter
from tuner.data.programme import cut_programme, select_steps
# the record of the reader's options and the mapping file, also reachable here (the reader's API in one module)
from tuner.data.read_options import (COLUMN_OPTIONS, DEFAULT_DAMPER_CLASS, READ_OPTIONS, ReadOptions,  # noqa: F401
                                     read_column_mapping)
from tuner.data.rigfile import RawTable, read_raw
# the plausibility checks, also reachable here (the reader's API in one module)
from tuner.data.plausibility import (DAMPER_CLASSES, RAILWAY_DAMPER_CLASSES, class_warning,  # noqa: F401
                                     plausibility)
from tuner.data.stamps import check_date_order, is_stamp, stamp_seconds
from tuner.data.time_base import declared_rates, rate_check, regularise
from tuner.data.units import FORCE, STROKE, TEMPERATURE as TEMPERATURE_UNITS, TIME, VELOCITY, us_conversions


@dataclass
class RigTest:
    """One rig test in SI units.

    time [s], stroke [m, + extension], force [N, + tension]: 1-D float arrays of
    equal length; channels: name -> array in ``channel_units[name]`` (temperature
    in degC); sample_rate [Hz]; source: file read; metadata: free extra keys;
    velocity: measured stroke velocity [m/s, + extension] when the rig has one, else None
    (the stroke is differentiated).
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
    velocity: np.ndarray | None = None

    @property
    def duration(self) -> float:
        """Duration [s] from the first to the last sample."""
        return float(self.time[-1] - self.time[0])


# --------------------------------------------------------------------------- checks

def _unit_factor(table: dict, unit: str, what: str, source) -> float:
    if unit not in table:
        raise DataError(f"{source}: unknown {what} unit {unit!r}; accepted: {', '.join(table)}")
    return table[unit]



# --------------------------------------------------------------------------- reading

def _numeric(raw: RawTable, col: str, source: str) -> np.ndarray:
    s = raw.frame[col]
    if s.dtype.kind in "fiu":
        return s.to_numpy(dtype=float)
    if s.dtype.kind == "b":
        raise DataError(f"{source}: column {col!r} holds booleans, not numbers")
    num = pd.to_numeric(s, errors="coerce")
    text = s.astype(str).str.strip().str.lower()
    bad = num.isna() & s.notna() & ~text.isin(["", "nan", "na", "n/a", "null"])
    if bad.any():
        i = int(np.argmax(bad.to_numpy()))
        line = f" (line {raw.lines[i]})" if raw.lines is not None else ""
        raise DataError(f"{source}: non-numeric value {s.iloc[i]!r} in column {col!r} "
                        f"at data row {i + 1}{line}")
    return num.to_numpy(dtype=float)


def _time_seconds(raw: RawTable, col: str, unit: str, source: str, date_order=None) -> tuple[np.ndarray, str, dict]:
    """Time column in seconds, its kind: ``'seconds'`` (numbers in ``unit``) or ``'timestamp'``
    (date-time stamps, seconds from the first), and what the stamps were read as (``date_order``,
    ``stamps``: :func:`tuner.data.stamps.stamp_seconds`; empty for numbers). ``date_order``: ``'mdy'``,
    ``'dmy'`` or None (from the data)."""
    s = raw.frame[col]
    if s.dtype.kind in "fiu" or pd.to_numeric(s.iloc[:20], errors="coerce").notna().any():
        return _numeric(raw, col, source) * _unit_factor(TIME, unit, "time", source), "seconds", {}
    if s.dtype.kind != "M" and is_stamp(s.iloc[0]):  # a date and a clock time, as loggers write them
        t, how = stamp_seconds(s, date_order, source, col, raw.lines)
        return t, "timestamp", how
    if s.dtype.kind == "M":
        stamps = pd.Series(s)
    else:  # ISO stamps with a time zone, month names ...
        try:
            stamps = pd.to_datetime(s, format="ISO8601", errors="raise")
        except (ValueError, TypeError):
            stamps = pd.to_datetime(s, errors="coerce", format="mixed", dayfirst=date_order == "dmy")
    bad = stamps.isna().to_numpy()
    if bad.any():
        i = int(np.argmax(bad))
        line = f" (line {raw.lines[i]})" if raw.lines is not None else ""
        raise DataError(f"{source}: time column {col!r} is neither numbers nor timestamps: "
                        f"{s.iloc[i]!r} at data row {i + 1}{line}")
    if getattr(stamps.dt, "tz", None) is not None:
        stamps = stamps.dt.tz_convert("UTC")
    ns = stamps.to_numpy(dtype="datetime64[ns]").astype(np.int64)
    return (ns - ns[0]) * 1e-9, "timestamp", {}




def _unit(given, declared, default: str, what: str, column: str, source: str, option: str) -> str:
    """The unit to use: the one given (option) or declared in the file, which must agree."""
    if given is not None and declared is not None and given != declared:
        raise DataError(f"{source}: column {column!r} declares {declared!r} but {option} {given!r} was given; "
                        f"drop {option} or correct the header")
    return given or declared or default


def _temperature_column(raw: RawTable, use: dict, source: str, warn: list) -> str | None:
    """The oil temperature column when none is named: the one called 'temperature' in degC or K (or in
    no declared unit); one in another unit (a thermocouple's volts) stays a channel, with a warning."""
    found = list(raw.frame.columns)
    named = [c for c in found if c not in use.values() and "temperature" in (raw.names[c].lower(), c.lower())]
    in_temperature = [c for c in named if not raw.units.get(c) or raw.units[c] in TEMPERATURE_UNITS]
    for col in named if not in_temperature else ():
        declared = raw.units.get(col)
        if declared and declared not in TEMPERATURE_UNITS:  # e.g. a thermocouple's raw volts
            warn.append(f"{source}: column {col!r} is in {declared!r}, not a temperature unit "
                        f"({', '.join(TEMPERATURE_UNITS)}): kept as a plain channel, not as the oil "
                        f"temperature; give --temperature-col with a column in degC or K to use one")
    if len(in_temperature) > 1:
        raise DataError(f"{source}: temperature column 'temperature' is ambiguous: {in_temperature}; "
                        f"name the oil temperature with --temperature-col (the full header)")
    return in_temperature[0] if in_temperature else None  # 'Temperature (V)' beside it is a channel


#: the column options' defaults (``ReadOptions``): role -> column name
_DEFAULT_COLUMNS = ReadOptions().columns


def _format_names(raw: RawTable, names: dict) -> dict:
    """Role -> the column option, where one left at its default (``force``) names no column of the file but
    the format names one for that role (an MTS export's ``Load``: ``RawTable.defaults``) taken as that."""
    low = {c.lower() for c in raw.frame.columns} | {raw.names[c].lower() for c in raw.frame.columns}
    out = dict(names)
    for role, col in raw.defaults.items():
        if names.get(role) == _DEFAULT_COLUMNS[role] and str(names[role]).lower() not in low:
            out[role] = col
    return out


def _pick_columns(raw: RawTable, source: str, opts: ReadOptions) -> tuple:
    """Which column is which (``opts.columns``: role -> the ``*_col`` option; ``opts.rate_hz``,
    ``opts.extra_cols``). Returns (use: role -> column, no_time, extra columns to read, whether they were
    asked for, unused columns, warnings). Raises DataError naming the option for a missing column."""
    found = list(raw.frame.columns)
    warn = list(raw.info.get("warnings", []))
    names, rate_hz, extra_cols = _format_names(raw, opts.columns), opts.rate_hz, opts.extra_cols
    time_col = names["time"]
    no_time = time_col is None or (rate_hz is not None and time_col == "time" and "time" not in found
                                   and not any(raw.names[c].lower() == "time" for c in found))
    use = {} if no_time else {"time": raw.find(time_col, "time", source)}
    use["stroke"] = raw.find(names["stroke"], "stroke", source)
    use["force"] = raw.find(names["force"], "force", source)
    if names["velocity"] is not None:
        use["velocity"] = raw.find(names["velocity"], "velocity", source)
    if names["temperature"] is not None:
        use["temperature"] = raw.find(names["temperature"], "temperature", source)
    elif extra_cols is None or "temperature" in extra_cols:
        col = _temperature_column(raw, use, source, warn)
        if col is not None:
            use["temperature"] = col
    if names["test"] is not None:
        use["test"] = raw.find(names["test"], "test id", source)
    if len(set(use.values())) != len(use):
        raise DataError(f"{source}: one column is used for two channels: {use}")
    rest = [c for c in found if c not in use.values()]
    if "temperature" not in use:
        looks = [c for c in rest if re.search(r"temp|oil|°c|degc|\(c\)|\[c\]", c, flags=re.IGNORECASE)]
        if looks:
            warn.append(f"{source}: column(s) {looks} look like a temperature but are not used as the oil "
                        f"temperature; give --temperature-col NAME to use one (the thermal analysis needs it)")
    asked_extra = extra_cols is not None
    if extra_cols is None:
        extra_cols = rest
    elif "temperature" in use:
        extra_cols = [c for c in extra_cols if c not in ("temperature", use["temperature"])]
    missing = [c for c in extra_cols if c not in found]
    if missing:
        raise DataError(f"{source}: missing column(s) {missing}; columns found: {found}")
    return use, no_time, extra_cols, asked_extra, rest, warn


def _signals(raw: RawTable, use: dict, source: str, opts: ReadOptions, cal: dict) -> tuple:
    """Stroke [m, + extension], force [N, + tension], the measured velocity [m/s] and the oil
    temperature [degC] of the columns in ``use``, in SI with our signs. ``opts.units``: role -> unit
    option (None: as the file declares, else SI); ``opts.signs``: stroke and force sign (+1/-1);
    ``opts.channel_units``: the temperature's unit when not given otherwise; ``cal``: channel ->
    scale and offset (:func:`tuner.data.calibration.calibration`): scale x raw + offset is in the
    channel's unit, and with a scale the unit a column declares is the raw one (not used). Returns
    (columns by role, the temperature as ``'ch:temperature'``, the raw values of calibrated channels
    as ``'raw:NAME'``; units read)."""
    cols, units, raws = {}, {}, {}
    given, signs, channel_units = opts.units, opts.signs, opts.channel_units
    for what, table, default in (("stroke", STROKE, "m"), ("force", FORCE, "N"),
                                 ("velocity", VELOCITY, None)):
        if what not in use:
            continue
        c = cal.get(what)
        declared = raw.units.get(use[what]) if c is None or c["scale"] is None else None
        units[what] = _unit(given[what], declared, default or units["stroke"] + "/s", what, use[what], source,
                            f"--{what}-unit")
        x = _numeric(raw, use[what], source)
        if c is not None:
            raws[f"raw:{what}"], x = x, calibrate(x, c)
        sign = signs["stroke" if what == "velocity" else what]
        cols[what] = sign * x * _unit_factor(table, units[what], what, source)
    if "temperature" in use:
        tu = _unit(given["temperature"] or (channel_units or {}).get("temperature"),
                   raw.units.get(use["temperature"]), "degC", "temperature", use["temperature"], source,
                   "--temperature-unit")
        cols["ch:temperature"] = _numeric(raw, use["temperature"], source) + _unit_factor(
            TEMPERATURE_UNITS, tu, "temperature", source)
        units["temperature"] = tu
    return {**cols, **raws}, units




def _time_base(raw: RawTable, use: dict, no_time: bool, opts: ReadOptions, source: str) -> tuple:
    """(time [s] of every row, what it came from, the time unit read or None, how stamps were read).
    Without a time column: ``opts.rate_hz`` [Hz], else the rate the preamble declares; with one, in
    ``opts.time_unit`` (or as declared) or date-time stamps in ``opts.date_order``."""
    rate_hz = opts.rate_hz
    if no_time:
        declared = declared_rates(raw.preamble)
        if rate_hz is None and declared:
            key, hz = declared[0]
            return (np.arange(len(raw.frame)) / hz, f"none: samples at {hz:g} Hz, as the preamble declares "
                                                    f"('{key}: {raw.preamble[key]}')", None, {})
        if rate_hz is None or not float(rate_hz) > 0:
            raise DataError(f"{source}: no time column: give the sample rate with --rate HZ")
        return np.arange(len(raw.frame)) / float(rate_hz), f"none: samples at --rate {float(rate_hz):g} Hz", None, {}
    unit = _unit(opts.time_unit, raw.units.get(use["time"]), "s", "time", use["time"], source, "--time-unit")
    t, kind, how = _time_seconds(raw, use["time"], unit, source, opts.date_order)
    return t, kind, "timestamp" if kind == "timestamp" else unit, how


def _text_only(raw: RawTable, col: str) -> str | None:
    """What a column holding only text (a logger's 'Events') holds, e.g. ``"'DAQ Start', 'DAQ Pause' on
    2 of 48000 rows"``; None for a column with a number or with nothing in it."""
    s = raw.frame[col]
    if s.dtype.kind != "O":
        return None
    cells = s.dropna().astype(str).str.strip()
    cells = cells[cells != ""]
    if cells.empty or pd.to_numeric(cells, errors="coerce").notna().any():
        return None
    kinds = list(dict.fromkeys(cells))
    shown = ", ".join(repr(v) for v in kinds[:3]) + (" ..." if len(kinds) > 3 else "")
    return f"{shown} on {len(cells)} of {len(s)} rows"


def _extra_channels(raw: RawTable, extra_cols, asked_extra: bool, channel_units, source: str,
                    warn: list) -> tuple:
    """The other columns as channels in the unit each declares (temperatures in degC). Returns
    (``'ch:NAME'`` -> values, NAME -> unit, columns left out, text columns left out: NAME -> what they
    hold); warnings are appended to ``warn``. A column nobody asked for holding only text (a logger's
    'Events') is left out with a note; one that cannot be read (a constant written once, an empty
    trailing column) with a warning; a column asked for must be readable (DataError)."""
    cols, ch_units, dropped, text = {}, {}, [], {}
    given_ch = channel_units or {}
    for c in extra_cols:
        held = None if asked_extra else _text_only(raw, c)
        if held is not None:
            text[c] = held
            dropped.append(c)
            continue
        try:
            v = _numeric(raw, c, source)
            if not asked_extra:
                check_finite(source, c, v, raw.lines)
        except DataError as err:
            if asked_extra:  # a channel the user asked for must be readable
                raise
            warn.append(f"{source}: column {c!r} not read ({str(err).removeprefix(source + ': ')}); only the "
                        f"columns in use and complete extra ones are kept")
            dropped.append(c)
            continue
        # the unit this column declares: 'Force (V)' beside 'Force (N)' is in V (by its own header, not by
        # the name they share)
        u = given_ch.get(c) or raw.units.get(c) or given_ch.get(raw.names[c]) or ""
        if u in TEMPERATURE_UNITS:
            v = v + TEMPERATURE_UNITS[u]
            u = "degC"
        cols[f"ch:{c}"], ch_units[c] = v, u
    return cols, ch_units, dropped, text


def _segment(tg: np.ndarray, cg: dict, lines, t_start, t_end, regularised: bool) -> tuple:
    """The samples between ``t_start`` and ``t_end`` [s from the first sample] (None: no limit)."""
    sel = np.ones(len(tg), dtype=bool)
    if t_start is not None:
        sel &= tg >= t_start
    if t_end is not None:
        sel &= tg <= t_end
    if sel.all():
        return tg, cg, lines
    lines = None if lines is None or regularised else [ln for ln, k in zip(lines, sel) if k]
    return tg[sel], {k: v[sel] for k, v in cg.items()}, lines


def _one_test_signals(label: str, t: np.ndarray, cols: dict, rows: np.ndarray, lines, opts: ReadOptions) -> tuple:
    """One test's ``rows`` of the file's time [s] and columns (``lines``: the file line of each row, or
    None): NaN/inf refused (named before any resampling), the time base regularised from 0
    (:func:`tuner.data.time_base.regularise`, within ``opts.dt_tol``), the force tared over its first
    ``opts.force_zero`` seconds (None: not; :func:`tuner.data.calibration.force_zero`), the segment ``opts.t_start`` to
    ``opts.t_end`` [s] selected. Returns (time [s], columns, file lines, regularisation note, tare)."""
    lines = None if lines is None else [lines[i] for i in rows]
    t, cols = t[rows] - t[rows][0], {k: v[rows] for k, v in cols.items()}
    for k, v in cols.items():
        check_finite(label, k.removeprefix("ch:"), v, lines)
    t, cols, note = regularise(label, t, cols, opts.dt_tol, lines)
    zero = None
    if opts.force_zero is not None:
        cols["force"], zero = tare_force(label, t, cols["force"], cols["stroke"], opts.force_zero)
    t, cols, lines = _segment(t, cols, lines, opts.t_start, opts.t_end, note is not None)
    return t, cols, lines, note, zero


def _calibration_read(cal: dict, use: dict, raw: RawTable, units: dict, cols: dict) -> dict | None:
    """Per calibrated channel: column, scale, offset, engineering unit, the unit the file declares (the
    raw one), and the raw and scaled ranges of one test (``cols`` holds its ``'raw:NAME'`` values)."""
    out = {}
    for what, c in cal.items():
        x = cols[f"raw:{what}"]
        lo, hi = float(np.min(x)), float(np.max(x))
        k, b = (1.0 if c["scale"] is None else c["scale"]), (c["offset"] or 0.0)
        out[what] = {"column": use[what], "scale": c["scale"], "offset": c["offset"], "unit": units[what],
                     "raw_unit": raw.units.get(use[what]) or "", "raw_range": [lo, hi],
                     "scaled_range": [k * lo + b, k * hi + b]}
    return out or None


def _checked_options(source: str, opts: ReadOptions) -> dict:
    """DataError naming the option for a bad role, sign, date order or calibration; returns the
    calibration (:func:`tuner.data.calibration.calibration`)."""
    if opts.role is not None and opts.role not in ROLES:
        raise DataError(f"{source}: unknown role {opts.role!r}; expected one of {ROLES}")
    for what, sign in opts.signs.items():
        if sign not in (1, -1):
            raise DataError(f"{source}: {what}_sign must be +1 or -1, got {sign!r}")
    check_date_order(opts.date_order, source)
    cal = calibration(opts.calibration, source)
    if "velocity" in cal and opts.velocity_col is None:
        raise DataError(f"{source}: --velocity-scale/--velocity-offset given without a velocity column: "
                        f"name it with --velocity-col")
    return cal


def _test_checks(label: str, t, cols: dict, channels: dict, lines, units: dict, preamble: dict,
                 opts: ReadOptions) -> tuple[float, dict, list]:
    """The checks of one test in SI: its signals (``check_signals``, within ``opts.dt_tol``), the manifest's
    (``opts.sample_rate_hz`` [Hz]) and the preamble's sample rate, and, when ``opts.check_plausible``,
    plausibility and the damper class. Returns (the sample rate [Hz], {'declared_rate', 'plausibility'},
    warnings)."""
    dt_tol, sample_rate_hz = opts.dt_tol, opts.sample_rate_hz
    rate = check_signals(label, t, cols["stroke"], cols["force"], channels, dt_tol=dt_tol, lines=lines, units=units)
    if sample_rate_hz is not None and abs(rate / float(sample_rate_hz) - 1.0) > dt_tol:
        raise DataError(f"{label}: time column gives {rate:.6g} Hz but the manifest "
                        f"says sample_rate_hz = {sample_rate_hz}")
    declared, rate_note = rate_check(label, preamble, rate, dt_tol)
    read_checks, class_note = None, None
    damper_class = opts.damper_class if opts.check_plausible else None
    if damper_class is not None:
        read_checks = plausibility(label, t, cols["stroke"], cols["force"], cols.get("velocity"), rate, units)
        class_note = class_warning(label, read_checks, damper_class, units)
    return rate, {"declared_rate": declared, "plausibility": read_checks}, [w for w in (rate_note, class_note) if w]


def _groups(raw: RawTable, use: dict) -> list:
    """(test id or None, row indices) of each test in the file: one per value of the test-id column, else one
    per continuous piece when the file's time base breaks (``RawTable.pieces``: ids ``part1``, ``part2`` ...)."""
    if "test" not in use and raw.pieces:  # a time base broken in the file (an MTS export missing a block)
        ends = [*raw.pieces[1:], len(raw.frame)]
        return [(f"part{k + 1}", np.arange(a, b)) for k, (a, b) in enumerate(zip(raw.pieces, ends))]
    if "test" not in use:
        return [(None, np.arange(len(raw.frame)))]
    ids = raw.frame[use["test"]].astype(str).to_numpy()
    return [(g, np.flatnonzero(ids == g)) for g in dict.fromkeys(ids)]


def _programme_groups(groups: list, t: np.ndarray, stroke: np.ndarray, source: str, selection) -> tuple[list, dict]:
    """Each group's (:func:`_groups`) steps of a test programme (:func:`tuner.data.programme.cut_programme` on
    its time [s] and stroke [m]) that ``selection`` picks (``select_steps``; None: all): (test id, rows) per
    step and test id -> ``ProgrammeStep``."""
    out, steps = [], {}
    for gid, rows in groups:
        label = source if gid is None else f"{source} [{gid}]"
        for step in select_steps(cut_programme(t[rows], stroke[rows], label), selection, label):
            sid = step.label if gid is None else f"{gid}-{step.label}"
            out.append((sid, rows[step.rows[0]:step.rows[1]]))
            steps[sid] = step
    return out, steps


def load_tests(path, options: ReadOptions | None = None, **changes) -> list[RigTest]:
    """Read one rig file with ``options`` (``ReadOptions``; None: the defaults) and return its test(s) in SI
    units, one per value of ``options.test_col``. ``changes``: single options by keyword, over ``options``
    (``load_tests(path, stroke_unit="mm")``); TypeError naming an unknown one.

    What the options mean: ``ReadOptions``. In short: a column is found by header, header without unit or
    1-based position; without a time column the samples are at ``rate_hz`` [Hz] (else the rate a logger's
    preamble declares); time may be numbers or date-time stamps (:mod:`tuner.data.stamps`); units are given
    or declared in the file (both must agree), else SI; ``velocity_col`` is used instead of differentiating
    the stroke; the oil temperature is channel ``temperature`` [degC] (without ``temperature_col`` the
    column named ``temperature`` in degC or K, or in no declared unit -- ``Temperature (V)`` beside
    ``Temperature (degC)`` stays a channel in V -- and another column that looks like a temperature gives a
    warning). Every other channel keeps the unit its own header declares; a text-only column (a logger's
    'Events') is left out with a note. Calibration: engineering value = scale x raw + offset, the force tared
    over its first ``force_zero`` [s] (:mod:`tuner.data.calibration`); ``prefilter`` (the lab's filter,
    :mod:`tuner.data.prefilter`) is recorded in ``metadata['read']['prefilter']``: the simulated force passes
    it before every comparison. Duplicated or irregular stamps are regularised with a warning (see
    :func:`tuner.data.time_base.regularise`); ``t_start``/``t_end`` [s from the first sample] select a
    segment. ``check_plausible``: refuse physically implausible strokes/forces (:func:`plausibility`);
    ``damper_class``: warn when the apparent damping is outside that class's range (:func:`class_warning`).
    The format's reader is picked by :func:`tuner.data.rigfile.read_raw` (an MTS 793 export's ``Load`` is
    the force; a missing block splits it into tests ``NAME-part1`` ...); ``programme``/``steps``: one test
    per step of a stepped sine (:mod:`tuner.data.programme`), named ``NAME-1Hz-15mm``. What was understood goes to
    ``metadata['read']`` (with the damper class declared, checked or not), warnings to
    ``metadata['warnings']``. Raises DataError on any problem."""
    opts = ReadOptions.of(options, **changes)
    path = Path(path)
    source = str(path)
    cal = _checked_options(source, opts)
    lab_filter = parse_prefilter(opts.prefilter, f"{source}: prefilter")
    raw = read_raw(path, source, opts.header_line)
    use, no_time, extra_cols, asked_extra, rest, warn = _pick_columns(raw, source, opts)
    t, time_kind, tu, stamps = _time_base(raw, use, no_time, opts, source)
    cols, units = _signals(raw, use, source, opts, cal)
    if tu is not None:
        units["time"] = tu
    extra, ch_units, dropped, text_cols = _extra_channels(raw, extra_cols, asked_extra, opts.channel_units, source,
                                                          warn)
    cols.update(extra)
    ch_units = {"temperature": "degC", **ch_units} if "temperature" in use else ch_units
    stem = re.sub(r"\.(csv|tsv|txt|dat)(\.gz)?$|\.(parquet|pq|mat)$", "", path.name, flags=re.IGNORECASE)
    file_read = {"format": raw.kind, "format_info": {k: v for k, v in raw.info.items() if k != "warnings"} or None,
                 "converted": us_conversions(units) or None, "columns": dict(use),
                 "ignored": [c for c in rest if c not in extra_cols or c in dropped],
                 "header_line": raw.header_line, "preamble": dict(raw.preamble), "date_order": stamps.get("date_order"),
                 "stamps": stamps.get("stamps"), "text_columns": text_cols}
    out = []
    groups, steps = _groups(raw, use), {}
    if opts.programme or opts.steps is not None:
        groups, steps = _programme_groups(groups, t, cols["stroke"], source, opts.steps)
    for gid, rows in groups:
        tagged = "test" in use and not steps  # a test-id column's value, else a piece or a step
        label = source if gid is None else f"{source} [test {gid}]" if tagged else f"{source} [{gid}]"
        tg, cg, lines, note, zero = _one_test_signals(label, t, cols, rows, raw.lines, opts)
        channels = {k[3:]: v for k, v in cg.items() if k.startswith("ch:")}
        rate, checks, notes = _test_checks(label, tg, cg, channels, lines, units, raw.preamble, opts)
        read = {"channels": list(channels), "units": units, "time": time_kind, "signs": opts.signs,
                "delimiter": raw.delimiter, "decimal": raw.decimal, "regularised": note,
                "segment_s": [opts.t_start, opts.t_end] if (opts.t_start is not None or opts.t_end is not None)
                else None, **checks, **file_read, "calibration": _calibration_read(cal, use, raw, units, cg),
                "force_zero": zero, "prefilter": lab_filter.to_dict() if lab_filter else None,
                "damper_class": opts.damper_class, "step": steps[gid].to_dict() if gid in steps else None}
        warns = list(warn) + ([f"{label}: {note}"] if note else []) + notes
        out.append(RigTest(
            name=(opts.name or stem) + ("" if gid is None else f"-{gid}"), role=opts.role,
            scenario="" if opts.scenario is None else str(opts.scenario), time=tg, stroke=cg["stroke"],
            force=cg["force"], channels=channels, source=path,
            sample_rate=float(opts.sample_rate_hz) if opts.sample_rate_hz else rate,
            metadata={**dict(opts.metadata or {}), "read": read, **({"warnings": warns} if warns else {})},
            channel_units=ch_units, velocity=cg.get("velocity")))
    return out


def reading_warnings(tests: list[RigTest]) -> list[str]:
    """The warnings of reading ``tests`` (each test's ``metadata['warnings']``: units, plausibility and
    damper class, repaired clocks, declared rates, columns left out; the command line adds a force that
    looks filtered), each once, in the tests' order, and each naming its file (a warning that does not
    start with it gets the test's file, or name, in front). What the job keeps in metrics.json for the
    end summary, ``summary.json`` and the report."""
    out = []
    for t in tests:
        where = str(t.source) if t.source is not None else t.name
        for w in t.metadata.get("warnings", []):
            text = str(w) if str(w).startswith(where) else f"{where}: {w}"
            if text not in out:
                out.append(text)
    return out


def load_test(path, options: ReadOptions | None = None, **changes) -> RigTest:
    """Read a rig file holding one test (``options`` and ``changes`` as in :func:`load_tests`)."""
    tests = load_tests(path, options, **changes)
    if len(tests) != 1:
        raise DataError(f"{path}: holds {len(tests)} tests (test-id column); use load_tests")
    return tests[0]


def load_files(paths, role, options: ReadOptions | None = None, **changes) -> list[RigTest]:
    """Read loose files (no manifest), all with ``role``, each with ``options`` (``ReadOptions``) and the
    single options ``changes`` by keyword over them, as in :func:`load_tests`
    (``load_files(paths, "identification", stroke_unit="mm", force_col="Kraft")``)."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
    opts = ReadOptions.of(options, **changes).merged(role=role)
    return [t for p in paths for t in load_tests(p, opts)]


def _dataset_units(source, units: dict) -> None:
    """DataError naming the test file unless the manifest's units are the dataset format's own
    (``damper_dataset.format``: metric; the reader's US customary units are for rig files, not datasets)."""
    for what, table in (("time", TIME_UNITS), ("stroke", STROKE_UNITS), ("force", FORCE_UNITS)):
        if what in units and units[what] not in table:
            raise DataError(f"{source}: unknown {what} unit {units[what]!r} in the dataset's manifest.json; the "
                            f"format {FORMAT_ID} takes {', '.join(table)}")


def load_dataset(folder, *, dt_tol=0.01, check_plausible=True, damper_class=DEFAULT_DAMPER_CLASS) -> list[RigTest]:
    """Read every test of a dataset folder (manifest order) in SI units; ``check_plausible`` and
    ``damper_class`` as in :func:`load_tests`. Raises DataError."""
    folder = Path(folder)
    man = read_manifest(folder)
    units = man.get("units", {})
    known = {"time", "stroke", "force"}
    read = ReadOptions(stroke_unit=units.get("stroke", "m"), force_unit=units.get("force", "N"),
                       time_unit=units.get("time", "s"),
                       channel_units={k: v for k, v in units.items() if k not in known}, dt_tol=dt_tol, check_plausible=check_plausible, damper_class=damper_class)
    out = []
    for e in man["tests"]:
        _dataset_units(folder / e["file"], units)
        out.append(load_test(folder / e["file"], read.merged(
            name=e["name"], role=e["role"], scenario=e["scenario"], sample_rate_hz=e["sample_rate_hz"],
            metadata={k: v for k, v in e.items() if k not in MANIFEST_TEST_KEYS})))
    return out
