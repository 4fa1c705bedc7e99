"""Fleet summary of a batch identification (``tuner.fleet``): table, outliers, characteristic plots.

Input: one record per manifest row (``tuner.fleet.batch`` writes them as ``<out>/<id>/done.json``), with the
identified parameters, the validation metrics and the diagnosis verdict of every finished row.

Output (every file written to a temporary name first, then moved into place with ``os.replace``):
    summary.csv              one line per manifest row: status and error, identification RMSE,
                             validation AME [N] and MSE [N^2] per test and model, named causes,
                             outlier flag, identified parameters (SI, unit in the column name)
    summary.html             the same table for reading, the outlier rule, the figures
    figures/fc_<type>.png    damping characteristic Fc,O(v) of every damper of a type overlaid,
                             the type's median and tolerance band, outliers in red

Outlier rule (``find_outliers``): for the dampers of one type that finished, the lumped model's
damping table Fc,O is compared ordinate by ordinate (at the fixed rates Fc_v01..Fc_v14; a table
with other rates is interpolated onto the first damper's). At each rate v_j let m_j be the median
of the type's forces and MAD_j the median absolute deviation from it. A damper is an outlier when
at some rate

    |Fc_j - m_j| > max(k * 1.4826 * MAD_j, tolerance * |m_j|)

(default k = 3, tolerance = 0.05). 1.4826 MAD is the standard deviation of normal scatter, so k = 3
is the usual three-sigma rule made robust (one odd damper does not widen the spread it is judged
against); the tolerance keeps a fleet of near-identical dampers, whose MAD is only identification
noise, from flagging differences of a few per cent. A type with fewer than ``MIN_DAMPERS`` (3)
finished dampers is not judged (the median of two is their mean: neither can lie outside).
"""
from __future__ import annotations

import csv
import html
import io
import os
from pathlib import Path

__all__ = ["OUTLIER_K", "OUTLIER_TOLERANCE", "MIN_DAMPERS", "MAD_TO_SIGMA", "characteristic",
           "find_outliers", "write_summary", "outlier_rule_text", "write_atomic"]

OUTLIER_K = 3.0
OUTLIER_TOLERANCE = 0.05
MIN_DAMPERS = 3
MAD_TO_SIGMA = 1.4826


