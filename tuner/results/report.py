"""HTML report of a fit output folder (paper: Isacchi, Ripamonti, Corsi 2023, section 3).

``make_report(out_dir)`` reads what ``tuner.identification.fit`` writes (SI units throughout)::

    parameters.json       {model: {values, units, bounds, parametrization}}
    metrics.json          {settings, tests: {name: {role, scenario, models: {model: metrics}}}, table3,
                           quality, full_rate}
    history_<model>.json  mean/best fitness per generation, initial and final populations (optional)
    simulations.npz       <test>__time [s], __stroke [m], __force [N], __<model> [N] (optional)

and writes PNG figures to ``out_dir/figures/`` and ``out_dir/report.html``: summary and verdict,
the paper's Table 3 with further indices, Figs. 9-10 (forces, differences, a zoom on the largest
error), force-stroke and force-velocity loops, Fig. 6 (fitness), Fig. 7 (constant parameters),
Fig. 8 (tables of the populations), Fig. 11 with eqs. 9-10 (5th-order fit, odd/even parts), the
Table 2 form of the parameters with bound flags, and the run settings. Missing optional inputs
(a model, a history file, the simulations) skip their figure and say so in the report.

Errors (difference plots, metrics) are measured minus simulated force [N]. Samples before
``settings["warmup_s"]`` are drawn shaded; the metrics in metrics.json exclude them.
"""
from __future__ import annotations

import datetime as _dt
import hashlib
import html
import json
import math
import platform
import re
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from damper_fmu.parameters import MODEL_KINDS, MODEL_PARAMETERS, defaults
from damper_fmu.tables import PwlTable
from tuner.formatting import effect_value, eng, fmt_quantity, unit_html
from tuner.metrics import polyfit_odd_even
from tuner.vehicle.compare import VEHICLE_FOLDER, summary_rows

__all__ = ["make_report", "make_diagnosis_report", "diagnosis_section_html", "vehicle_section_html",
           "bound_position"]

MODEL_ORDER = MODEL_KINDS
MODEL_LABEL = {"lumped": "lumped (proposed)", "maxwell": "Maxwell (linear)",
               "maxwell_table": "Maxwell, table dashpot", "twochamber": "two-chamber (twin-tube form)"}
MODEL_COLOR = {"lumped": "tab:green", "maxwell": "tab:red", "maxwell_table": "tab:orange", "twochamber": "tab:purple"}
CONSTANTS = ("M_C", "M_O", "M_P", "k_B", "c_B")
BOUND_FLAG_FRACTION = 0.01      # "at bound": within 1 % of the bound range
ZOOM_WINDOW_S = 1.5             # zoom panel width [s]
LOOP_DIFF_WINDOW_S = 0.02       # Savitzky-Golay window for the loop velocity [s]

def _num(value, text: str) -> str:
    """HTML span showing ``text`` and carrying the exact value (machine-readable)."""
    return f'<span class="num" data-value="{float(value)!r}">{html.escape(text)}</span>'


def _mlabel(m: str) -> str:
    """HTML label of a model: readable name and the key used in the output files."""
    return f"{html.escape(MODEL_LABEL.get(m, m))} [<code>{html.escape(m)}</code>]"


def _e(s) -> str:
    return html.escape(str(s))


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or "test"


def _table(header: list[str], rows: list[list[str]], cls: str = "", row_classes=None) -> str:
    """HTML table; header cells are escaped, body cells are trusted HTML."""
    out = [f'<table class="{cls}"><thead><tr>' + "".join(f"<th>{_e(h)}</th>" for h in header)
           + "</tr></thead><tbody>"]
    for i, r in enumerate(rows):
        c = f' class="{row_classes[i]}"' if row_classes and row_classes[i] else ""
        out.append(f"<tr{c}>" + "".join(f"<td>{cell}</td>" for cell in r) + "</tr>")
    out.append("</tbody></table>")
    return "\n".join(out)


# --------------------------------------------------------------------------- inputs

def _read_json(path: Path, required: bool):
    if not path.exists():
        if required:
            raise ValueError(f"fit output is incomplete: {path.name} not found in {path.parent}")
        return None
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path} is not valid JSON: {exc}") from exc


def _ordered_models(names) -> list[str]:
    names = list(names)
    return [m for m in MODEL_ORDER if m in names] + sorted(m for m in names if m not in MODEL_ORDER)


class _Run:
    """Everything read from one fit output folder."""

    def __init__(self, out: Path):
        if not out.is_dir():
            raise ValueError(f"fit output folder {out} does not exist")
        self.out = out
        self.params = _read_json(out / "parameters.json", True)
        self.metrics = _read_json(out / "metrics.json", True)
        for key in ("tests",):
            if key not in self.metrics:
                raise ValueError(f"metrics.json has no '{key}' entry")
        self.settings = self.metrics.get("settings", {}) or {}
        self.tests = self.metrics["tests"]
        self.table3 = self.metrics.get("table3", {}) or {}
        names = set(self.params)
        for t in self.tests.values():
            names.update(t.get("models", {}))
        self.models = _ordered_models(names)
        self.histories = {m: _read_json(out / f"history_{m}.json", False) for m in self.models}
        self.validation = [n for n, t in self.tests.items() if t.get("role") == "validation"]
        self.identification = [n for n, t in self.tests.items() if t.get("role") != "validation"]
        self.warmup = float(self.settings.get("warmup_s", 0.0) or 0.0)
        self.sims = None
        npz = out / "simulations.npz"
        if npz.exists():
            with np.load(npz) as z:
                self.sims = {k: np.asarray(z[k], dtype=float) for k in z.files}

    def series(self, test: str):
        """(time [s], stroke [m], measured force [N], {model: simulated force [N]}) or None."""
        if self.sims is None or f"{test}__time" not in self.sims:
            return None
        t, x, f = (self.sims.get(f"{test}__{k}") for k in ("time", "stroke", "force"))
        if x is None or f is None:
            return None
        sim = {m: self.sims[f"{test}__{m}"] for m in self.models if f"{test}__{m}" in self.sims}
        for name, a in [("stroke", x), ("force", f), *sim.items()]:
            if a.shape != t.shape:
                raise ValueError(f"simulations.npz: {test}__{name} has {a.size} samples, "
                                 f"{test}__time has {t.size}")
        return t, x, f, sim

    def values(self, model: str) -> dict:
        """Identified values of ``model`` completed with the preset (fixed abscissae) [SI]."""
        v = defaults(model) if model in MODEL_PARAMETERS else {}
        v.update((self.params.get(model) or {}).get("values", {}))
        return v


# --------------------------------------------------------------------------- figures

def _save(fig: Figure, path: Path, dpi: int) -> str:
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=dpi)
    return f"figures/{path.name}"


