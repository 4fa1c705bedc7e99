"""The report's section on how well the identification tests determine each identified parameter: per
fitted model a table of the 95 % intervals and flags of parameters.json's ``intervals``
(``tuner.identification.intervals``), and a figure of the damping and elastic characteristics with their
95 % bands and the range the tests reach marked. SI units in, engineering prefixes out.

The band between two table points is that of the interpolated force, F(x) = w_a F_a + w_b F_b, with the
variance w^T C w from the parameters' covariance (so the band's width between points shows how the two
ordinates' errors cancel or add); where a neighbouring ordinate has no finite variance there is no band,
and that point's error bar spans its bounds (dotted).
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from tuner.formatting import eng
from tuner.identification.intervals import DETERMINED_WIDTH, TIE_CORRELATION, ModelIntervals
from tuner.metrics import Z95
from tuner.results.figure_layout import SUPTITLE_IN, TOP_IN, fixed_margins
from tuner.results.fit_folder import FitFolder
from tuner.results.html import MODEL_COLOR, MODEL_LABEL, esc, figure_html, model_label, table

__all__ = ["intervals_section_html", "fig_characteristic_bands", "model_intervals_of", "band"]

#: tables drawn: prefix -> (abscissa letter, axis scale, x label, title)
_TABLES = {"Fc": ("v", 1e3, "element rate [mm/s]", "damping characteristic Fc"),
           "Fk": ("x", 1e3, "element elongation [mm]", "elastic characteristic Fk")}


def model_intervals_of(run: FitFolder) -> dict:
    """{model: ModelIntervals} of the fitted models whose parameters.json entry has intervals."""
    out = {}
    for m in run.models:
        entry = run.params.get(m) or {}
        if entry.get("intervals"):
            out[m] = ModelIntervals.from_dict(m, entry["intervals"])
    return out


def _table_points(iv: ModelIntervals, prefix: str) -> list:
    """The ``ParameterInterval`` of each ordinate of table ``prefix``, by abscissa."""
    pts = [p for p in iv.parameters if re.fullmatch(rf"{prefix}_\d+", p.name) and p.abscissa is not None]
    return sorted(pts, key=lambda p: p.abscissa)


def band(iv: ModelIntervals, prefix: str, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(force [N], 95 % half-width [N]) of table ``prefix`` at ``x`` [m/s or m] within its abscissae, with the
    origin fixed at zero; the half-width is NaN where a neighbouring ordinate has no finite variance."""
    pts = _table_points(iv, prefix)
    xs = np.array([p.abscissa for p in pts] + [0.0])
    order = np.argsort(xs)
    xs = xs[order]
    names = [pts[i].name if i < len(pts) else None for i in order]
    fs = np.array([pts[i].value if i < len(pts) else 0.0 for i in order])
    index = {n: k for k, n in enumerate(iv.covariance_names)}
    force, half = np.interp(x, xs, fs), np.full(x.shape, np.nan)
    for j, xv in enumerate(x):
        b = int(np.clip(np.searchsorted(xs, xv), 1, xs.size - 1))
        wb = (xv - xs[b - 1]) / (xs[b] - xs[b - 1])
        terms = [(names[b - 1], 1.0 - wb), (names[b], wb)]
        terms = [(n, w) for n, w in terms if n is not None and w > 1e-12]
        if any(n not in index for n, _ in terms):
            continue
        var = sum(wi * wk * iv.covariance[index[ni], index[nk]] for ni, wi in terms for nk, wk in terms)
        half[j] = Z95 * math.sqrt(max(var, 0.0))
    return force, half


def _draw_table(ax, iv: ModelIntervals, prefix: str, color: str) -> None:
    """One characteristic with its band, its points by flag, the reached range shaded."""
    _, scale, xlabel, title = _TABLES[prefix]
    pts = _table_points(iv, prefix)
    x = np.linspace(pts[0].abscissa, pts[-1].abscissa, 400)
    force, half = band(iv, prefix, x)
    reach = next((r for r in iv.reached if r.table == prefix), None)
    if reach is not None:
        ax.axvspan(reach.low * scale, reach.high * scale, color="tab:green", alpha=0.12, lw=0,
                   label="reached by the identification tests")
    ax.fill_between(x * scale, (force - half) / 1e3, (force + half) / 1e3, color=color, alpha=0.3, lw=0,
                    label="95 % band")
    ax.plot(x * scale, force / 1e3, color=color, lw=1.2, label="identified")
    for p in pts:
        determined = p.status == "determined"
        lo, hi = (p.low, p.high) if p.low is not None else p.bounds
        bar = ax.errorbar([p.abscissa * scale], [p.value / 1e3],
                          yerr=[[max(p.value - lo, 0.0) / 1e3], [max(hi - p.value, 0.0) / 1e3]], fmt="o", ms=4,
                          mfc=color if determined else "white", mec="tab:orange" if p.extrapolated else color,
                          ecolor=color, elinewidth=0.8, capsize=2)
        if p.low is None:  # no finite variance: the bar spans the bounds
            bar[2][0].set_linestyle(":")
    ax.plot([], [], "o", ms=4, mfc="white", mec=color, ls="none", label="not determined / at a bound")
    ax.plot([], [], "o", ms=4, mfc=color, mec="tab:orange", ls="none", label="orange edge: extrapolated")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("force [kN]")
    ax.set_title(f"{MODEL_LABEL.get(iv.model, iv.model)}: {title}", fontsize=9)
    ax.grid(alpha=0.3)


