"""What the reader understood of each rig test: the summary ``python -m tuner inspect`` prints, and
``fit``/``diagnose`` print before they start.

Per test: file, columns used and ignored, units and signs as read, time base, sample rate,
duration, stroke/velocity/force/temperature ranges (SI and the file's units), force noise (the
estimate ``tuner.data.noise.force_noise`` chose, its method and whether it is credible), and
which part of the damping and elastic tables' range the data covers. For a data logger's file also:
the preamble before the header and the sample rate it declares against the time column, how
date-time stamps were read (day-month order and why), the raw and scaled range of each calibrated
channel, the force tare removed, and the text columns left out.
"""
from __future__ import annotations

from damper_fmu.parameters import FC_ABSCISSAE

from tuner.data import units
from tuner.data.reading import RigTest
from tuner.data.differentiator import Differentiator
from tuner.data.noise import FLATNESS, force_noise
from tuner.data.preprocess import stroke_band_hz

__all__ = ["summarize", "format_summary", "summary_text", "filter_warning"]


def summarize(test: RigTest, fit_rate_hz: float, diff_band_hz: float | None = None) -> dict:
    """Figures of one test in SI units (see module docstring); JSON-serialisable. The velocity as
    the fit will see it: measured, or differentiated with ``diff_band_hz`` [Hz] (None: the band
    ``tuner.data.preprocess.stroke_band_hz`` derives for a fit at ``fit_rate_hz`` [Hz])."""
    read = test.metadata.get("read", {})
    noise = force_noise(test, fit_rate_hz)
    if test.velocity is not None:
        v, vsrc = test.velocity, "measured (velocity column)"
    else:
        band = diff_band_hz or stroke_band_hz(test, fit_rate_hz)
        diff = Differentiator.design(test.sample_rate, band, max_window=len(test.stroke))
        half = diff.window // 2          # one-sided fits at the ends overshoot (12 % on a 35 Hz sine)
        v = diff.apply(test.stroke)[half:len(test.stroke) - half]
        vsrc = f"differentiated stroke, within 0.5 % up to {band:.4g} Hz"
    out = {
        "name": test.name, "file": str(test.source) if test.source else None, "role": test.role,
        "columns": read.get("columns", {}), "ignored_columns": read.get("ignored", []),
        "units_read": read.get("units", {}), "signs": read.get("signs", {"stroke": 1, "force": 1}),
        "time_base": read.get("time", "seconds"), "regularised": read.get("regularised"),
        "header_line": read.get("header_line"), "preamble": read.get("preamble", {}),
        "date_order": read.get("date_order"), "stamps": read.get("stamps"), "declared_rate": read.get("declared_rate"),
        "calibration": read.get("calibration"), "force_zero": read.get("force_zero"),
        "text_columns": read.get("text_columns", {}), "prefilter": read.get("prefilter"),
        "format": read.get("format"), "format_info": read.get("format_info"), "converted": read.get("converted"),
        "step": read.get("step"),
        "apparent_damping_n_s_per_m": (read.get("plausibility") or {}).get("apparent_damping_n_s_per_m"),
        "looks_filtered": _looks_filtered(noise),
        "sample_rate_hz": float(test.sample_rate), "duration_s": test.duration, "samples": int(len(test.time)),
        "stroke_m": [float(test.stroke.min()), float(test.stroke.max())],
        "velocity_m_s": [float(v.min()), float(v.max())], "velocity_source": vsrc,
        "force_n": [float(test.force.min()), float(test.force.max())],
        "force_noise_n": noise["value_n"],
        "force_noise": {k: noise[k] for k in ("value_n", "in_band_n", "fit_rate_hz", "method", "credible", "reasons")},
        "channels": {k: [float(x.min()), float(x.max()), test.channel_units.get(k, "")]
                     for k, x in test.channels.items()},
        "warnings": list(test.metadata.get("warnings", [])),
    }
    vmax = max(abs(out["velocity_m_s"][0]), abs(out["velocity_m_s"][1]))
    table_v = max(abs(a) for a in FC_ABSCISSAE)
    out["coverage"] = {
        "velocity_peak_m_s": vmax, "damping_table_last_abscissa_m_s": table_v,
        "damping_table_points_reached": int(sum(1 for a in FC_ABSCISSAE if abs(a) <= vmax)),
        "damping_table_points": len(FC_ABSCISSAE),
        "beyond_damping_table": vmax > table_v,
    }
    return out


#: the quiet band's white-equivalent noise this many times below the scatter between repeated cycles or
#: segments: the band above the stroke's content was removed (a raw load cell's noise is white)
FILTERED_RATIO = 10.0


