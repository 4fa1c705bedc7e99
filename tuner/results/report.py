"""HTML report of a fit output folder (paper: Isacchi, Ripamonti, Corsi 2023, section 3).

``make_report(out_dir)`` reads what ``tuner.identification.fit`` writes (SI units throughout)::

    parameters.json       {model: {values, units, bounds, parametrization, intervals}}
    metrics.json          {settings, tests: {name: {role, scenario, models: {model: metrics}}}, table3,
                           quality, full_rate, warnings (of reading the data, each once)}
    history_<model>.json  mean/best fitness per generation, initial and final populations (optional)
    simulations.npz       <test>__time [s], __stroke [m], __force [N], __<model> [N] (optional)

and writes PNG figures to ``out_dir/figures/`` and ``out_dir/report.html``: the summary with the one
recommendation of what to use (``tuner.results.recommendation``, also in the end summary and summary.json),
the data as read (the warnings of reading it, each once), the paper's Table 3 with further indices,
Figs. 9-10 (forces, differences, a zoom on the largest error), force-stroke and force-velocity loops,
Fig. 6 (fitness), Fig. 7 (constant parameters),
Fig. 8 (tables of the populations), Fig. 11 with eqs. 9-10 (5th-order fit, odd/even parts), the
Table 2 form of the parameters with bound flags, how well the tests determine each parameter (95 %
intervals, identifiability flags and the characteristics with their bands: ``intervals_report``), and
the run settings. Missing optional inputs
(a model, a history file, the simulations) skip their figure and say so in the report.

Errors (difference plots, metrics) are measured minus simulated force [N]. Samples before
``settings["warmup_s"]`` are drawn shaded; the metrics in metrics.json exclude them.

The report's parts live beside it: what is read (``fit_folder``), the figures (``fit_figures``), the
parameter intervals (``intervals_report``), the diagnosis, vehicle and datasheet sections (``diagnosis_report``,
``vehicle_report``, ``datasheet_report``), the HTML building blocks
(``html``); this module writes the fit report's own sections and assembles the page.
"""
from __future__ import annotations

import datetime as _dt
import hashlib
import math
import platform
from pathlib import Path

import numpy as np

from damper_fmu.parameters import MODEL_PARAMETERS
from tuner.formatting import eng, unit_html
from tuner.results.diagnosis_report import diagnosis_section_html
from tuner.results.fit_figures import bound_position, bounds_of, is_log, polyfits
from tuner.results.fit_folder import FitFolder, read_json
from tuner.results.html import MODEL_LABEL, esc, figure_html, model_label, num, table, write_page
from tuner.results.intervals_report import intervals_section_html
from tuner.results.recommendation import railway_damper, recommend, recommendation_html
from tuner.results.report_figures import draw_report_figures, undrawn_figures
from tuner.results.vehicle_report import vehicle_section_html
from tuner.results.design_report import design_section_html
from tuner.results.datasheet_report import datasheet_section_html


__all__ = ["make_report", "main"]

BOUND_FLAG_FRACTION = 0.01      # "at bound": within 1 % of the bound range
def _m(run: FitFolder, test: str, model: str) -> dict | None:
    return (run.tests.get(test, {}).get("models", {}) or {}).get(model)


def _table3_row(run: FitFolder, test: str) -> dict | None:
    """Table 3 entries of a validation test: metrics.json['table3'], else from the test metrics."""
    if test in run.table3:
        return run.table3[test]
    mx, lp = _m(run, test, "maxwell"), _m(run, test, "lumped")
    if not mx or not lp or not mx["mse"] or not mx["ame"]:
        return None
    return {"mse_maxwell": mx["mse"], "mse_lumped": lp["mse"],
            "mse_variation_pct": 100 * (lp["mse"] - mx["mse"]) / mx["mse"],
            "ame_maxwell": mx["ame"], "ame_lumped": lp["ame"],
            "ame_variation_pct": 100 * (lp["ame"] - mx["ame"]) / mx["ame"]}


def _rms_ratio(run: FitFolder, test: str, model: str) -> float | None:
    s = run.series(test)
    if s is None or model not in s[3]:
        return None
    t, _, f, sim = s
    keep = (t - t[0]) >= run.warmup
    den = float(np.sqrt(np.mean(f[keep] ** 2)))
    return float(np.sqrt(np.mean(sim[model][keep] ** 2))) / den * 100 if den > 0 else None