def _mark_warmup(ax, t, warmup):
    if warmup > 0 and t.size:
        ax.axvspan(t[0], min(t[0] + warmup, t[-1]), color="0.9", zorder=0, lw=0)


def _fig_forces(run: _Run, test: str, fdir: Path, dpi: int, prefix: str):
    """Figs. 9-10 of one test: forces, differences, zoom around the lumped model's largest error."""
    s = run.series(test)
    if s is None:
        return None, None
    t, _, f, sim = s
    valid = (t - t[0]) >= run.warmup
    if not valid.any():
        valid = np.ones_like(t, dtype=bool)
    ref = "lumped" if "lumped" in sim else (next(iter(sim)) if sim else None)
    fig = Figure(figsize=(10, 8.2), layout="constrained")
    ax1, ax2, ax3 = fig.subplots(3, 1, gridspec_kw={"height_ratios": [1.2, 1, 1.2]})
    ax1.sharex(ax2)
    ax1.plot(t, f / 1e3, color="k", lw=1.0, label="measured")
    for m, y in sim.items():
        ax1.plot(t, y / 1e3, color=MODEL_COLOR.get(m), lw=0.9, alpha=0.85, label=MODEL_LABEL.get(m, m))
        ax2.plot(t, (f - y) / 1e3, color=MODEL_COLOR.get(m), lw=0.8, alpha=0.85, label=MODEL_LABEL.get(m, m))
    for ax in (ax1, ax2):
        _mark_warmup(ax, t, run.warmup)
        ax.grid(alpha=0.3)
    ax1.set_ylabel("damper force [kN]")
    ax1.set_title(f"{test}: measured and simulated force (Fig. 9)", fontsize=10)
    ax1.legend(loc="upper right", fontsize=8, ncol=4)
    ax2.set_ylabel("measured - simulated [kN]")
    ax2.set_title("difference (Fig. 10)", fontsize=10)
    zoom = None
    if ref is not None:
        err = np.where(valid, np.abs(f - sim[ref]), -1.0)
        k = int(np.argmax(err))
        half = ZOOM_WINDOW_S / 2
        lo, hi = max(t[0], t[k] - half), min(t[-1], t[k] + half)
        if hi - lo < ZOOM_WINDOW_S:   # keep the full width when clipped at one end
            lo, hi = max(t[0], hi - ZOOM_WINDOW_S), min(t[-1], lo + ZOOM_WINDOW_S)
        w = (t >= lo) & (t <= hi)
        for ax in (ax1, ax2):
            ax.axvspan(lo, hi, color="tab:blue", alpha=0.08, lw=0)
        ax3.plot(t[w], f[w] / 1e3, color="k", lw=1.3, marker="." if w.sum() <= 300 else None, ms=2.5,
                 label="measured")
        for m, y in sim.items():
            ax3.plot(t[w], y[w] / 1e3, color=MODEL_COLOR.get(m), lw=1.1, label=MODEL_LABEL.get(m, m))
        ax3.axvline(t[k], color="tab:blue", ls=":", lw=1)
        ax3.set_title(f"zoom {lo:.2f}-{hi:.2f} s around the largest {MODEL_LABEL.get(ref, ref)} error "
                      f"({eng(err[k], 'N')} at {t[k]:.2f} s; shaded blue above)", fontsize=10)
        ax3.grid(alpha=0.3)
        ax3.set_ylabel("damper force [kN]")
        zoom = {"t": float(t[k]), "error": float(err[k]), "lo": float(lo), "hi": float(hi), "model": ref}
    ax2.set_xlabel("time [s]")
    ax3.set_xlabel("time [s]")
    src = _save(fig, fdir / f"{prefix}_{_safe(test)}.png", dpi)
    return src, zoom


def _velocity(t, x):
    """Stroke velocity [m/s] for the loops: derivative of a centred cubic least-squares fit over
    ~20 ms (Savitzky-Golay, zero-phase); second-order differences within half a window of the ends."""
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    h = max(2, int(round(LOOP_DIFF_WINDOW_S / dt / 2)))
    v = np.gradient(x, t, edge_order=2) if t.size > 2 else np.gradient(x, t)
    if t.size <= 2 * h:
        return v
    k = np.arange(-h, h + 1, dtype=float)
    w = np.linalg.pinv(np.vander(k, 4, increasing=True))[1] / dt   # d/dt at the centre
    v[h:-h] = np.convolve(x, w[::-1], mode="valid")
    return v


def _fig_loops(run: _Run, test: str, fdir: Path, dpi: int):
    """Force-stroke and force-velocity loops, measured vs lumped (after warm-up)."""
    s = run.series(test)
    if s is None or "lumped" not in s[3]:
        return None
    t, x, f, sim = s
    v = _velocity(t, x)
    keep = (t - t[0]) >= run.warmup
    fig = Figure(figsize=(10, 4.2), layout="constrained")
    a1, a2 = fig.subplots(1, 2, sharey=True)
    for ax, ab, lab in ((a1, x[keep] * 1e3, "stroke [mm] (+ extension)"),
                        (a2, v[keep] * 1e3, "stroke velocity [mm/s]")):
        ax.plot(ab, f[keep] / 1e3, color="k", lw=0.6, alpha=0.8, label="measured")
        ax.plot(ab, sim["lumped"][keep] / 1e3, color=MODEL_COLOR["lumped"], lw=0.6, alpha=0.8,
                label=MODEL_LABEL["lumped"])
        ax.set_xlabel(lab)
        ax.grid(alpha=0.3)
    a1.set_ylabel("damper force [kN] (+ tension)")
    a1.set_title(f"{test}: force-stroke loop", fontsize=10)
    a2.set_title("force-velocity loop", fontsize=10)
    a1.legend(fontsize=8)
    return _save(fig, fdir / f"loops_{_safe(test)}.png", dpi)


