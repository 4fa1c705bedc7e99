"""The report's section on test design: the rig tests that would pin down the parameters the identification
tests leave open (``design/design.json``, written by ``python -m tuner design``,
``tuner.identification.rig_test_design``): per model the best candidates, their expected gain per parameter,
and the stroke files written. SI units in, mm and % out."""
from __future__ import annotations

import math
from pathlib import Path

from tuner.identification.rig_test_design import DESIGN_FOLDER
from tuner.results.html import esc, model_label, table
from tuner import strict_json

__all__ = ["design_section_html", "SHOWN"]

#: candidates shown per model (the files written are marked)
SHOWN = 5


def design_section_html(out_dir) -> str:
    """HTML section for ``out_dir/design/design.json`` ('' when there is none)."""
    path = Path(out_dir) / DESIGN_FOLDER / "design.json"
    if not path.exists():
        return ""
    data = strict_json.loads(path.read_text())
    lim = data["limits"]
    parts = [f"<p>Candidate rig tests within the rig's limits (stroke {1e3 * lim['stroke_m']:.3g} mm, velocity "
             f"{1e3 * lim['velocity_m_s']:.3g} mm/s, force {lim['force_n']:.0f} N), ranked by how much they are "
             "expected to shrink the 95 % intervals of the parameters each model leaves not determined "
             "(D-optimal on those parameters: the factor by which their joint confidence region shrinks; the "
             "expected widths, as the intervals, hold the representation shift of the fit with the candidate "
             "added; the prediction is linear, at the fit, with the fit's residual level). The best are written "
             f"as stroke files in the dataset format in <code>{DESIGN_FOLDER}/</code> (the force column is the fitted "
             "model's prediction; the rig records the measured force in its place).</p>"]
    for model, d in data["models"].items():
        rows = []
        for g in d["ranked"][:SHOWN]:
            gains = ", ".join(f"{esc(n)} x{t['shrink']:.2g}" for n, t in g["targets"].items())
            written = "yes" if f"{g['name']}.csv" in d["written"] else ""
            rows.append([esc(g["name"]), esc(g["description"]), f"{math.exp(g['score_nats']):.3g}",
                         f"{g['eigen_gain']:.3g}", gains, f"{g['peak_force_n'] / 1e3:.3g}", written])
        note = d["ranked"][0].get("note", "") if d["ranked"] else ""
        parts.append(f"<h3>{model_label(model)}: not determined {esc(', '.join(d['targets']))}</h3>"
                     + (f"<p>{esc(note)}</p>" if note else "")
                     + table(["test", "stroke", "volume shrink 1/x", "worst direction variance ratio",
                              "expected 95 % width after / before", "peak force [kN]", "file written"], rows))
    return ("<section id='design'><h2>The tests that would pin down the rest</h2>" + "".join(parts)
            + "</section>")