def _range(lo: float, hi: float, decimals: int) -> str:
    """'lo-hi %', or a single value when both round alike."""
    a, b = f"{lo:.{decimals}f}", f"{hi:.{decimals}f}"
    return f"{a} %" if a == b else f"{a}-{b} %"


def _named(test: str, scenario: str) -> str:
    """'<b>test</b> (scenario)', or the test alone when it has no scenario description (HTML)."""
    return f"<b>{esc(test)}</b>" + (f" ({esc(scenario)})" if scenario else "")


def _paper_comparison(run: FitFolder) -> tuple[list[str], str]:
    """The paper's lumped-vs-Maxwell comparison on the validation tests: (one HTML list item per test, one
    sentence over them). Information only: what to use is the recommendation's."""
    items, var, ame_pct, worse = [], [], [], []
    for test in run.validation:
        row, lp = _table3_row(run, test), _m(run, test, "lumped")
        scen = run.tests[test].get("scenario", "")
        if row is None or lp is None:
            items.append(f"<li>{_named(test, scen)}: lumped or Maxwell metrics missing.</li>")
            continue
        pct = 100 * lp["ame"] / lp["peak_measured"] if lp.get("peak_measured") else math.nan
        v = row["mse_variation_pct"]
        var.append(v)
        ame_pct.append(pct)
        if v >= 0:
            worse.append(test)
        word = f"a {abs(v):.1f} % reduction" if v < 0 else f"an INCREASE of {v:.1f} %"
        items.append(
            f'<li data-test="{esc(test)}">{_named(test, scen)}: MSE of the lumped model vs Maxwell '
            f'<span class="mse-var">{num(v, eng(v, "%"))}</span>, {word} '
            f'({eng(row["mse_maxwell"], "N^2")} &rarr; {eng(row["mse_lumped"], "N^2")}); '
            f'lumped AME {eng(lp["ame"], "N")} = <span class="ame-pct">{num(pct, eng(pct, "%"))}</span> '
            f'of the {eng(lp["peak_measured"], "N")} peak force.</li>')
    if not var:
        return items, ""
    if worse:
        return items, f"The lumped model does not beat the Maxwell model on {', '.join(worse)}."
    return items, (f"The lumped model beats the Maxwell model on every validation run ({_range(-max(var), -min(var), 1)} "
                   f"less squared error); its mean error reaches {max(ame_pct):.1f} % of peak force.")


def _amplitude(run: FitFolder, railway: bool) -> str:
    """Force amplitude of the lumped and Maxwell models against the measured one (HTML paragraph, '' when
    there is no simulation); the paper's curving consequence only for a railway damper's data."""
    amp = []
    for m in ("lumped", "maxwell"):
        r = [x for x in (_rms_ratio(run, t, m) for t in run.validation) if x is not None]
        if r:
            amp.append((m, min(r), max(r)))
    if not amp:
        return ""
    text = ("<p>Force amplitude on the validation runs (RMS of simulated / RMS of measured force, after warm-up): "
            + "; ".join(f"{esc(MODEL_LABEL.get(m, m))} {_range(a, b, 0)}" for m, a, b in amp) + ".")
    mx = [a for a in amp if a[0] == "maxwell"]
    if mx and mx[0][2] < 95:
        text += " The Maxwell element gives lower forces than the damper" + (
            ", which in curves over-estimates the curving performance of the vehicle (paper, section 3.2)."
            if railway else ".")
    elif mx and mx[0][1] > 105:
        text += " The Maxwell element gives higher forces than the damper."
    return text + "</p>"


def _summary(run: FitFolder) -> str:
    """The summary section: the recommendation box (``tuner.results.recommendation``, the one place that
    decides what to use), then what it rests on: the quality gate, the paper's lumped-vs-Maxwell comparison
    per validation test and the force amplitudes."""
    items, comparison = _paper_comparison(run)
    full_rate = run.metrics.get("full_rate") or {}
    gate = "".join(f"<li>{esc(MODEL_LABEL.get(m, m))}: {esc(q['text'])}"
                   + (f"; {esc(full_rate[m]['text'])}" if m in full_rate else "") + "</li>"
                   for m, q in (run.metrics.get("quality") or {}).items())
    gate = f"<p>Quality gate:</p><ul class='summary'>{gate}</ul>" if gate else ""
    paper = ""
    if items:
        paper = ("<p>The paper's comparison, lumped against Maxwell, on the validation tests (not used in the fit):</p>"
                 f"<ul class='summary'>{''.join(items)}</ul>" + (f"<p>{esc(comparison)}</p>" if comparison else ""))
    n_warned = len(run.metrics.get("warnings") or [])
    warned = (f"<p>Reading the data gave {n_warned} warning{'s' if n_warned > 1 else ''}: see "
              "<a href='#data'>the data as read</a>.</p>" if n_warned else "")
    return (f'<section id="summary"><h2>1. Summary</h2>{recommendation_html(recommend(run.out))}{warned}{gate}'
            f'{paper}{_amplitude(run, railway_damper(run.metrics))}</section>')


