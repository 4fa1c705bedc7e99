"""The report's datasheet section (``datasheet/datasheet.json``, written by the job for every tuned FMU and by
``python -m tuner datasheet --out RUN``): the force-velocity table of every FMU with its series stiffness, the
figures (``datasheet_figures``), the measured points of the rig's sine tests beside the models' with the models'
errors, and the nominal band. Which points are measured and which simulated is said in every table and figure.
SI units in; kN, MN/m, kN s/m and % out."""
from __future__ import annotations

import math
from pathlib import Path

from tuner import strict_json
from tuner.formatting import eng
from tuner.datasheet.sheet import DATASHEET_FILE, DATASHEET_FOLDER
from tuner.results.datasheet_figures import FIGURES, draw_datasheet_figures
from tuner.results.html import NOT_DRAWN, esc, figure_html, table

__all__ = ["datasheet_section_html"]


def _kn(v) -> str:
    return "" if v is None or not math.isfinite(v) else f"{v / 1e3:.4g}"


def _force_velocity_table(sheet: dict) -> str:
    """Peak velocity | per FMU the extension and compression force [kN], and the series stiffness row."""
    labels = list(sheet["fmus"])
    velocities = sorted({round(abs(p["velocity_m_s"]), 9) for ch in sheet["fmus"].values()
                         for p in ch["force_velocity"]})
    rows = []
    for v in velocities:
        row = [f"{v:.4g}"]
        for label in labels:
            pts = {(p["direction"], round(abs(p["velocity_m_s"]), 9)): p["force_n"]
                   for p in sheet["fmus"][label]["force_velocity"]}
            row += [_kn(pts.get(("extension", v))), _kn(pts.get(("compression", v)))]
        rows.append(row)
    rows.append(["series stiffness [MN/m]"] + [x for label in labels for x in (
        f"{sheet['fmus'][label]['series_stiffness_n_m'] / 1e6:.4g}"
        if sheet["fmus"][label]["series_stiffness_n_m"] is not None else "inf", "")])
    header = ["peak velocity [m/s]"] + [f"{label}: {d} [kN]" for label in labels for d in ("extension", "compression")]
    return table(header, rows)


#: the compared quantities: (key, label, unit for eng, error key, error unit)
COMPARED = (("dynamic_stiffness_n_m", "|K*|", "N/m", "dynamic_stiffness_n_m_pct", "%"),
            ("loss_angle_deg", "loss angle", "deg", "loss_angle_deg", "deg"),
            ("maxwell_c_n_s_m", "Maxwell c", "N s/m", "maxwell_c_n_s_m_pct", "%"),
            ("force_extension_n", "F at +v̂", "N", "force_extension_n_pct", "%"),
            ("force_compression_n", "F at -v̂", "N", "force_compression_n_pct", "%"),
            ("distortion", "distortion", "%", "distortion_pct_points", "pct points"))


def _value(v, unit: str) -> str:
    if unit == "deg":
        return "n/a" if v is None else f"{v:.1f}°"
    if unit == "%":
        return "n/a" if v is None else f"{100 * v:.1f} %"
    return eng(v, unit)


def _error(v, unit: str) -> str:
    if v is None or not math.isfinite(v):
        return "n/a"
    return f"{v:+.1f}°" if unit == "deg" else f"{v:+.1f} {'%' if unit == '%' else 'pt'}"


def _measured_html(sheet: dict) -> str:
    """The measured points of the rig's sine tests beside each FMU's, with the FMU's error ('' without)."""
    meas = (sheet.get("measured") or {})
    points, skipped = meas.get("points", []), meas.get("not_sine", [])
    if not points and not skipped:
        return ""
    parts = ["<h3>Measured (rig sine tests) beside simulated</h3>"]
    said = esc("; ".join(f"{n['test']}: {n['reason']}" for n in skipped))
    if not points:
        return parts[0] + f"<p>No rig test is a sine test, so every point of this datasheet is simulated ({said}).</p>"
    by_test = {p["test"]: p for p in points}
    parts.append("<p>Measured: the quantities of each rig sine test over its steady whole periods (the same reading "
                 "as the simulated ones). Model: the FMU at that test's frequency and amplitude, settled, through the "
                 "lab's filter where the test declares one. Each cell: measured / model (the model's error: "
                 "model - measured, in % of the measured value, in degrees or percentage points).</p>")
    for label, ch in sheet["fmus"].items():
        rows = []
        for c in ch.get("measured_comparison", []):
            m = by_test[c["test"]]
            rows.append([esc(c["test"]), f"{c['frequency_hz']:.3g}", f"{1e3 * c['amplitude_m']:.3g}",
                         f"{m['peak_velocity_m_s']:.3g}"]
                        + [f"{_value(m[k], u)} / {_value(c['model'][k], u)} ({_error(c['error'][e], eu)})"
                           for k, _, u, e, eu in COMPARED])
        parts.append(f"<p><b>{esc(label)}</b></p>" + table(
            ["test", "frequency [Hz]", "amplitude [mm]", "peak velocity [m/s]", *[c[1] for c in COMPARED]], rows))
    if skipped:
        parts.append(f"<p>Not sine tests (no measured point): {said}.</p>")
    return "".join(parts)