def write_atomic(path: Path, data: str | bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder and ``os.replace``
    (a reader sees the old file or the new one, never a partial one)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    if isinstance(data, str):
        tmp.write_text(data, encoding="utf-8")
    else:
        tmp.write_bytes(data)
    os.replace(tmp, path)
    return path


def outlier_rule_text(k: float = OUTLIER_K, tolerance: float = OUTLIER_TOLERANCE) -> str:
    return (f"A damper is an outlier of its type when, at some rate v_j of the damping table Fc,O, "
            f"|Fc_j - median_j| > max({k:g} x 1.4826 x MAD_j, {100 * tolerance:g} % of |median_j|), "
            f"median and MAD (median absolute deviation) over the type's finished dampers; "
            f"types with fewer than {MIN_DAMPERS} finished dampers are not judged.")


def characteristic(values: dict):
    """(rates v [m/s], forces Fc [N]) of the lumped model's damping table from its parameter values
    (``Fc_v01``.. abscissae, ``Fc_01``.. ordinates), sorted by rate."""
    import numpy as np

    idx = sorted(k[len("Fc_v"):] for k in values if k.startswith("Fc_v"))
    if not idx or any(f"Fc_{i}" not in values for i in idx):
        raise ValueError("no lumped damping table (Fc_v01.., Fc_01..) in the parameter values")
    v = np.array([float(values[f"Fc_v{i}"]) for i in idx])
    f = np.array([float(values[f"Fc_{i}"]) for i in idx])
    order = np.argsort(v)
    return v[order], f[order]


def find_outliers(curves: dict, k: float = OUTLIER_K, tolerance: float = OUTLIER_TOLERANCE) -> dict:
    """Outliers among the damping characteristics of ONE type (rule in the module docstring).

    curves: {damper id: (v [m/s], Fc [N])}. Returns {"judged": bool, "v", "median", "limit"
    (arrays, or None when not judged), "dampers": {id: {"outlier": bool, "worst_rate_m_s",
    "deviation_n", "limit_n", "ratio"}}} where ratio = |deviation| / limit at the worst rate (> 1:
    outlier).
    """
    import numpy as np

    ids = list(curves)
    if len(ids) < MIN_DAMPERS:
        return {"judged": False, "v": None, "median": None, "limit": None,
                "dampers": {i: {"outlier": False, "worst_rate_m_s": None, "deviation_n": None,
                                "limit_n": None, "ratio": None} for i in ids}}
    v0 = curves[ids[0]][0]
    F = np.array([np.interp(v0, *curves[i]) if len(curves[i][0]) != len(v0) or np.any(curves[i][0] != v0)
                  else curves[i][1] for i in ids])
    med = np.median(F, axis=0)
    mad = np.median(np.abs(F - med), axis=0)
    limit = np.maximum(k * MAD_TO_SIGMA * mad, tolerance * np.abs(med))
    limit = np.maximum(limit, 1e-9)  # a zero median and zero MAD: any difference counts
    out = {}
    for row, i in zip(F, ids):
        ratio = np.abs(row - med) / limit
        j = int(np.argmax(ratio))
        out[i] = {"outlier": bool(ratio[j] > 1.0), "worst_rate_m_s": float(v0[j]),
                  "deviation_n": float(row[j] - med[j]), "limit_n": float(limit[j]), "ratio": float(ratio[j])}
    return {"judged": True, "v": v0, "median": med, "limit": limit, "dampers": out}


def _plot_type(path: Path, type_name: str, curves: dict, spread: dict) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    if spread["judged"]:
        v, med, lim = spread["v"], spread["median"], spread["limit"]
        ax.fill_between(v, (med - lim) / 1e3, (med + lim) / 1e3, color="0.85", label="tolerance band", zorder=0)
        ax.plot(v, med / 1e3, color="k", lw=1.2, ls="--", label="type median", zorder=1)
        ax2.fill_between(v, -lim, lim, color="0.85", zorder=0)
        ax2.axhline(0.0, color="k", lw=1.0, ls="--")
    named = len(curves) <= 12  # a large fleet: only the outliers get a legend entry
    first = True
    for i, (vv, ff) in curves.items():
        info = spread["dampers"][i]
        odd = info["outlier"]
        style = dict(color="tab:red", lw=2.0, zorder=3) if odd else dict(color="tab:blue", lw=1.0, alpha=0.7, zorder=2)
        label = f"{i} (outlier)" if odd else (i if named else ("within the band" if first else None))
        first = first and (odd or named)
        ax.plot(vv, ff / 1e3, marker="o", ms=3, label=label, **style)
        if spread["judged"]:
            import numpy as np

            ax2.plot(spread["v"], np.interp(spread["v"], vv, ff) - spread["median"], marker="o", ms=3, **style)
            if odd:
                ax2.annotate(i, (info["worst_rate_m_s"], info["deviation_n"]), color="tab:red",
                             textcoords="offset points", xytext=(4, 4))
    ax.set_xlabel("damping rate v [m/s]")
    ax.set_ylabel("Fc,O [kN]")
    ax.set_title(f"type {type_name}: damping characteristic ({len(curves)} dampers)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    ax2.set_xlabel("damping rate v [m/s]")
    ax2.set_ylabel("Fc,O - type median [N]")
    ax2.set_title("deviation from the type median (band: outlier limit)" if spread["judged"]
                  else f"not judged: fewer than {MIN_DAMPERS} dampers")
    ax2.set_xscale("symlog", linthresh=2.5e-3)
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return write_atomic(path, buf.getvalue())


def _fmt(x, digits: int = 4) -> str:
    if x is None or x == "":
        return ""
    if isinstance(x, float):
        return f"{x:.{digits}g}"
    return str(x)


def _safe_name(text: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in text) or "_"


def _summary_line(r: dict, o: dict | None, tests: list, models: list, par_cols: dict) -> dict:
    """The summary.csv line of the fleet row ``r`` (``write_summary``'s rows), ``o`` its outlier record (None when
    its type had no curves): identification RMSE [N], validation AME [N] and MSE [N^2] per test and model, the
    identified parameters of ``par_cols`` (column -> (model, parameter)) in SI."""
    rec = r.get("record") or {}
    detail = ""
    if o and o["ratio"] is not None:
        detail = (f"worst at v = {o['worst_rate_m_s']:+.4g} m/s: {o['deviation_n']:+.0f} N from the type median, "
                  f"limit {o['limit_n']:.0f} N")
    diag = rec.get("diagnosis") or {}
    line = {"row": r["row"], "id": r["id"], "damper_id": r["damper_id"], "session": r.get("session", ""),
            "type": r["type"], "status": r["status"], "error": r.get("error", ""),
            "seed": rec.get("seed", r.get("seed", "")),
            "outlier": ("" if o is None or o["ratio"] is None else ("yes" if o["outlier"] else "no")),
            "outlier_detail": detail, "causes": "+".join(diag.get("causes", [])) if diag else "",
            "verdict": diag.get("verdict", "") if diag else "", "noise_floor_n": rec.get("noise_floor_n", "")}
    for m in models:
        line[f"identification_rmse.{m}_n"] = (rec.get("identification_rmse_n") or {}).get(m, "")
    for t in tests:
        for m in models:
            met = ((rec.get("validation") or {}).get(t) or {}).get(m) or {}
            line[f"validation.{t}.{m}.ame_n"] = met.get("ame", "")
            line[f"validation.{t}.{m}.mse_n2"] = met.get("mse", "")
    for col, (m, p) in par_cols.items():
        line[col] = ((rec.get("parameters") or {}).get(m) or {}).get(p, "")
    return line


def write_summary(out: Path, rows: list[dict], *, k: float = OUTLIER_K, tolerance: float = OUTLIER_TOLERANCE,
                  title: str = "Fleet summary") -> dict:
    """Write summary.csv, summary.html and the per-type figures into ``out``; return {"csv", "html",
    "figures", "outliers": {id: info}}.

    rows: one dict per manifest row, in manifest order: "row" (number), "id", "damper_id", "session",
    "type", "status" ('done', 'failed', 'pending'), "error" (message or ''), and for finished rows
    "record" (the row's done.json).
    """
    out = Path(out)
    # outliers per type
    outliers, figures = {}, {}
    types = []
    for r in rows:
        if r["type"] not in types:
            types.append(r["type"])
    for t in types:
        curves = {}
        for r in rows:
            if r["type"] == t and r["status"] == "done":
                values = (r["record"].get("parameters") or {}).get("lumped")
                if values:
                    curves[r["id"]] = characteristic(values)
        if not curves:
            continue
        spread = find_outliers(curves, k, tolerance)
        outliers.update(spread["dampers"])
        figures[t] = _plot_type(out / "figures" / f"fc_{_safe_name(t)}.png", t, curves, spread)

    # table
    tests, models, par_cols = [], [], {}
    for r in rows:
        rec = r.get("record") or {}
        for name, per_model in (rec.get("validation") or {}).items():
            if name not in tests:
                tests.append(name)
            for m in per_model:
                if m not in models:
                    models.append(m)
        for m, units in (rec.get("units") or {}).items():
            for p in (rec.get("identified") or {}).get(m, []):
                par_cols.setdefault(f"{m}.{p} [{units.get(p, '')}]", (m, p))
    head = ["row", "id", "damper_id", "session", "type", "status", "error", "seed", "outlier",
            "outlier_detail", "causes", "verdict", "noise_floor_n"]
    head += [f"identification_rmse.{m}_n" for m in models]
    head += [f"validation.{t}.{m}.{q}" for t in tests for m in models for q in ("ame_n", "mse_n2")]
    head += list(par_cols)
    lines = [_summary_line(r, outliers.get(r["id"]), tests, models, par_cols) for r in rows]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=head, lineterminator="\n")
    w.writeheader()
    for line in lines:
        w.writerow({c: (repr(v) if isinstance(v, float) else v) for c, v in line.items()})
    csv_path = write_atomic(out / "summary.csv", buf.getvalue())
    html_path = write_atomic(out / "summary.html", _html(title, lines, tests, models, par_cols, figures, out,
                                                         outlier_rule_text(k, tolerance)))
    return {"csv": csv_path, "html": html_path, "figures": figures, "outliers": outliers}


def _html(title, lines, tests, models, par_cols, figures, out, rule: str) -> str:
    """summary.html: the rows' table (``tests``, ``models`` and the parameter columns ``par_cols``), the per-type
    ``figures`` (paths under ``out``), the identified parameters and the verdicts; ``rule``: the outlier rule's
    words (``outlier_rule_text``)."""
    e = html.escape
    n_done = sum(1 for x in lines if x["status"] == "done")
    n_fail = sum(1 for x in lines if x["status"] == "failed")
    odd = [x["id"] for x in lines if x["outlier"] == "yes"]
    h = [f"<!doctype html><html><head><meta charset='utf-8'><title>{e(title)}</title><style>"
         "body{font-family:sans-serif;margin:1.5em} table{border-collapse:collapse;font-size:12px}"
         "td,th{border:1px solid #bbb;padding:2px 6px;text-align:right} td.l,th.l{text-align:left}"
         "tr.failed{background:#fdd} tr.outlier{background:#ffe9c7} img{max-width:100%}</style></head><body>",
         f"<h1>{e(title)}</h1>",
         f"<p>{len(lines)} rows: {n_done} done, {n_fail} failed, {len(lines) - n_done - n_fail} not run. "
         f"Outliers: {e(', '.join(odd)) if odd else 'none'}.</p>",
         f"<p><b>Outlier rule.</b> {e(rule)}</p>",
         "<h2>Dampers</h2><table><tr><th>row</th><th class=l>id</th><th class=l>type</th><th class=l>status</th>"
         "<th class=l>outlier</th><th class=l>causes</th>"
         + "".join(f"<th>ident. RMSE {e(m)} [N]</th>" for m in models)
         + "".join(f"<th>{e(t)}<br>AME {e(m)} [N]</th><th>{e(t)}<br>MSE {e(m)} [N&sup2;]</th>"
                   for t in tests for m in models)
         + "<th class=l>error / detail</th></tr>"]
    for x in lines:
        cls = "failed" if x["status"] == "failed" else ("outlier" if x["outlier"] == "yes" else "")
        link = f"<a href='{e(x['id'])}/report.html'>{e(x['id'])}</a>" if x["status"] == "done" else e(x["id"])
        h.append(f"<tr class='{cls}'><td>{x['row']}</td><td class=l>{link}</td><td class=l>{e(x['type'])}</td>"
                 f"<td class=l>{e(x['status'])}</td><td class=l>{e(x['outlier'])}</td><td class=l>{e(x['causes'])}</td>"
                 + "".join(f"<td>{_fmt(x[f'identification_rmse.{m}_n'], 4)}</td>" for m in models)
                 + "".join(f"<td>{_fmt(x[f'validation.{t}.{m}.ame_n'], 4)}</td><td>{_fmt(x[f'validation.{t}.{m}.mse_n2'], 4)}</td>"
                           for t in tests for m in models)
                 + f"<td class=l>{e(x['error'] or x['outlier_detail'])}</td></tr>")
    h.append("</table>")
    if figures:
        h.append("<h2>Damping characteristics per type</h2>")
        for t, p in figures.items():
            h.append(f"<h3>type {e(t)}</h3><img src='{e(str(Path(p).relative_to(out)))}' alt='Fc,O of type {e(t)}'>")
    if par_cols:
        h.append("<h2>Identified parameters (SI)</h2><table><tr><th class=l>id</th>"
                 + "".join(f"<th>{e(c)}</th>" for c in par_cols) + "</tr>")
        for x in lines:
            if x["status"] == "done":
                h.append(f"<tr><td class=l>{e(x['id'])}</td>" + "".join(f"<td>{_fmt(x[c], 5)}</td>" for c in par_cols)
                         + "</tr>")
        h.append("</table>")
    verdicts = [x for x in lines if x["verdict"]]
    if verdicts:
        h.append("<h2>Diagnosis verdicts</h2><ul>"
                 + "".join(f"<li><b>{e(x['id'])}</b>: {e(x['verdict'])}</li>" for x in verdicts) + "</ul>")
    h.append("</body></html>")
    return "\n".join(h)