def _data_section(run: FitFolder) -> str:
    """The data as read: the warnings of reading the tests (metrics.json's ``warnings``, written by the job:
    units, plausibility and damper class, repaired clocks, declared rates, columns left out, a force that
    looks filtered), each once and naming its file, as the end summary and summary.json give them."""
    warnings = run.metrics.get("warnings")
    if warnings is None:
        said = ("<p class='skip'>No warnings of reading the data are recorded in this folder's metrics.json "
                "(written before the job kept them).</p>")
    elif not warnings:
        said = "<p>Reading the data gave no warning.</p>"
    else:
        said = (f"<p>Reading the data gave {len(warnings)} warning{'s' if len(warnings) > 1 else ''}, each once: "
                "the fit ran on the data as read, so check each before using the results.</p>"
                "<ul class='warnings'>" + "".join(f"<li>{esc(w)}</li>" for w in warnings) + "</ul>")
    return "<section id='data'><h2>The data as read</h2>" + said + "</section>"


def _metrics_section(run: FitFolder) -> str:
    rows = []
    for test in run.validation:
        r = _table3_row(run, test)
        if r is None:
            continue
        rows.append([esc(test), esc(run.tests[test].get("scenario", "")),
                     eng(r["mse_maxwell"], "N^2"), eng(r["mse_lumped"], "N^2"),
                     num(r["mse_variation_pct"], eng(r["mse_variation_pct"], "%")),
                     eng(r["ame_maxwell"], "N"), eng(r["ame_lumped"], "N"),
                     num(r["ame_variation_pct"], eng(r["ame_variation_pct"], "%"))])
    t3 = (table(["Test", "Scenario", "MSE Maxwell", "MSE lumped", "MSE variation",
                  "AME Maxwell", "AME lumped", "AME variation"], rows, "t3") if rows
          else '<p class="skip">Table 3 skipped: it needs the lumped and Maxwell models on validation tests.</p>')
    full, cls = [], []
    for test in [*run.validation, *run.identification]:
        role = run.tests[test].get("role", "")
        for m in run.models:
            x = _m(run, test, m)
            if x is None:
                continue
            pct = 100 * x["ame"] / x["peak_measured"] if x.get("peak_measured") else math.nan
            full.append([esc(test), esc(role + (" (fit data)" if role == "identification" else "")),
                         model_label(m), eng(x["mse"], "N^2"), eng(x["ame"], "N"),
                         eng(pct, "%"), eng(x["rmse"], "N"), eng(x.get("nrmse"), "-"),
                         eng(x.get("r2"), "-", 4), eng(x["max_abs_error"], "N"),
                         eng(x["peak_measured"], "N"), str(int(x["n"]))])
            cls.append("ident" if role == "identification" else "")
    return ("<section id='metrics'><h2>2. Accuracy (Table 3 and further indices)</h2>"
            "<p>MSE = Σ(F<sub>exp</sub> - F<sub>num</sub>)² / N, AME = Σ|F<sub>exp</sub> - F<sub>num</sub>| / N "
            "over the samples after warm-up; variation = (lumped - Maxwell) / Maxwell (negative = lumped better).</p>"
            + t3 + "<h3>All tests and models</h3>"
            "<p>NRMSE = RMSE / (max - min of the measured force); R² = 1 - SSE/SST; max error = "
            "max |F<sub>exp</sub> - F<sub>num</sub>|; peak = max |F<sub>exp</sub>|. "
            "Identification tests (shaded) were used by the fit and do not measure prediction quality.</p>"
            + table(["Test", "Role", "Model", "MSE", "AME", "AME / peak", "RMSE", "NRMSE", "R²",
                      "Max error", "Peak force", "Samples"], full, "metrics", cls) + "</section>")