def _fig_fitness(run: _Run, fdir: Path, dpi: int):
    """Fig. 6: mean fitness of the population per iteration and best-ever, per model."""
    hist = {m: h for m, h in run.histories.items() if h and h.get("mean_fitness")}
    if not hist:
        return None
    fig = Figure(figsize=(8, 4.5), layout="constrained")
    ax = fig.subplots()
    for m, h in hist.items():
        for key, ls, lab in (("mean_fitness", "-", "mean"), ("best_fitness", "--", "best ever")):
            y = np.array([np.nan if v is None else float(v) for v in h.get(key, [])], dtype=float)
            if not y.size:
                continue
            y[~np.isfinite(y) | (y <= 0)] = np.nan
            ax.plot(np.arange(y.size), y, ls=ls, color=MODEL_COLOR.get(m), lw=1.4,
                    label=f"{MODEL_LABEL.get(m, m)}: {lab}")
    ax.set_yscale("log")
    ax.set_xlabel("iteration (0 = initial population)")
    ax.set_ylabel("fitness G = N / Σ(F_exp - F_num)² [1/N²]")
    ax.set_title("Evolution of the population fitness (Fig. 6)", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    return _save(fig, fdir / "fig06_fitness.png", dpi)


def bound_position(value: float, low: float, high: float, log: bool = False) -> float:
    """Position of ``value`` within [low, high] as a fraction [-] (0 = low, 1 = high);
    in log10 space when ``log`` and both bounds are positive."""
    if log and low > 0 and high > 0 and value > 0:
        return (math.log10(value) - math.log10(low)) / (math.log10(high) - math.log10(low))
    return (value - low) / (high - low) if high != low else math.nan


def _bounds(run: _Run, model: str) -> dict[str, tuple[float, float]]:
    spec = {p.name: (p.low, p.high) for p in MODEL_PARAMETERS.get(model, ()) if p.tunable}
    spec.update({k: tuple(map(float, v)) for k, v in (run.params.get(model) or {}).get("bounds", {}).items()})
    return spec


def _is_log(model: str, name: str) -> bool:
    return any(p.name == name and p.log_scale for p in MODEL_PARAMETERS.get(model, ()))


def _fig_constants(run: _Run, fdir: Path, dpi: int):
    """Fig. 7: M_C, M_O, M_P, k_B, c_B of initial vs final population, normalised to bounds."""
    h = run.histories.get("lumped")
    if not h or not h.get("initial_population") or not h.get("final_population"):
        return None
    b = _bounds(run, "lumped")
    best = run.values("lumped")
    rng = np.random.default_rng(0)
    fig = Figure(figsize=(9, 4.5), layout="constrained")
    ax = fig.subplots()
    labels = []
    for i, name in enumerate(CONSTANTS):
        lo, hi = b[name]
        lg = _is_log("lumped", name)
        for pop, dx, col, lab in ((h["initial_population"], -0.18, "0.55", "initial population"),
                                  (h["final_population"], 0.18, MODEL_COLOR["lumped"], "final population")):
            y = [bound_position(p[name], lo, hi, lg) for p in pop if name in p]
            ax.scatter(i + dx + rng.uniform(-0.06, 0.06, len(y)), y, s=18, color=col, alpha=0.75,
                       edgecolor="none", label=lab if i == 0 else None)
        ax.scatter([i + 0.18], [bound_position(best[name], lo, hi, lg)], marker="*", s=140, color="k",
                   label="identified (best ever)" if i == 0 else None, zorder=5)
        u = (run.params.get("lumped") or {}).get("units", {}).get(name, "")
        labels.append(f"{name}\n{eng(best[name], u)}\n[{eng(lo, u)}, {eng(hi, u)}]" + ("\nlog" if lg else ""))
    ax.set_xticks(range(len(CONSTANTS)), labels, fontsize=8)
    ax.set_ylim(-0.05, 1.05)
    ax.set_ylabel("position within bounds [-]")
    ax.set_title("Constant parameters of the lumped model: initial vs final population (Fig. 7)", fontsize=10)
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.32), ncol=3)
    return _save(fig, fdir / "fig07_constants.png", dpi)


def _table_of(values: dict, prefix: str, axis: str, base: dict) -> PwlTable | None:
    """PwlTable of characteristic ``prefix`` ('Fk' with axis 'x', 'Fc' with 'v') from values."""
    names = sorted(n for n in base if re.fullmatch(rf"{prefix}_\d+", n))
    try:
        xs = [values.get(n.replace(prefix + "_", f"{prefix}_{axis}"), base[n.replace(prefix + "_", f"{prefix}_{axis}")])
              for n in names]
        fs = [values[n] for n in names]
        return PwlTable(xs, fs)
    except (KeyError, ValueError):
        return None


_CHAR = {"Fk": ("x", 1e3, "element elongation [mm]", "Fk,O: elastic characteristic"),
         "Fc": ("v", 1e3, "element elongation rate [mm/s]", "Fc,O: damping characteristic")}


def _zoom_limit(tab: PwlTable) -> float:
    """Half-width of the small-amplitude region: the second abscissa on each side (max of both)."""
    neg = [x for x in tab.xs if x < 0][::-1]
    pos = [x for x in tab.xs if x > 0]
    return max(abs(neg[min(1, len(neg) - 1)]), pos[min(1, len(pos) - 1)])


def _fig_populations(run: _Run, fdir: Path, dpi: int):
    """Fig. 8: Fk,O and Fc,O of initial and final population, full range and small-amplitude zoom."""
    h = run.histories.get("lumped")
    if not h or not h.get("initial_population") or not h.get("final_population"):
        return None
    best = run.values("lumped")
    fig = Figure(figsize=(10, 7.5), layout="constrained")
    axes = fig.subplots(2, 2)
    for row, key in enumerate(("Fk", "Fc")):
        axis, sc, xlabel, title = _CHAR[key]
        tb = _table_of(best, key, axis, best)
        if tb is None:
            continue
        lim = _zoom_limit(tb)
        for col, (x0, x1) in enumerate(((tb.xs[0], tb.xs[-1]), (-lim, lim))):
            ax = axes[row, col]
            xg = np.linspace(x0, x1, 201)
            ys = []
            for pop, c, lw, lab in ((h["initial_population"], "0.6", 0.7, "initial population"),
                                    (h["final_population"], MODEL_COLOR["lumped"], 0.9, "final population")):
                for j, p in enumerate(pop):
                    tp = _table_of(p, key, axis, best)
                    if tp is None:
                        continue
                    y = tp.evaluate(xg)
                    ys.append(y)
                    ax.plot(xg * sc, y / 1e3, color=c, lw=lw, alpha=0.6, label=lab if j == 0 else None)
            yb = tb.evaluate(xg)
            ax.plot(xg * sc, yb / 1e3, color="k", lw=1.8, label="identified (best ever)")
            pts = [(x, fv) for x, fv in zip(tb.xs, tb.fs) if x0 <= x <= x1]
            ax.plot([p[0] * sc for p in pts], [p[1] / 1e3 for p in pts], "ko", ms=3.5)
            ax.set_xlabel(xlabel)
            ax.set_ylabel("force [kN]")
            ax.set_title(title + (" (small-amplitude zoom)" if col else ""), fontsize=10)
            ax.grid(alpha=0.3)
            if col == 1:
                ymax = max(float(np.max(np.abs(yb))), *(float(np.percentile(np.abs(y), 90)) for y in ys)) \
                    if ys else float(np.max(np.abs(yb)))
                ax.set_ylim(-1.1 * ymax / 1e3, 1.1 * ymax / 1e3)
            if row == 0 and col == 0:
                ax.legend(fontsize=8)
    fig.suptitle("Nonlinear oil terms of the lumped model: initial vs final population (Fig. 8)", fontsize=11)
    return _save(fig, fdir / "fig08_tables.png", dpi)