def _nominal_html(sheet: dict) -> str:
    """Every force-velocity point against the nominal band: counts per FMU and for the measurement, the points
    outside listed ('' without a nominal characteristic)."""
    nominal = sheet.get("nominal")
    if not nominal:
        return ""
    rows = []
    for key, pts in nominal["judged"].items():
        c = nominal["counts"][key]
        out = [p for p in pts if p["inside"] is False]
        listed = "; ".join(f"{p['velocity_m_s']:+.3g} m/s: {p['force_n'] / 1e3:.4g} kN against "
                           f"{p['nominal_force_n'] / 1e3:.4g} kN ({p['deviation_pct']:+.1f} %)" for p in out)
        what = "measured (rig sine tests)" if key == "measured" else f"{key} (simulated)"
        rows.append([esc(what), str(c["inside"]), str(c["outside"]), str(c["not_judged"]), esc(listed)])
    tols = sorted({f"{p['tolerance_pct']:g}" for p in nominal["points"]})
    return (f"<h3>Against the nominal characteristic</h3><p>Nominal: <code>{esc(nominal['file'])}</code>, "
            f"± {'/'.join(tols)} % of the nominal force; a point beyond the nominal's velocities is not judged.</p>"
            + table(["points", "inside", "outside", "not judged", "outside: velocity, force against nominal"], rows))


def _figures(sheet: dict, folder: Path, figures: bool) -> str:
    """The three figures (drawn here from the record when ``figures``; else the note that they were not)."""
    if figures:
        draw_datasheet_figures(sheet, folder)
    captions = {"force_velocity": "Force at peak velocity of settled sines, extension and compression: simulated "
                                  "(lines) and measured (black diamonds, the rig's sine tests).",
                "dynamic_stiffness": "Storage K' and loss K'' stiffness (first harmonic) against frequency, per "
                                     "stroke amplitude; black diamonds: measured.",
                "loss_angle": "Loss angle atan(K''/K') against frequency, per amplitude; black diamonds: measured."}
    return "".join(figure_html(f"{DATASHEET_FOLDER}/{name}" if figures else NOT_DRAWN, esc(captions[key]), "")
                   for key, name in FIGURES.items())


def datasheet_section_html(out_dir, figures: bool = True) -> str:
    """HTML section for ``out_dir/datasheet/datasheet.json`` ('' when there is none); ``figures``: draw its figures
    from the record into that folder (False: the captions with the note that they were not drawn)."""
    folder = Path(out_dir) / DATASHEET_FOLDER
    path = folder / DATASHEET_FILE
    if not path.exists():
        return ""
    sheet = strict_json.loads(path.read_text())
    s = sheet["settings"]
    files = ", ".join(f"<code>{DATASHEET_FOLDER}/{esc(label)}_force_velocity.csv</code>, "
                      f"<code>{DATASHEET_FOLDER}/{esc(label)}_maxwell.csv</code>" for label in sheet["fmus"])
    intro = (f"<p>Each FMU driven through fmpy by sine strokes as a co-simulation master drives it (inputs at the "
             f"start of each step of at most {1e3 * s['max_step_s']:g} ms), each run until its loop has settled "
             f"(the last period within {100 * s['settle_tolerance']:g} % of the one before). Simulated: the force at "
             f"the "
             f"peak velocities of sines of {1e3 * s['fv_amplitude_m']:g} mm "
             f"({', '.join(f'{v:g}' for v in s['peak_velocities_m_s'])} m/s), and the first-harmonic dynamic "
             f"stiffness at {', '.join(f'{f:g}' for f in s['frequencies_hz'])} Hz and "
             f"{', '.join(f'{1e3 * a:g}' for a in s['amplitudes_m'])} mm. The series stiffness is the median "
             f"equivalent Maxwell k where the elasticity carries most of the force (loss angle below 45 deg). "
             f"Tables for a multibody code: {files}; everything in <code>{DATASHEET_FOLDER}/{DATASHEET_FILE}</code>."
             f"</p>")
    return ("<section id='datasheet'><h2>Datasheet: force-velocity and dynamic characteristics</h2>" + intro
            + "<h3>Force-velocity characteristic (simulated)</h3>" + _force_velocity_table(sheet)
            + _measured_html(sheet) + _nominal_html(sheet) + _figures(sheet, folder, figures) + "</section>")
