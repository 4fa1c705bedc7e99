"""The fit report's figures (PNG; the paper's Figs. 6-11 and the loops), from a ``FitFolder``. Errors are measured
minus simulated force [N]; samples before the warm-up are drawn shaded."""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from damper_fmu.parameters import MODEL_PARAMETERS
from damper_fmu.tables import PwlTable
from tuner.formatting import eng
from tuner.metrics import polyfit_odd_even
from tuner.results.figure_layout import SUPTITLE_IN, TOP_IN, fixed_margins
from tuner.results.fit_folder import FitFolder
from tuner.results.html import MODEL_COLOR, MODEL_LABEL, safe_name


__all__ = ["fig_forces", "fig_loops", "fig_fitness", "fig_constants", "fig_populations", "fig_polyfit", "polyfits", "bound_position", "bounds_of", "is_log", "loop_velocity"]

CONSTANTS = ("M_C", "M_O", "M_P", "k_B", "c_B")
ZOOM_WINDOW_S = 1.5             # zoom panel width [s]
LOOP_DIFF_WINDOW_S = 0.02       # Savitzky-Golay window for the loop velocity [s]

def _save(fig: Figure, path: Path, dpi: int) -> str:
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=dpi)
    return f"figures/{path.name}"


def _mark_warmup(ax, t, warmup):
    if warmup > 0 and t.size:
        ax.axvspan(t[0], min(t[0] + warmup, t[-1]), color="0.9", zorder=0, lw=0)


def fig_forces(run: FitFolder, test: str, fdir: Path, dpi: int, prefix: str):
    """Figs. 9-10 of one test: forces, differences, zoom around the lumped model's largest error."""
    s = run.series(test)
    if s is None:
        return None, None
    t, _, f, sim = s
    valid = (t - t[0]) >= run.warmup
    if not valid.any():
        valid = np.ones_like(t, dtype=bool)
    ref = "lumped" if "lumped" in sim else (next(iter(sim)) if sim else None)
    fig = Figure(figsize=(10, 8.2))
    ax1, ax2, ax3 = fig.subplots(3, 1, gridspec_kw={"height_ratios": [1.2, 1, 1.2]})
    fixed_margins(fig)
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
    src = _save(fig, fdir / f"{prefix}_{safe_name(test)}.png", dpi)
    return src, zoom


def loop_velocity(t, x):
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


def fig_loops(run: FitFolder, test: str, fdir: Path, dpi: int):
    """Force-stroke and force-velocity loops, measured vs lumped (after warm-up)."""
    s = run.series(test)
    if s is None or "lumped" not in s[3]:
        return None
    t, x, f, sim = s
    v = loop_velocity(t, x)
    keep = (t - t[0]) >= run.warmup
    fig = Figure(figsize=(10, 4.2))
    a1, a2 = fig.subplots(1, 2, sharey=True)
    fixed_margins(fig, wgap=0.3)  # the y axis is shared: no labels between the two
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
    return _save(fig, fdir / f"loops_{safe_name(test)}.png", dpi)


def fig_fitness(run: FitFolder, fdir: Path, dpi: int):
    """Fig. 6: mean fitness of the population per iteration and best-ever, per model."""
    hist = {m: h for m, h in run.histories.items() if h and h.get("mean_fitness")}
    if not hist:
        return None
    fig = Figure(figsize=(8, 4.5))
    ax = fig.subplots()
    fixed_margins(fig)
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


def bounds_of(run: FitFolder, model: str) -> dict[str, tuple[float, float]]:
    spec = {p.name: (p.low, p.high) for p in MODEL_PARAMETERS.get(model, ()) if p.tunable}
    spec.update({k: tuple(map(float, v)) for k, v in (run.params.get(model) or {}).get("bounds", {}).items()})
    return spec


def is_log(model: str, name: str) -> bool:
    return any(p.name == name and p.log_scale for p in MODEL_PARAMETERS.get(model, ()))


def fig_constants(run: FitFolder, fdir: Path, dpi: int):
    """Fig. 7: M_C, M_O, M_P, k_B, c_B of initial vs final population, normalised to bounds."""
    h = run.histories.get("lumped")
    if not h or not h.get("initial_population") or not h.get("final_population"):
        return None
    b = bounds_of(run, "lumped")
    best = run.values("lumped")
    rng = np.random.default_rng(0)
    fig = Figure(figsize=(9, 4.5))
    ax = fig.subplots()
    fixed_margins(fig, bottom=1.4)  # four-line tick labels and the legend below them
    labels = []
    for i, name in enumerate(CONSTANTS):
        lo, hi = b[name]
        lg = is_log("lumped", name)
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


def fig_populations(run: FitFolder, fdir: Path, dpi: int):
    """Fig. 8: Fk,O and Fc,O of initial and final population, full range and small-amplitude zoom."""
    h = run.histories.get("lumped")
    if not h or not h.get("initial_population") or not h.get("final_population"):
        return None
    best = run.values("lumped")
    fig = Figure(figsize=(10, 7.5))
    axes = fig.subplots(2, 2)
    fixed_margins(fig, top=TOP_IN + SUPTITLE_IN)
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


def polyfits(run: FitFolder):
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


def fig_polyfit(fits: dict, fdir: Path, dpi: int):
    """Fig. 11: identified terms, linear fit, odd and even parts of the 5th-order fit, Fk zoom."""
    if not fits:
        return None
    panels = [(k, False) for k in ("Fk", "Fc") if k in fits] + ([("Fk", True)] if "Fk" in fits else [])
    fig = Figure(figsize=(4.2 * len(panels), 4.4))
    axes = np.atleast_1d(fig.subplots(1, len(panels)))
    fixed_margins(fig, top=TOP_IN + SUPTITLE_IN)
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
