"""The report's datasheet section (``datasheet/datasheet.json``, written by the job for every tuned FMU and by
``python -m tuner datasheet --out RUN``): the force-velocity table of every FMU with its series stiffness, the
figures (``datasheet_figures``), the measured points of the rig's sine tests beside the models' with the models'
errors, and the nominal band. Which points are measured and which simulated is said in every table and figure.
SI units in; kN, MN/m, kN s/m and % out."""
from __future__ import annotations

import math
from pathlib import Path

from tuner import strict_json
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
             f"(the last period within {100 * s['settle_tolerance']:g} % of the one before). Simulated: the force at the "
             f"peak velocities of sines of {1e3 * s['fv_amplitude_m']:g} mm "
             f"({', '.join(f'{v:g}' for v in s['peak_velocities_m_s'])} m/s), and the first-harmonic dynamic "
             f"stiffness at {', '.join(f'{f:g}' for f in s['frequencies_hz'])} Hz and "
             f"{', '.join(f'{1e3 * a:g}' for a in s['amplitudes_m'])} mm. The series stiffness is the median "
             f"equivalent Maxwell k where the elasticity carries most of the force (loss angle below 45 deg). "
             f"Tables for a multibody code: {files}; everything in <code>{DATASHEET_FOLDER}/{DATASHEET_FILE}</code>."
             f"</p>")
    return ("<section id='datasheet'><h2>Datasheet: force-velocity and dynamic characteristics</h2>" + intro
            + "<h3>Force-velocity characteristic (simulated)</h3>" + _force_velocity_table(sheet)
            + _figures(sheet, folder, figures) + "</section>")