def _timeseries_section(run: FitFolder, drawn: dict) -> str:
    parts = ["<section id='time'><h2>3. Measured and simulated force (Figs. 9-10) and loops</h2>"]
    if run.sims is None:
        parts.append('<p class="skip">Figures skipped: simulations.npz not found.</p></section>')
        return "".join(parts)
    parts.append("<p>Grey band: warm-up, excluded from the metrics. Blue band: the zoom window of the "
                 "bottom panel, centred on the largest error of the lumped model.</p>")
    for group, names, prefix in (("Validation tests", run.validation, "fig09_10"),
                                 ("Identification tests (fit data)", run.identification, "fit")):
        if not names:
            continue
        parts.append(f"<h3>{esc(group)}</h3>")
        for test in names:
            scen = run.tests[test].get("scenario", "")
            src, zoom = drawn["forces", test, prefix]
            cap = f"{_named(test, scen)}: forces, differences and zoom."
            if zoom:
                cap += (f" Largest {esc(MODEL_LABEL.get(zoom['model'], zoom['model']))} error "
                        f"{eng(zoom['error'], 'N')} at {zoom['t']:.2f} s.")
            parts.append(figure_html(src, cap, f"no arrays for test {test} in simulations.npz"))
            if prefix == "fig09_10":
                src = drawn["loops", test]
                parts.append(figure_html(src, f"<b>{esc(test)}</b>: force-stroke and force-velocity loops, "
                                            "measured vs lumped (velocity by a cubic Savitzky-Golay "
                                            "derivative of the stroke over ~20 ms).",
                                       f"no lumped simulation of {test} in simulations.npz"))
    parts.append("</section>")
    return "".join(parts)


def _fitness_section(run: FitFolder, drawn: dict) -> str:
    missing = [m for m in run.models if not run.histories.get(m)]
    src = drawn["fitness",]
    rows = []
    for m in run.models:
        h = run.histories.get(m)
        if not h:
            continue
        mean = [v for v in h.get("mean_fitness", []) if v is not None]
        best = [v for v in h.get("best_fitness", []) if v is not None]
        ev = h.get("evaluations") or [None]
        b = best[-1] if best else math.nan
        rows.append([model_label(m), esc(h.get("iterations", max(len(mean) - 1, 0))), esc(ev[-1]),
                     eng(mean[-1] if mean else math.nan, "1/N^2"), eng(b, "1/N^2"),
                     eng(1 / math.sqrt(b) if b and b > 0 and math.isfinite(b) else math.nan, "N"),
                     esc(h.get("stop_reason", "")), esc(_window_text(h.get("search_window")))])
    note = (f'<p class="skip">No history file for: {", ".join(model_label(m) for m in missing)} (not shown).</p>'
            if missing else "")
    return ("<section id='fitness'><h2>4. Convergence of the Firefly search (Fig. 6)</h2>"
            + figure_html(src, "Mean fitness of the population per iteration (solid) and best fitness ever "
                             "seen (dashed), log scale; on the search's windows of the identification tests where "
                             "they are shorter (the start of each test that covers its range twice; the "
                             "refinements then use every sample).", "no history_<model>.json file found")
            + note + (table(["Model", "Iterations", "Evaluations", "Final mean G", "Best G",
                              "Best RMSE = 1/√G", "Stop reason", "Searched on"], rows) if rows else "")
            + "</section>")


def _window_text(window: dict | None) -> str:
    """'20.3 s of 75.8 s' of a history's search windows (``tuner.identification.search_window``), '' if none."""
    if not window:
        return ""
    return f"{window['window_s']:.3g} s of {window['whole_s']:.3g} s"


def _population_sections(run: FitFolder, drawn: dict) -> str:
    why = ("history_lumped.json not found or without populations" if "lumped" in run.models
           else "no lumped model in this fit")
    src7 = src8 = None
    if "lumped" in run.models:
        src7, src8 = drawn["constants",], drawn["tables",]
    return ("<section id='constants'><h2>5. Constant parameters, initial vs final population (Fig. 7)</h2>"
            + figure_html(src7, "Each parameter normalised to its bounds (0 = lower, 1 = upper; log10 scale for "
                              "k_B and c_B); tick labels give the identified value and the bounds. A final "
                              "population collapsed on one value means the search converged.", why)
            + "</section><section id='tables'><h2>6. Oil characteristics Fk,O and Fc,O (Fig. 8)</h2>"
            + figure_html(src8, "Piecewise-linear tables of every individual of the initial (grey) and final "
                              "(green) population and the identified one (black, dots at the table points); "
                              "right: the small-amplitude region.", why) + "</section>")