def fig_characteristic_bands(ivs: dict, fdir: Path, dpi: int):
    """The damping and elastic characteristics of every model in ``ivs`` ({model: ModelIntervals}) with
    their 95 % bands; None when no model has a table."""
    rows = [(m, [k for k in _TABLES if _table_points(iv, k)]) for m, iv in ivs.items()]
    rows = [(m, keys) for m, keys in rows if keys]
    if not rows:
        return None
    fig = Figure(figsize=(10, 3.6 * len(rows)))
    axes = np.atleast_2d(fig.subplots(len(rows), 2, squeeze=False))
    fixed_margins(fig, top=TOP_IN + SUPTITLE_IN)
    for r, (m, keys) in enumerate(rows):
        for c in range(2):
            if c < len(keys):
                _draw_table(axes[r, c], ivs[m], keys[c], MODEL_COLOR.get(m, "k"))
                if r == 0 and c == 0:
                    axes[r, c].legend(fontsize=7, loc="upper left")
            else:
                axes[r, c].set_visible(False)
    fig.suptitle("Identified characteristics with their 95 % bands (points: table ordinates with their intervals)",
                 fontsize=10)
    FigureCanvasAgg(fig)
    path = fdir / "intervals_characteristics.png"
    fig.savefig(path, dpi=dpi)
    return f"figures/{path.name}"


def _rows(iv: ModelIntervals) -> tuple[list, list]:
    rows, classes = [], []
    for p in iv.parameters:
        interval = (f"{eng(p.low, p.unit, 4)} … {eng(p.high, p.unit, 4)}" if p.low is not None else
                    "none: the tests do not move the force along it")
        flags = "; ".join([f for f in p.flags if not f.startswith("tied to")]
                          + [f"tied to {n} ({c:+.2f})" for n, c in p.tied_to])
        width = "" if p.low is None else f"{100 * p.width_fraction:.3g} %"
        rows.append([f"<code>{esc(p.name)}</code>", eng(p.value, p.unit, 4), esc(interval), width,
                     f'<span class="flag" data-interval="{esc(p.name)}">{esc(flags)}</span>', esc(p.reason)])
        classes.append("" if p.status == "determined" else "flagged")
    return rows, classes


def intervals_section_html(run: FitFolder, figure) -> str:
    """The section (HTML): what the intervals are, the ``figure`` (its src from ``fig_characteristic_bands``, or
    ``html.NOT_DRAWN``), one table per model; a note for a fit without intervals (an output folder of an older
    version)."""
    head = "<section id='intervals'><h2>Identified parameters: intervals and identifiability</h2>"
    ivs = model_intervals_of(run)
    notes = [f"{model_label(m)}: {esc((run.params.get(m) or {}).get('intervals_note', 'no intervals'))}"
             for m in run.models if m in run.params and m not in ivs]
    if not ivs:
        return head + "<p class='skip'>No parameter intervals in parameters.json.</p></section>"
    parts = [head,
             "<p>How well the identification tests determine each identified parameter: the 95 % interval from the "
             "Jacobian of the identification residual at the fit, with the correlated residual counted by the block "
             "sandwich (blocks of three residual correlation times), clipped to the bounds. <b>determined</b>: the "
             f"interval lies inside the bounds and spans at most {100 * DETERMINED_WIDTH:g} % of their range (in "
             "decades for log-scaled parameters); <b>at a bound</b>: the bound, not the tests, holds it; <b>not "
             "determined</b>: a wide range of values fits as well (do not read the value as measured); <b>tied "
             f"to</b>: |correlation| above {TIE_CORRELATION:g} with the parameter named (the tests fix a combination); "
             "<b>extrapolated</b>: a table point beyond the element rate or elongation the tests reach. The interval "
             "is local (linearised at the fit) and statistical: it does not include a bias of the model form or of "
             "the identification's own discretisation.</p>",
             figure_html(figure,
                         "Identified characteristics with their 95 % bands; green span: the element rates "
                         "(elongations) the identification tests reach; open points: not determined or held by a "
                         "bound; orange edges: extrapolated.", "no fitted model has a table")]
    for m, iv in ivs.items():
        rows, classes = _rows(iv)
        parts.append(f"<h3>{model_label(m)}</h3><p>{esc(iv.summary_text())}; residual correlation time "
                     f"{eng(iv.correlation_time_s, 's')}, {iv.samples} samples.</p>"
                     + table(["Parameter", "Value", "95 % interval", "Width / bound range", "Flags", "Why"],
                             rows, "intervals", classes))
    parts += [f"<p class='skip'>{n}</p>" for n in notes]
    return "".join(parts) + "</section>"