def _polyfits(run: _Run):
    """Eqs. 9-10: 5th-order and linear least-squares fits of the identified tables (origin included)."""
    best = run.values("lumped")
    out = {}
    for key in ("Fk", "Fc"):
        axis = _CHAR[key][0]
        tb = _table_of(best, key, axis, best)
        if tb is None:
            continue
        x, y = np.array(tb.xs), np.array(tb.fs)
        try:
            p5 = polyfit_odd_even(x, y, 5)
            p1 = polyfit_odd_even(x, y, 1)
        except ValueError:
            continue
        out[key] = {"table": tb, "p5": p5, "p1": p1}
    return out


def _fig_polyfit(fits: dict, fdir: Path, dpi: int):
    """Fig. 11: identified terms, linear fit, odd and even parts of the 5th-order fit, Fk zoom."""
    if not fits:
        return None
    panels = [(k, False) for k in ("Fk", "Fc") if k in fits] + ([("Fk", True)] if "Fk" in fits else [])
    fig = Figure(figsize=(4.2 * len(panels), 4.4), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(panels)))
    for ax, (key, zoomed) in zip(axes, panels):
        axis, sc, xlabel, title = _CHAR[key]
        tb, p5, p1 = fits[key]["table"], fits[key]["p5"], fits[key]["p1"]
        lim = _zoom_limit(tb) if zoomed else None
        x0, x1 = (-lim, lim) if zoomed else (tb.xs[0], tb.xs[-1])
        xg = np.linspace(x0, x1, 401)
        inside = [(x, o, e) for x, o, e in zip(tb.xs, p5.odd, p5.even) if x0 <= x <= x1]
        xm, odd, even = (np.array(a) for a in zip(*inside))
        ax.plot(xg * sc, tb.evaluate(xg) / 1e3, color=MODEL_COLOR["lumped"], lw=2, label="identified")
        ax.plot(xg * sc, np.polyval(p1.coefficients[::-1], xg) / 1e3, "k--", lw=1, label="linear fit")
        ax.plot(xg * sc, np.polyval(p5.coefficients[::-1], xg) / 1e3, color="tab:blue", lw=0.8,
                label="5th-order fit")
        ax.plot(xm * sc, odd / 1e3, "+", color="tab:red", ms=7, label="odd terms")
        ax.plot(xm * sc, even / 1e3, "x", color="gold", ms=6, mew=1.5, label="even terms")
        if zoomed:
            ymax = float(np.max(np.abs(tb.evaluate(xg))))
            ax.set_ylim(-1.2 * ymax / 1e3, 1.2 * ymax / 1e3)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("force [kN]")
        ax.set_title(title.split(":")[0] + (" zoom" if zoomed else "") +
                     f" (asymmetry index {p5.asymmetry_index:.3f})", fontsize=10)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("Linearity and symmetry of the identified oil terms (Fig. 11)", fontsize=11)
    return _save(fig, fdir / "fig11_polyfit.png", dpi)


# --------------------------------------------------------------------------- HTML sections

def _fig_html(src: str | None, caption: str, missing: str) -> str:
    if src is None:
        return f'<p class="skip">Figure skipped: {_e(missing)}</p>'
    return (f'<figure><a href="{_e(src)}"><img src="{_e(src)}" alt="{_e(caption)}"></a>'
            f"<figcaption>{caption}</figcaption></figure>")


def _m(run: _Run, test: str, model: str) -> dict | None:
    return (run.tests.get(test, {}).get("models", {}) or {}).get(model)


def _table3_row(run: _Run, test: str) -> dict | None:
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


def _rms_ratio(run: _Run, test: str, model: str) -> float | None:
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


def _summary(run: _Run) -> str:
    items, var, ame_pct, worse = [], [], [], []
    for test in run.validation:
        row, lp = _table3_row(run, test), _m(run, test, "lumped")
        scen = run.tests[test].get("scenario", "")
        if row is None or lp is None:
            items.append(f"<li><b>{_e(test)}</b> ({_e(scen)}): lumped or Maxwell metrics missing.</li>")
            continue
        pct = 100 * lp["ame"] / lp["peak_measured"] if lp.get("peak_measured") else math.nan
        v = row["mse_variation_pct"]
        var.append(v)
        ame_pct.append(pct)
        if v >= 0:
            worse.append(test)
        word = f"a {abs(v):.1f} % reduction" if v < 0 else f"an INCREASE of {v:.1f} %"
        items.append(
            f'<li data-test="{_e(test)}"><b>{_e(test)}</b> ({_e(scen)}): MSE of the lumped model vs Maxwell '
            f'<span class="mse-var">{_num(v, eng(v, "%"))}</span>, {word} '
            f'({eng(row["mse_maxwell"], "N^2")} &rarr; {eng(row["mse_lumped"], "N^2")}); '
            f'lumped AME {eng(lp["ame"], "N")} = <span class="ame-pct">{_num(pct, eng(pct, "%"))}</span> '
            f'of the {eng(lp["peak_measured"], "N")} peak force.</li>')
    if not var:
        verdict = "No validation test has both lumped and Maxwell metrics: no verdict."
    elif worse:
        verdict = (f"The lumped model does not beat the Maxwell model on {', '.join(worse)}: do not use it in "
                   "place of the Maxwell element before revisiting the identification (data, bounds, iterations).")
    else:
        lo, hi = -max(var), -min(var)
        span = _range(lo, hi, 1)
        worst = max(ame_pct)
        if worst <= 5:
            verdict = (f"The lumped model follows the measured damper force within {worst:.1f} % of peak force "
                       f"(mean absolute error) on all {len(var)} validation runs and removes {span} of the "
                       "Maxwell model's squared error: use it in place of the linear Maxwell element in "
                       "vehicle-dynamics (curving and stability) simulations.")
        elif worst <= 10:
            verdict = (f"The lumped model beats Maxwell on every validation run ({span} less squared error) but "
                       f"its mean error reaches {worst:.1f} % of peak force: fine for comparative studies; "
                       "check the diagnosis before using it for stability margins.")
        else:
            verdict = (f"The lumped model beats Maxwell ({span} less squared error) but its mean error reaches "
                       f"{worst:.1f} % of peak force: it does not yet represent this damper.")
    amp = []
    for m in ("lumped", "maxwell"):
        r = [x for x in (_rms_ratio(run, t, m) for t in run.validation) if x is not None]
        if r:
            amp.append((m, min(r), max(r)))
    amp_txt = ""
    if amp:
        amp_txt = ("<p>Force amplitude on the validation runs (RMS of simulated / RMS of measured force, "
                   "after warm-up): " + "; ".join(f"{_e(MODEL_LABEL.get(m, m))} {_range(a, b, 0)}" for m, a, b in amp)
                   + ".")
        mx = [a for a in amp if a[0] == "maxwell"]
        if mx and mx[0][2] < 95:
            amp_txt += (" The Maxwell element gives lower forces than the damper, which in curves "
                        "over-estimates the curving performance of the vehicle (paper, section 3.2).")
        elif mx and mx[0][1] > 105:
            amp_txt += " The Maxwell element gives higher forces than the damper."
        amp_txt += "</p>"
    full_rate = run.metrics.get("full_rate") or {}
    gate = "".join(f"<li>{_e(MODEL_LABEL.get(m, m))}: {_e(q['text'])}"
                   + (f"; {_e(full_rate[m]['text'])}" if m in full_rate else "") + "</li>"
                   for m, q in (run.metrics.get("quality") or {}).items())
    gate = f"<p>Quality gate:</p><ul class='summary'>{gate}</ul>" if gate else ""
    return (f'<section id="summary"><h2>1. Summary</h2><p>Validation tests (not used in the fit):</p>'
            f'<ul class="summary">{"".join(items)}</ul>{amp_txt}{gate}'
            f'<p class="verdict"><b>Verdict:</b> {_e(verdict)}</p></section>')