def _poly_section(run: FitFolder, drawn: dict) -> str:
    head = "<section id='poly'><h2>7. Linearity and symmetry of Fk,O and Fc,O (Fig. 11, eqs. 9-10)</h2>"
    if "lumped" not in run.models:
        return head + '<p class="skip">Skipped: no lumped model in this fit.</p></section>'
    fits = polyfits(run)
    src = drawn["poly",]
    parts = [head, figure_html(src, "Identified tables (green) against a least-squares line (dashed), a "
                                  "5th-order least-squares polynomial (blue) fitted on the table points and the "
                                  "origin (as in the paper), and its odd (red +) and even (yellow x) parts at "
                                  "those points. Between widely spaced points the polynomial may swing away "
                                  "from the table: read its residual below before using the coefficients.",
                             "the identified tables could not be fitted")]
    var = {"Fk": ("e", "elongation of the Fk,O element [m]"), "Fc": ("v", "elongation rate of the Fc,O element [m/s]")}
    for key, fit in fits.items():
        c = fit["p5"].coefficients
        s, desc = var[key]
        terms = " ".join(f"{'+' if ci >= 0 else '-'} {abs(ci):.4g}" + (f"·{s}" if k else "") +
                         (f"<sup>{k}</sup>" if k > 1 else "") for k, ci in reversed(list(enumerate(c))))
        rows = [[f"c<sub>{k}</sub>", f"{ci:.3e}", unit_html(_coef_unit(key, k)), "odd" if k % 2 else "even"]
                for k, ci in enumerate(c)]
        p5, fs = fit["p5"], np.array(fit["table"].fs)
        resid = float(np.sqrt(np.mean((p5.fit - fs) ** 2)))
        parts.append(
            f"<h3>{key},O</h3><p class='eq'>{key},O,5th({s}) = {terms.lstrip('+ ')} &nbsp; [N], "
            f"{s} = {esc(desc)}</p>"
            f"<p>Linear fit slope {eng(fit['p1'].coefficients[1], _coef_unit(key, 1))}; "
            f"asymmetry index rms(even part) / rms(fit) = {num(p5.asymmetry_index, f'{p5.asymmetry_index:.3f}')} "
            "(0 = same force in extension and compression); RMS residual of the 5th-order fit at the table "
            f"points {eng(resid, 'N')} ({100 * resid / max(np.max(np.abs(fs)), 1e-300):.1f} % of the largest "
            "ordinate).</p>"
            + table(["Coefficient", "Value", "Unit", "Parity"], rows))
    parts.append("</section>")
    return "".join(parts)


def _coef_unit(key: str, k: int) -> str:
    """Unit of the x^k coefficient: Fk,O in N/m^k, Fc,O in N s^k/m^k."""
    if k == 0:
        return "N"
    p = f"^{k}" if k > 1 else ""
    return f"N/m{p}" if key == "Fk" else f"N.s{p}/m{p}"