def _looks_filtered(noise: dict) -> str | None:
    """Why the force looks low-pass filtered or smoothed, from its noise estimates (``tuner.data.noise.
    force_noise``): the quiet band's white-equivalent level far below what does not repeat between cycles
    or segments, or a level that falls across the quiet band; None when neither holds."""
    est = noise.get("all") or {}
    band = est.get("quiet_band") or {}
    spread = next((e for e in (est.get("cycle_scatter"), est.get("repeats")) if e and e.get("credible")), None)
    if band.get("value_n") and spread and spread["value_n"] > FILTERED_RATIO * band["value_n"]:
        return (f"the force's upper band holds {band['value_n']:.3g} N rms (white-equivalent), "
                f"{spread['value_n'] / band['value_n']:.3g} x less than its {spread['method'].replace('_', ' ')} "
                f"({spread['value_n']:.3g} N)")
    levels = band.get("levels_n") or []
    if levels and min(levels) > 0 and levels[0] > FLATNESS * levels[-1]:
        lo, hi = band["bands_hz"][0][0], band["bands_hz"][-1][1]
        return f"the force's quiet-band level falls {levels[0] / levels[-1]:.3g} x from {lo:.4g} to {hi:.4g} Hz"
    return None


def _noise_text(n: dict) -> str:
    """'; force noise ...' for the summary line: value, method, fit-band value, credible or why not."""
    if n["value_n"] is None:
        return "; force noise: no estimate (" + "; ".join(n["reasons"]) + ")"
    text = (f"; force noise {n['value_n']:.3g} N rms ({n['method'].replace('_', ' ')}"
            + (f", {n['in_band_n']:.3g} N in the {n['fit_rate_hz'] / 2:g} Hz fit band" if n["in_band_n"] is not None
               else "") + ")")
    return text + ("" if n["credible"] else " NOT credible: " + "; ".join(n["reasons"]))


def _range(lo: float, hi: float, scale: float, unit: str, digits: int = 4) -> str:
    return f"{lo * scale:.{digits}g} .. {hi * scale:.{digits}g} {unit}"


def _block_text(b: dict) -> str:
    """'line 3, Time: 1.0196941 Sec, 10/4/2021 7:48:04 AM, 1024 rows' of one MTS block stamp."""
    parts = [f"block {b['block']}"] + ([f"line {b['line']}"] if b.get("line") else [])
    if b.get("time") is not None:
        parts.append(f"Time: {b['time']:.8g} {b.get('time_unit') or ''}".rstrip())
    return ", ".join(parts + ([b["stamp"]] if b.get("stamp") else []) + [f"{b['rows']} rows"])


def _format_lines(s: dict) -> list[str]:
    """The summary's lines on the file's format (an MTS export's blocks, a MATLAB file's variables, a
    programme's step) and on US customary units converted; none for a plain metric table."""
    out = []
    info = s.get("format_info") or {}
    if info.get("blocks"):
        blocks = info["blocks"]
        out.append(f"  format: {s['format']} ({info['export']}): {len(blocks)} blocks of {info['rows_per_block']} "
                   f"rows" + (f", {info['blocks_left_out']} left out (see the warnings)" if info["blocks_left_out"]
                              else "") + f"; first {_block_text(blocks[0])}; last {_block_text(blocks[-1])}")
    elif info.get("variables"):
        out.append(f"  format: {s['format']}; variables: {', '.join(info['variables'])}"
                   + (f" ({info['note']})" if info.get("note") else ""))
    if s.get("step"):
        st = s["step"]
        out.append(f"  programme step {st['index']} of {st['of']}: {st['frequency_hz']:.4g} Hz, amplitude "
                   f"{st['amplitude_m'] * 1e3:.4g} mm, {st['cycles']} cycles from {st['t_start_s']:.4g} s to "
                   f"{st['t_end_s']:.4g} s of the file ({st['settling_cycles']} settling cycles left out)")
    conv = s.get("converted") or {}
    if conv:
        pairs = "; ".join(f"{role} {c['unit']} -> {c['si']} x {c['factor']:.15g}" for role, c in conv.items())
        c_app = s.get("apparent_damping_n_s_per_m")
        extra = (f"; apparent damping {c_app:.4g} N s/m = {c_app / units.DAMPING['lbf*s/in']:.4g} lbf*s/in"
                 if c_app else "")
        out.append(f"  US customary units read and converted exactly to SI: {pairs}{extra}")
    return out