def _metrics_section(run: _Run) -> str:
    rows = []
    for test in run.validation:
        r = _table3_row(run, test)
        if r is None:
            continue
        rows.append([_e(test), _e(run.tests[test].get("scenario", "")),
                     eng(r["mse_maxwell"], "N^2"), eng(r["mse_lumped"], "N^2"),
                     _num(r["mse_variation_pct"], eng(r["mse_variation_pct"], "%")),
                     eng(r["ame_maxwell"], "N"), eng(r["ame_lumped"], "N"),
                     _num(r["ame_variation_pct"], eng(r["ame_variation_pct"], "%"))])
    t3 = (_table(["Test", "Scenario", "MSE Maxwell", "MSE lumped", "MSE variation",
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
            full.append([_e(test), _e(role + (" (fit data)" if role == "identification" else "")),
                         _mlabel(m), eng(x["mse"], "N^2"), eng(x["ame"], "N"),
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
            + _table(["Test", "Role", "Model", "MSE", "AME", "AME / peak", "RMSE", "NRMSE", "R²",
                      "Max error", "Peak force", "Samples"], full, "metrics", cls) + "</section>")


def _timeseries_section(run: _Run, fdir: Path, dpi: int) -> str:
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
        parts.append(f"<h3>{_e(group)}</h3>")
        for test in names:
            scen = run.tests[test].get("scenario", "")
            src, zoom = _fig_forces(run, test, fdir, dpi, prefix)
            cap = f"<b>{_e(test)}</b> ({_e(scen)}): forces, differences and zoom."
            if zoom:
                cap += (f" Largest {_e(MODEL_LABEL.get(zoom['model'], zoom['model']))} error "
                        f"{eng(zoom['error'], 'N')} at {zoom['t']:.2f} s.")
            parts.append(_fig_html(src, cap, f"no arrays for test {test} in simulations.npz"))
            if prefix == "fig09_10":
                src = _fig_loops(run, test, fdir, dpi)
                parts.append(_fig_html(src, f"<b>{_e(test)}</b>: force-stroke and force-velocity loops, "
                                            "measured vs lumped (velocity by a cubic Savitzky-Golay "
                                            "derivative of the stroke over ~20 ms).",
                                       f"no lumped simulation of {test} in simulations.npz"))
    parts.append("</section>")
    return "".join(parts)


def _fitness_section(run: _Run, fdir: Path, dpi: int) -> str:
    missing = [m for m in run.models if not run.histories.get(m)]
    src = _fig_fitness(run, fdir, dpi)
    rows = []
    for m in run.models:
        h = run.histories.get(m)
        if not h:
            continue
        mean = [v for v in h.get("mean_fitness", []) if v is not None]
        best = [v for v in h.get("best_fitness", []) if v is not None]
        ev = h.get("evaluations") or [None]
        b = best[-1] if best else math.nan
        rows.append([_mlabel(m), _e(h.get("iterations", max(len(mean) - 1, 0))), _e(ev[-1]),
                     eng(mean[-1] if mean else math.nan, "1/N^2"), eng(b, "1/N^2"),
                     eng(1 / math.sqrt(b) if b and b > 0 and math.isfinite(b) else math.nan, "N"),
                     _e(h.get("stop_reason", ""))])
    note = (f'<p class="skip">No history file for: {", ".join(_mlabel(m) for m in missing)} (not shown).</p>'
            if missing else "")
    return ("<section id='fitness'><h2>4. Convergence of the Firefly search (Fig. 6)</h2>"
            + _fig_html(src, "Mean fitness of the population per iteration (solid) and best fitness ever "
                             "seen (dashed), log scale.", "no history_<model>.json file found")
            + note + (_table(["Model", "Iterations", "Evaluations", "Final mean G", "Best G",
                              "Best RMSE = 1/√G", "Stop reason"], rows) if rows else "") + "</section>")


def _population_sections(run: _Run, fdir: Path, dpi: int) -> str:
    why = ("history_lumped.json not found or without populations" if "lumped" in run.models
           else "no lumped model in this fit")
    src7 = _fig_constants(run, fdir, dpi) if "lumped" in run.models else None
    src8 = _fig_populations(run, fdir, dpi) if "lumped" in run.models else None
    return ("<section id='constants'><h2>5. Constant parameters, initial vs final population (Fig. 7)</h2>"
            + _fig_html(src7, "Each parameter normalised to its bounds (0 = lower, 1 = upper; log10 scale for "
                              "k_B and c_B); tick labels give the identified value and the bounds. A final "
                              "population collapsed on one value means the search converged.", why)
            + "</section><section id='tables'><h2>6. Oil characteristics Fk,O and Fc,O (Fig. 8)</h2>"
            + _fig_html(src8, "Piecewise-linear tables of every individual of the initial (grey) and final "
                              "(green) population and the identified one (black, dots at the table points); "
                              "right: the small-amplitude region.", why) + "</section>")


def _poly_section(run: _Run, fdir: Path, dpi: int) -> str:
    head = "<section id='poly'><h2>7. Linearity and symmetry of Fk,O and Fc,O (Fig. 11, eqs. 9-10)</h2>"
    if "lumped" not in run.models:
        return head + '<p class="skip">Skipped: no lumped model in this fit.</p></section>'
    fits = _polyfits(run)
    src = _fig_polyfit(fits, fdir, dpi)
    parts = [head, _fig_html(src, "Identified tables (green) against a least-squares line (dashed), a "
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
            f"{s} = {_e(desc)}</p>"
            f"<p>Linear fit slope {eng(fit['p1'].coefficients[1], _coef_unit(key, 1))}; "
            f"asymmetry index rms(even part) / rms(fit) = {_num(p5.asymmetry_index, f'{p5.asymmetry_index:.3f}')} "
            "(0 = same force in extension and compression); RMS residual of the 5th-order fit at the table "
            f"points {eng(resid, 'N')} ({100 * resid / max(np.max(np.abs(fs)), 1e-300):.1f} % of the largest "
            "ordinate).</p>"
            + _table(["Coefficient", "Value", "Unit", "Parity"], rows))
    parts.append("</section>")
    return "".join(parts)


def _coef_unit(key: str, k: int) -> str:
    """Unit of the x^k coefficient: Fk,O in N/m^k, Fc,O in N s^k/m^k."""
    if k == 0:
        return "N"
    p = f"^{k}" if k > 1 else ""
    return f"N/m{p}" if key == "Fk" else f"N.s{p}/m{p}"


def _params_section(run: _Run) -> str:
    parts = ["<section id='params'><h2>8. Identified parameters (Table 2 form)</h2>"
             f"<p>Position = where the value lies between its bounds (log10 scale for k_B, c_B, k_s, c); "
             f"values within {100 * BOUND_FLAG_FRACTION:g} % of a bound are flagged: the bound may be limiting "
             "the fit (for the Fc,O ordinates the zero bound is the sign constraint).</p>"]
    for m in run.models:
        entry = run.params.get(m)
        if not entry:
            parts.append(f"<h3>{_mlabel(m)}</h3><p class='skip'>No parameters in parameters.json.</p>")
            continue
        vals, units, b = entry.get("values", {}), entry.get("units", {}), _bounds(run, m)
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
                pos = bound_position(v, lo, hi, _is_log(m, n))
                if pos <= BOUND_FLAG_FRACTION:
                    flag = "AT LOWER BOUND"
                elif pos >= 1 - BOUND_FLAG_FRACTION:
                    flag = "AT UPPER BOUND"
                if flag:
                    flagged.append(n)
                rows.append([f"<code>{_e(n)}</code>", _e(desc), eng(v, u), eng(lo, u), eng(hi, u),
                             eng(100 * pos, "%"), f'<span class="flag" data-param="{_e(n)}">{flag}</span>'])
            else:
                rows.append([f"<code>{_e(n)}</code>", _e(desc), eng(v, u), "", "", "", ""])
            cls.append("flagged" if flag else "")
        fixed = [n for n in vals if n not in b and n in spec and not spec[n].tunable]
        fx = ""
        if fixed:
            fx = "<p>Fixed table abscissae (not identified): " + "; ".join(
                f"<code>{_e(n)}</code> {eng(vals[n], units.get(n, spec[n].unit))}" for n in fixed) + "</p>"
        parts.append(f"<h3>{_mlabel(m)}</h3><p>Parametrization: "
                     f"{_e(entry.get('parametrization', 'n/a'))}. Flagged: "
                     f"{_e(', '.join(flagged)) if flagged else 'none'}.</p>"
                     + _table(["Parameter", "Meaning", "Value", "Lower bound", "Upper bound",
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
        return _e(v)
    if isinstance(v, (int, float)):
        unit = ""
        base = key.split(".")[0].removesuffix("_used")
        for suf, u in (("_s", "s"), ("_hz", "Hz"), ("_n", "N"), ("_n_per_m", "N/m")):
            if base.endswith(suf):
                unit = u
        if isinstance(v, int) and not unit:
            return str(v)
        return eng(v, unit, 4) if unit else _e(f"{v:.6g}")
    if isinstance(v, list):
        if all(isinstance(x, str) for x in v) and any(len(x) > 60 for x in v):
            return "<br>".join(f"<pre>{_e(x)}</pre>" for x in v)
        return _e(", ".join(map(str, v)))
    return f"<pre>{_e(v)}</pre>" if isinstance(v, str) and ("\n" in v or len(v) > 80) else _e(v)


def _provenance_section(run: _Run) -> str:
    rows = [[f"<code>{_e(k)}</code>", _setting_value(k, v)] for k, v in _flatten(run.settings)]
    files = []
    for p in sorted(run.out.rglob("*")):
        rel = p.relative_to(run.out).as_posix()
        if p.is_file() and rel != "report.html" and not rel.startswith("figures/"):
            digest = hashlib.sha256(p.read_bytes()).hexdigest()[:16]
            files.append([f"<code>{_e(rel)}</code>", eng(p.stat().st_size, "B") if p.stat().st_size >= 1000
                          else f"{p.stat().st_size} B", f"<code>{digest}</code>"])
    import matplotlib

    env = (f"Report written {_dt.datetime.now(_dt.timezone.utc).strftime('%Y-%m-%d %H:%M UTC')} by "
           f"tuner.results.report (Python {platform.python_version()}, numpy {np.__version__}, "
           f"matplotlib {matplotlib.__version__}) from folder <code>{_e(run.out.resolve())}</code>.")
    return ("<section id='provenance'><h2>9. Provenance and run settings</h2><p>" + env + "</p>"
            + _table(["Setting (metrics.json)", "Value"], rows, "settings")
            + "<h3>Files of the output folder</h3>" + _table(["File", "Size", "SHA-256 (first 16)"], files)
            + "</section>")


_CSS = """
body{font-family:system-ui,Segoe UI,Helvetica,Arial,sans-serif;max-width:1100px;margin:auto;padding:1em;color:#222}
h1{font-size:1.6em}h2{border-bottom:1px solid #ccc;margin-top:1.8em}
table{border-collapse:collapse;margin:0.6em 0;font-size:0.88em}
th,td{border:1px solid #ccc;padding:3px 7px;text-align:right;vertical-align:top}
th{background:#f0f0f0}td:first-child,td:nth-child(2){text-align:left}
tr.ident{background:#f4f4f4;color:#555}tr.flagged{background:#fff1d6}.flag{color:#b35900;font-weight:bold}
figure{margin:1em 0}img{max-width:100%;border:1px solid #ddd}figcaption{font-size:0.9em;color:#444}
.skip{color:#8a5a00;font-style:italic}.verdict{background:#eef6ee;padding:0.6em;border-left:4px solid #3a3}
pre{white-space:pre-wrap;margin:0;font-size:0.9em}.eq{font-family:monospace}
table.settings td{text-align:left}
"""


def make_report(out_dir, *, dpi: int = 110) -> Path:
    """Write ``out_dir/figures/*.png`` and ``out_dir/report.html`` from a fit output folder.

    out_dir: folder written by tuner.identification.fit (see module docstring); dpi: figure resolution [dots/inch].
    Returns the path of report.html. Raises ValueError when parameters.json or metrics.json is
    missing or unreadable, or when simulations.npz holds arrays of inconsistent length.
    """
    out = Path(out_dir)
    run = _Run(out)
    fdir = out / "figures"
    fdir.mkdir(exist_ok=True)
    title = "Damper model identification report"
    ds = run.settings.get("dataset")
    toc = "".join(f"<li><a href='#{a}'>{t}</a></li>" for a, t in (
        ("summary", "Summary"), ("diagnosis", "Diagnosis"), ("vehicle", "In the vehicle"), ("metrics", "Accuracy tables"), ("time", "Force time histories and loops"),
        ("fitness", "Fitness evolution"), ("constants", "Constant parameters"), ("tables", "Oil characteristics"),
        ("poly", "Polynomial fits"), ("params", "Identified parameters"), ("provenance", "Provenance")))
    intro = (f"<p>Identification of a hydraulic damper model (lumped nonlinear model of Isacchi, Ripamonti "
             f"and Corsi 2023) against rig measurements{', dataset <code>' + _e(ds) + '</code>' if ds else ''}; "
             f"models: {', '.join(_mlabel(m) for m in run.models)}; "
             f"identification tests: {_e(', '.join(run.identification) or 'none')}; validation tests: "
             f"{_e(', '.join(run.validation) or 'none')}. Sign convention: stroke positive in extension, "
             "force positive in tension. SI units with engineering prefixes.</p>")

    body = [f"<h1>{title}</h1>", intro, f"<ol class='toc'>{toc}</ol>", _summary(run),
            diagnosis_section_html(out), vehicle_section_html(out), _metrics_section(run),
            _timeseries_section(run, fdir, dpi), _fitness_section(run, fdir, dpi),
            _population_sections(run, fdir, dpi), _poly_section(run, fdir, dpi), _params_section(run),
            _provenance_section(run)]
    return _write_page(out, title, body)


def _number_sections(html_text: str) -> str:
    """Number the ``<h2>`` section headings 1, 2, ... in the order they appear (whatever sections a
    run has), replacing any number they carry."""
    count = iter(range(1, 1000))
    return re.sub(r"<h2>(?:\d+\.\s*)?", lambda m: f"<h2>{next(count)}. ", html_text)


def _write_page(out: Path, title: str, body: list[str]) -> Path:
    page = (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>{title}</title>"
            f"<style>{_CSS}</style></head><body>" + _number_sections("\n".join(body)) + "</body></html>\n")
    path = out / "report.html"
    path.write_text(page, encoding="utf-8")
    return path


def make_diagnosis_report(out_dir) -> Path:
    """``out_dir/report.html`` for a diagnosis run on its own (no fit in the folder): the
    diagnosis section of the full report. Returns its path."""

    out = Path(out_dir)
    title = "Damper diagnosis report"
    return _write_page(out, title, [f"<h1>{title}</h1>", diagnosis_section_html(out)])


def _detection_html(limits: dict) -> str:
    """The detection limits of a diagnosis (``tuner.diagnosis.detection``) as a table ('' without any)."""
    if not limits:
        return ""
    rows = [[_e(effect), _e(fmt_quantity(r["limit"], r["unit"]) if r["reachable"] else "not within its search range"),
             _e(r["best_test"] or "-"),
             {"score": "held-out score", "noise": "force above the noise", "range": "physical range"}[r["limited_by"]]]
            for effect, r in limits.items()]
    return ("<h3>What these tests could have detected</h3><p>The smallest magnitude of each effect that the "
            "diagnosis would have named on these tests (linearised at the base refit: the part of the effect's "
            "force the base refit cannot absorb, against the acceptance score and the noise), and the held-out "
            "test that shows it best. A verdict 'none' means nothing above these sizes.</p>"
            + _table(["effect", "detectable from", "best test", "limited by"], rows))


def diagnosis_section_html(out_dir) -> str:
    """HTML section of the report for ``out_dir/diagnosis.json`` ('' when there is none)."""
    import html

    path = Path(out_dir) / "diagnosis.json"
    if not path.exists():
        return ""
    d = json.loads(path.read_text())
    e = html.escape
    causes = d.get("causes") or ([d["cause"]] if d["cause"] not in ("none", "unexplained") else [])

    def _rows(ranking, winner):
        out = []
        for r in ranking:
            cls = " class='winner'" if r["effect"] == winner else ""
            fitted = ", ".join(f"{n} = {effect_value(n, v, r['units'][n])}" for n, v in r["parameters"].items())
            why = " (evidence disagrees)" if r.get("evidence_agrees") is False else " (below noise)"
            size = (f"{r['effect_rms_n']:.3g}" + ("" if r.get("resolved", True) else why)
                    if r.get("parameters") else "-")
            ci = ", ".join(f"{fmt_quantity(lo, r['units'][n])} .. {fmt_quantity(hi, r['units'][n])}"
                           for n, (lo, hi) in r.get("interval", {}).items())
            ci += "" if "significant" not in r else (" (excludes 0)" if r["significant"] else " (includes 0)")
            ci += "; magnitude below the effect's physical range" if r.get("meaningful") is False else ""
            out.append(f"<tr{cls}><td>{e(r['effect'])}</td><td>{e(fitted)}</td><td>{e(ci or '-')}</td>"
                       f"<td>{r['validation_mse_change_pct']:+.1f} %</td><td>{r['score']:+.3f}</td>"
                       f"<td>{e(size)}</td></tr>")
        return "".join(out)

    head = ("<tr><th>candidate</th><th>fitted parameters</th><th>95 % interval</th><th>validation MSE change vs "
            "{ref}</th><th>score</th><th>effect force [N rms]</th></tr>")
    rows = _rows(d["ranking"], causes[0] if causes else None)
    steps = ""
    for k, st in enumerate(d.get("selection", [])):
        if st.get("tried"):
            added = causes[k + 1] if st["cause"] != "none" else None
            winner = next((r["effect"] for r in st["tried"] if r.get("added") == added), None) if added else None
            steps += (f"<h3>Forward selection, step {k + 2}: on top of {e(' + '.join(causes[:k + 1]))}</h3>"
                      f"<table>{head.format(ref='the causes so far')}{_rows(st['tried'], winner)}</table>")
    val = "".join(f"<tr><td>{e(n)}</td><td>{v['mse_before']:.3e}</td><td>{v['mse_after']:.3e}</td>"
                  f"<td>{v['mse_change_pct']:+.1f} %</td><td>{v['ame_before']:.0f}</td><td>{v['ame_after']:.0f}</td></tr>"
                  for n, v in d["validation"].items())
    eff = "".join(f"<tr><td>{e(n)}</td><td>{e(fmt_quantity(p['value'], p['unit']))}</td><td>"
                  f"{e(fmt_quantity(p['plausible_range'][0], p['unit']))} - {e(fmt_quantity(p['plausible_range'][1], p['unit']))}</td>"
                  f"<td>{'yes' if p['plausible'] else 'NO'}</td></tr>" for n, p in d["effect_parameters"].items())
    ev = (d.get("evidence") or {}).get("effects", {})
    ev_rows = "".join(f"<li><b>{e(k)}</b>: {e(str(v.get('sentence', '')))}</li>" for k, v in ev.items()
                      if isinstance(v, dict) and v.get("sentence"))
    scr = (d.get("evidence") or {}).get("joint_screen")
    if scr:
        kept = " + ".join(f"{k} ({scr['terms'][k]['contribution_n']:.3g} N)" for k in scr["kept"]) or "nothing"
        ev_rows += (f"<li><b>joint screen</b> (the residual on all seven signatures at once, terms below "
                    f"{scr['threshold_n']:.3g} N or of unphysical sign dropped): keeps {e(kept)}, explaining "
                    f"{100 * scr['r2_kept']:.0f} % of the residual power; all seven together "
                    f"{100 * scr['r2_all']:.0f} %: the most any linear mix of catalogue effects could remove</li>")
    figs = "".join(f"<figure><img src='{e(f)}' alt='{e(f)}'></figure>" for f in d.get("figures", []))
    s = d["settings"]
    base_kind = d.get("base_model", "lumped")
    choice = d.get("base_choice") or {}
    base_text = (f"<p>Base model: <b>{e(MODEL_LABEL.get(base_kind, base_kind))}</b>"
                 + (", chosen by " + e(choice.get("by", "")) + ": " + ", ".join(
                     f"{e(MODEL_LABEL.get(k, k))} {math.sqrt(v):.3g} N rms" for k, v in choice["validation_mse"].items())
                    if choice.get("validation_mse") else "") + ".</p>")
    if choice.get("after_diagnosis"):  # the first choice left a residual above the floor: both diagnosed
        base_text += ("<p>The first choice, " + e(MODEL_LABEL.get(choice["first_choice"], choice["first_choice"]))
                      + ", left a residual above the floor, so the diagnosis was repeated on every base form and "
                      "the final model with the lowest held-out MSE kept: " + ", ".join(
                          f"{e(MODEL_LABEL.get(k, k))} with {e(' + '.join(v['causes']) or 'no cause')} "
                          f"{math.sqrt(v['validation_mse']):.3g} N rms" for k, v in choice["after_diagnosis"].items())
                      + ".</p>")
    floor_text = (f" The residual floor is {d['residual_floor_n']:.3g} N: the force noise and the "
                  f"{d['stroke_noise_force_n']:.3g} N the stroke channel's noise makes through the model."
                  if d.get("residual_floor_n") else "")
    noise = d.get("noise") or {}
    if noise and not noise.get("credible", True):
        floor_text += (" The residual was not compared with it: "
                       + e(noise.get("text", "noise estimate not credible")) + ".")
    return (
        "<section id='diagnosis'><h2>Diagnosis: what the model gets wrong, and why</h2>"
        f"<p class='verdict'>{e(d['verdict'])}{'. ' + e(d['note']) if d.get('note') else ''}</p>"
        + base_text +
        "<p>Each candidate effect was added to the base model and the extended model refitted on the "
        "identification tests; the decision rests on the validation (held-out) MSE: score = -ln(MSE_ext / "
        f"MSE_base) - {s['penalty_per_parameter']} per extra parameter, a cause is named when its score exceeds "
        f"{s['accept_score']}.</p>"
        "<p>'none' is the base model refitted from the same starts with the same effort; every score is "
        "measured against it, so a refit's own progress is not credited to an effect. An effect whose force "
        f"contribution (fitted model minus the same with the effect off) is below the measurement noise "
        f"({e(noise.get('text') or format(d.get('noise_std_n', float('nan')), '.3g') + ' N')}) is not named.</p>"
        "<p>A cause is also significant: the 95 % confidence interval of its magnitude excludes zero. The "
        "interval comes from the identification residual's Jacobian by a block sandwich estimate (blocks of "
        "three residual correlation times), because the residuals are correlated and the textbook interval "
        "would be far too narrow. Causes are added one at a time (forward selection) while the next one "
        "earns its score against the model of the causes found so far. When the final model's residual stays "
        f"above {s.get('unexplained_ratio', 2)} x the residual floor, the report says so: a model-form error the "
        f"catalogue does not explain.{floor_text}</p>"
        f"<table>{head.format(ref=chr(39) + 'none' + chr(39))}{rows}</table>{steps}"
        + (f"<h3>Effect parameters vs plausible ranges</h3><table><tr><th>parameter</th><th>fitted</th>"
           f"<th>typical range</th><th>plausible</th></tr>{eff}</table>" if eff else "")
        + "<h3>Validation before and after</h3><table><tr><th>test</th><th>MSE before [N&sup2;]</th>"
          f"<th>MSE after [N&sup2;]</th><th>change</th><th>AME before [N]</th><th>AME after [N]</th></tr>{val}</table>"
        + (f"<h3>Residual evidence (base model)</h3><ul>{ev_rows}</ul>" if ev_rows else "")
        + _detection_html(d.get("detection_limits") or {})
        + figs + "</section>")



def vehicle_section_html(out_dir) -> str:
    """HTML section for ``out_dir/vehicle/vehicle.json`` (``tuner.job.vehicle_consequences``): the tuned
    FMUs as the vehicle's yaw dampers, side by side ('' when there is none)."""
    folder = Path(out_dir) / VEHICLE_FOLDER
    path = folder / "vehicle.json"
    if not path.exists():
        return ""
    data = json.loads(path.read_text())
    labels, rows = summary_rows(data)
    speeds = {lab: (r.get("critical_speed") or {}).get("critical_speed_kmh") for lab, r in data["results"].items()}
    speeds = {lab: v for lab, v in speeds.items() if v is not None}
    spread = ""
    if len(speeds) > 1:
        lo, hi = min(speeds, key=speeds.get), max(speeds, key=speeds.get)
        spread = (f"<p>The hunting critical speed ranges from {speeds[lo]:.0f} km/h ({_e(lo)}) to {speeds[hi]:.0f} "
                  f"km/h ({_e(hi)}): {speeds[hi] - speeds[lo]:.0f} km/h decided by the damper model alone, "
                  "each fitted to the same rig data.</p>")
    figs = "".join(_fig_html(f"{VEHICLE_FOLDER}/{name}.png", _e(desc), "")
                   for name, desc in data["scenarios"].items() if (folder / f"{name}.png").exists())
    return ("<section id='vehicle'><h2>In the vehicle: what the damper model changes</h2>"
            "<p>Each tuned FMU as the four yaw dampers of the campaign's 14-degree-of-freedom vehicle (two "
            f"bogies, four wheelsets, linear creep), stepped at {1e3 * data['step_s']:g} ms by the vehicle as "
            "master (<code>python -m tuner vehicle</code>). Critical speed: kick runs and bisection on the growth "
            "rate of the least damped mode; for the linear Maxwell FMU also the eigenvalues of the linear vehicle "
            "(eig). Damper force: the largest of the four dampers; bogie yaw relative to the track.</p>"
            + spread + _table(["quantity", *labels], [[_e(q), *(_e(c) for c in cells)] for q, cells in rows])
            + figs + "</section>")


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