def _params_section(run: FitFolder) -> str:
    parts = ["<section id='params'><h2>8. Identified parameters (Table 2 form)</h2>"
             f"<p>Position = where the value lies between its bounds (log10 scale for k_B, c_B, k_s, c); "
             f"values within {100 * BOUND_FLAG_FRACTION:g} % of a bound are flagged: the bound may be limiting "
             "the fit (for the Fc,O ordinates the zero bound is the sign constraint).</p>"]
    for m in run.models:
        entry = run.params.get(m)
        if not entry:
            parts.append(f"<h3>{model_label(m)}</h3><p class='skip'>No parameters in parameters.json.</p>")
            continue
        vals, units, b = entry.get("values", {}), entry.get("units", {}), bounds_of(run, m)
        spec = {p.name: p for p in MODEL_PARAMETERS.get(m, ())}
        order = [p.name for p in MODEL_PARAMETERS.get(m, ()) if p.tunable and p.name in vals]
        order += sorted(n for n in vals if n in b and n not in order)
        rows, cls, flagged = [], [], []
        for n in order:
            v, u = vals[n], units.get(n, spec[n].unit if n in spec else "")
            desc = spec[n].description if n in spec else ""
            ab = n.replace("Fk_", "Fk_x").replace("Fc_", "Fc_v")
            if n.startswith(("Fk_", "Fc_")) and ab in vals:
                desc = f"{desc.split(' ordinate')[0]} at {eng(vals[ab], units.get(ab, 'm'))}"
            flag = ""
            if n in b:
                lo, hi = b[n]
                pos = bound_position(v, lo, hi, is_log(m, n))
                if pos <= BOUND_FLAG_FRACTION:
                    flag = "AT LOWER BOUND"
                elif pos >= 1 - BOUND_FLAG_FRACTION:
                    flag = "AT UPPER BOUND"
                if flag:
                    flagged.append(n)
                rows.append([f"<code>{esc(n)}</code>", esc(desc), eng(v, u), eng(lo, u), eng(hi, u),
                             eng(100 * pos, "%"), f'<span class="flag" data-param="{esc(n)}">{flag}</span>'])
            else:
                rows.append([f"<code>{esc(n)}</code>", esc(desc), eng(v, u), "", "", "", ""])
            cls.append("flagged" if flag else "")
        fixed = [n for n in vals if n not in b and n in spec and not spec[n].tunable]
        fx = ""
        if fixed:
            fx = "<p>Fixed table abscissae (not identified): " + "; ".join(
                f"<code>{esc(n)}</code> {eng(vals[n], units.get(n, spec[n].unit))}" for n in fixed) + "</p>"
        parts.append(f"<h3>{model_label(m)}</h3><p>Parametrization: "
                     f"{esc(entry.get('parametrization', 'n/a'))}. Flagged: "
                     f"{esc(', '.join(flagged)) if flagged else 'none'}.</p>"
                     + table(["Parameter", "Meaning", "Value", "Lower bound", "Upper bound",
                               "Position", "Flag"], rows, "params", cls) + fx)
    parts.append("</section>")
    return "".join(parts)


def _flatten(d, prefix=""):
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and v:
            yield from _flatten(v, key + ".")
        else:
            yield key, v


def _setting_value(key: str, v) -> str:
    if isinstance(v, bool) or v is None:
        return esc(v)
    if isinstance(v, (int, float)):
        unit = ""
        base = key.split(".")[0].removesuffix("_used")
        for suf, u in (("_s", "s"), ("_hz", "Hz"), ("_n", "N"), ("_n_per_m", "N/m")):
            if base.endswith(suf):
                unit = u
        if isinstance(v, int) and not unit:
            return str(v)
        return eng(v, unit, 4) if unit else esc(f"{v:.6g}")
    if isinstance(v, list):
        if all(isinstance(x, str) for x in v) and any(len(x) > 60 for x in v):
            return "<br>".join(f"<pre>{esc(x)}</pre>" for x in v)
        return esc(", ".join(map(str, v)))
    return f"<pre>{esc(v)}</pre>" if isinstance(v, str) and ("\n" in v or len(v) > 80) else esc(v)


def _provenance_section(run: FitFolder) -> str:
    rows = [[f"<code>{esc(k)}</code>", _setting_value(k, v)] for k, v in _flatten(run.settings)]
    files = []
    for p in sorted(run.out.rglob("*")):
        rel = p.relative_to(run.out).as_posix()
        if p.is_file() and rel != "report.html" and not rel.startswith("figures/"):
            digest = hashlib.sha256(p.read_bytes()).hexdigest()[:16]
            files.append([f"<code>{esc(rel)}</code>", eng(p.stat().st_size, "B") if p.stat().st_size >= 1000
                          else f"{p.stat().st_size} B", f"<code>{digest}</code>"])
    import matplotlib

    env = (f"Report written {_dt.datetime.now(_dt.timezone.utc).strftime('%Y-%m-%d %H:%M UTC')} by "
           f"tuner.results.report (Python {platform.python_version()}, numpy {np.__version__}, "
           f"matplotlib {matplotlib.__version__}) from folder <code>{esc(run.out.resolve())}</code>.")
    return ("<section id='provenance'><h2>9. Provenance and run settings</h2><p>" + env + "</p>"
            + _time_budget_html(run.out)
            + table(["Setting (metrics.json)", "Value"], rows, "settings")
            + "<h3>Files of the output folder</h3>" + table(["File", "Size", "SHA-256 (first 16)"], files)
            + "</section>")