def _logger_lines(s: dict) -> list[str]:
    """The summary's lines on what a data logger's file needed: the preamble before the header, the
    declared sample rate, the calibration of each channel (raw and scaled ranges), the force tare and
    the text columns left out; none for a plain table."""
    out = []
    if s["preamble"]:
        pairs = ", ".join(f"{k}: {v}" for k, v in s["preamble"].items())
        out.append(f"  file: column names on line {s['header_line']}, after a preamble ({pairs})")
    d = s["declared_rate"]
    if d:
        declared = ", ".join(f"{k} {hz:.6g} Hz" for k, hz in d["declared_hz"].items())
        out.append(f"  declared sample rate: {declared}; the time column gives {d['time_column_hz']:.6g} Hz"
                   + ("" if d["agrees"] else " (DIFFERS, see the warning)"))
    for what, c in (s["calibration"] or {}).items():
        scale = "" if c["scale"] is None else f"{c['scale']:g} x "
        offset = "" if c["offset"] is None else f" {'-' if c['offset'] < 0 else '+'} {abs(c['offset']):g}"
        raw = f"{c['raw_range'][0]:.4g} .. {c['raw_range'][1]:.4g}" + (f" {c['raw_unit']}" if c["raw_unit"] else "")
        out.append(f"  {what} = {scale}{c['column']!r}{offset} [{c['unit']}]: raw {raw} -> "
                   f"{_range(*c['scaled_range'], 1, c['unit'])}")
    z = s["force_zero"]
    if z:
        out.append(f"  force zero: {z['removed_n']:.4g} N removed (the mean over the first {z['seconds']:g} s, "
                   f"{z['samples']} samples; the stroke moved {z['stroke_motion_m'] * 1e3:.3g} mm meanwhile)")
    for col, held in s["text_columns"].items():
        out.append(f"  text column {col!r} left out (not a signal): {held}")
    if s["prefilter"]:
        pf = s["prefilter"]
        ends = "first" if pf["force_only"] and not pf["zero_phase"] else "first and last"
        out.append(f"  lab filter declared: {pf['text']} (" + ("" if pf["force_only"] else "the stroke is undone, ")
                   + f"the simulated force is compared through it; the {ends} {pf['settling_s']:.3g} s do not count)")
    elif s["looks_filtered"]:
        out.append(f"  looks filtered: {s['looks_filtered']}; if the lab low-passed or smoothed its channels, declare "
                   "the filter with --prefilter (a model compared with filtered data meets an error the filter made)")
    return out


def filter_warning(s: dict) -> str | None:
    """The warning a test's summary (:func:`summarize`) gives when its force looks filtered and no lab
    filter was declared, naming the file; None otherwise."""
    if s["prefilter"] or not s["looks_filtered"]:
        return None
    return (f"{s['file'] or s['name']}: the force looks filtered ({s['looks_filtered']}); if the lab low-passed "
            "or smoothed its channels, declare the filter with --prefilter (a model compared with filtered data "
            "meets an error the filter made)")


def format_summary(test: RigTest, fit_rate_hz: float, diff_band_hz: float | None = None) -> str:
    """Plain-text summary of :func:`summarize` (a few lines per test)."""
    return summary_text(summarize(test, fit_rate_hz, diff_band_hz))


def summary_text(s: dict) -> str:
    """Plain-text form of one test's :func:`summarize` figures (a few lines)."""
    cols = ", ".join(f"{k} <- {v!r}" for k, v in s["columns"].items()) or "time, stroke, force"
    units = ", ".join(f"{k} in {v}" for k, v in s["units_read"].items())
    signs = s["signs"]
    sign_text = ("as written (extension and tension positive)" if signs.get("stroke", 1) == signs.get("force", 1) == 1
                 else f"stroke x {signs.get('stroke', 1):+d}, force x {signs.get('force', 1):+d} "
                      f"(to extension and tension positive)")
    lines = [f"{s['name']}" + (f" ({s['role']})" if s["role"] else "") + f": {s['file']}",
             f"  columns: {cols}" + (f"; ignored: {s['ignored_columns']}" if s["ignored_columns"] else ""),
             f"  read: {units or 'SI'}; signs {sign_text}; time: {s['time_base']}"
             + (f", {s['stamps']}" if s["stamps"] else ""),
             f"  {s['samples']} samples at {s['sample_rate_hz']:.6g} Hz, {s['duration_s']:.4g} s",
             f"  stroke {_range(*s['stroke_m'], 1e3, 'mm')}; velocity {_range(*s['velocity_m_s'], 1e3, 'mm/s')} "
             f"({s['velocity_source']}); force {_range(*s['force_n'], 1e-3, 'kN')}"
             + _noise_text(s["force_noise"])] + _format_lines(s) + _logger_lines(s)
    for k, (lo, hi, u) in s["channels"].items():
        lines.append(f"  channel {k}: {lo:.4g} .. {hi:.4g} {u}".rstrip())
    c = s["coverage"]
    reach = (f"beyond the damping table's last abscissa {c['damping_table_last_abscissa_m_s'] * 1e3:.4g} mm/s "
             f"(extrapolated there)" if c["beyond_damping_table"] else
             f"{c['damping_table_points_reached']} of {c['damping_table_points']} damping-table abscissae")
    lines.append(f"  covers: peak velocity {c['velocity_peak_m_s'] * 1e3:.4g} mm/s, {reach}")
    if s["regularised"]:
        lines.append(f"  time base repaired: {s['regularised']}")
    for w in s["warnings"]:
        if not (s["regularised"] and s["regularised"] in w):
            lines.append(f"  warning: {w}")
    return "\n".join(lines)