def _time_budget_html(out: Path) -> str:
    """Where the run's minutes went (``time_budget.json``, ``tuner.time_budget``): each stage and its sections of
    at least 1 % of the run, seconds and share; '' when the folder has no budget (a run before it was kept)."""
    path = out / "time_budget.json"
    if not path.exists():
        return ""
    rec = read_json(path, True)
    rows = []
    for st in rec.get("stages", []):
        rows.append([f"<b>{esc(st['stage'])}</b>", "", f"{st['seconds']:.1f}", f"{100 * st['share']:.1f}"])
        if len(st.get("sections", [])) > 1:
            rows += [["", esc(sec["section"]), f"{sec['seconds']:.1f}", f"{100 * sec['share']:.1f}"]
                     for sec in st["sections"] if sec["share"] >= 0.01]
    return (f"<h3>Where the time went ({rec.get('total_s', 0.0):.0f} s up to this report)</h3>"
            + table(["Stage", "Section", "Seconds", "Share of the run [%]"], rows, "budget"))


def make_report(out_dir, *, dpi: int = 110, figures: bool = True, workers: int = 0) -> Path:
    """Write ``out_dir/figures/*.png`` and ``out_dir/report.html`` from a fit output folder.

    out_dir: folder written by tuner.identification.fit (see module docstring); dpi: figure resolution [dots/inch];
    figures: False writes the page without its figures (each says so; about 0.5 s a figure less, ten to fifteen
    figures): a fleet row's or a script's report, drawn later by ``python -m tuner report``; workers: >= 2 draws the
    figures in that many processes (``report_figures``).
    Returns the path of report.html. Raises ValueError when parameters.json or metrics.json is
    missing or unreadable, or when simulations.npz holds arrays of inconsistent length.
    """
    out = Path(out_dir)
    run = FitFolder(out)
    if figures:
        (out / "figures").mkdir(exist_ok=True)
    drawn = draw_report_figures(run, out / "figures", dpi, workers) if figures else undrawn_figures(run)
    title = "Damper model identification report"
    ds = run.settings.get("dataset")
    diagnosis, vehicle = diagnosis_section_html(out), vehicle_section_html(out)  # '' when that stage did not run
    design = design_section_html(out)  # '' before python -m tuner design
    datasheet = datasheet_section_html(out, figures=figures)  # '' without datasheet/datasheet.json
    toc = "".join(f"<li><a href='#{a}'>{t}</a></li>" for a, t, shown in (
        ("summary", "Summary", True), ("data", "The data as read", True), ("diagnosis", "Diagnosis", diagnosis),
        ("vehicle", "In the vehicle", vehicle), ("datasheet", "Datasheet", datasheet),
        ("metrics", "Accuracy tables", True), ("time", "Force time histories and loops", True),
        ("fitness", "Fitness evolution", True), ("constants", "Constant parameters", True),
        ("tables", "Oil characteristics", True), ("poly", "Polynomial fits", True),
        ("params", "Identified parameters", True), ("intervals", "Parameter intervals", True),
        ("design", "Tests that would pin down the rest", design), ("provenance", "Provenance", True)) if shown)
    intro = (f"<p>Identification of a hydraulic damper model (lumped nonlinear model of Isacchi, Ripamonti "
             f"and Corsi 2023) against rig measurements{', dataset <code>' + esc(ds) + '</code>' if ds else ''}; "
             f"models: {', '.join(model_label(m) for m in run.models)}; "
             f"identification tests: {esc(', '.join(run.identification) or 'none')}; validation tests: "
             f"{esc(', '.join(run.validation) or 'none')}. Sign convention: stroke positive in extension, "
             "force positive in tension. SI units with engineering prefixes.</p>")

    body = [f"<h1>{title}</h1>", intro, f"<ol class='toc'>{toc}</ol>", _summary(run), _data_section(run),
            diagnosis, vehicle, datasheet, _metrics_section(run),
            _timeseries_section(run, drawn), _fitness_section(run, drawn),
            _population_sections(run, drawn), _poly_section(run, drawn), _params_section(run),
            intervals_section_html(run, drawn["intervals",]), design,
            _provenance_section(run)]
    return write_page(out, title, body)


def main(argv=None) -> int:
    import argparse

    ap = argparse.ArgumentParser(description="Write report.html and figures for a tuner fit output folder.")
    ap.add_argument("out_dir", help="folder written by the tuner (parameters.json, metrics.json, ...)")
    ap.add_argument("--dpi", type=int, default=110, help="figure resolution [dots/inch]")
    a = ap.parse_args(argv)
    print(make_report(a.out_dir, dpi=a.dpi))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
