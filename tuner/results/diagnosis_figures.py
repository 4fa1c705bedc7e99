"""The diagnosis's figures: the base model's residual (``tuner.diagnosis.residuals``) in time, against
velocity and stroke, around velocity reversals, against frequency, its drift over the test and against
the temperature channel, and its map over the restoring-force plane, one set per base form diagnosed. The
job draws them (``tuner.job.write_diagnosis``) from the residual series a ``Diagnosis`` carries, into the
files its record lists.

Residual r = measured - simulated force [N] (+ tension), stroke [m] (+ extension), velocity [m/s], time
[s], temperature [degC]; the axes show mm, mm/s and kN where they say so.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from tuner.diagnosis.residual_map import MIN_BIN_SAMPLES, identification_only, map_summary, residual_map
from tuner.diagnosis.residual_signatures import knee_velocity
from tuner.diagnosis.residual_tests import GAP_WINDOW_S, PreparedTest, TestResidual, dot
from tuner.diagnosis.residuals import BANDS_HZ, FIGURE_TOPICS, figure_files, residual_summary, spectra, true_runs
from tuner.diagnosis.result import Diagnosis
from tuner.results.figure_layout import RIGHT_IN, SUPTITLE_IN, TOP_IN, TWIN_AXIS_IN, WGAP_IN, fixed_margins
from tuner.worker_processes import map_in_workers

__all__ = ["diagnosis_figures", "residual_figures"]

REVERSAL_SPAN_S = (-0.100, 0.200)  # reversal-average figure span [s]
DRIFT_WINDOW_S = 1.0             # windows of the drift figure [s]


def _finish(ax, xlabel, ylabel, title="", legend=False):
    ax.set(xlabel=xlabel, ylabel=ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3, which="both")
    if legend:
        ax.legend(fontsize=7)


def _drift_windows(p):
    """Per DRIFT_WINDOW_S window (>= half usable): mid time [s], rms r [N], gain m/F_sim, mean T [degC]."""
    k, t, rows = max(1, int(round(DRIFT_WINDOW_S * p.fs))), p.t, []
    for a in range(0, t.time.size, k):
        u = np.flatnonzero(p.use[a:a + k]) + a
        ff = t.simulated[u]
        if u.size >= k / 2 and dot(ff, ff) > 0:
            rows.append((t.time[u].mean(), np.sqrt(np.mean(p.r[u] ** 2)), dot(t.measured[u], ff) / dot(ff, ff),
                         np.mean(t.temperature[u]) if t.temperature is not None else np.nan))
    return np.array(rows).reshape(-1, 4).T


def diagnosis_figures(diagnosis: Diagnosis, out: Path, workers: int = 0) -> list[Path]:
    """The residual figures of every base form the diagnosis ran on (``Diagnosis.residuals``: the first base's
    in ``figures/``, a repeat's in ``figures/base_<kind>/``) into the output folder ``out``: the files its
    record lists (``figures``), drawn in ``workers`` processes when >= 2 (the same files). Returns their paths."""
    return [p for folder, tests in diagnosis.residuals.items()
            for p in residual_figures(tests, Path(out) / folder, workers=workers)]


def residual_figures(tests: list[TestResidual], out_dir: Path, prefix: str = "diag", workers: int = 0) -> list[Path]:
    """Write six PNGs to ``out_dir`` (identification solid, validation dashed), named by
    ``tuner.diagnosis.residuals.figure_files``, and return their paths: residual [N] in time over the
    measured force (grey: outside the mask); residual vs velocity and stroke; residual x sign(v after)
    averaged around velocity reversals with -F_sim; Welch spectra of residual and force; windowed rms
    residual and gain vs time and temperature; the restoring-force map of the identification tests (``map``).
    ``workers`` >= 2: drawn in that many processes (``tuner.worker_processes``), each figure on one core."""
    if not tests:
        raise ValueError("no tests given")
    preps, out_dir = [PreparedTest(t) for t in tests], Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    sty = [{"color": f"C{i % 10}", "ls": "-" if p.t.role == "identification" else "--",
            "label": f"{p.t.name} ({p.t.role[:5]}.)"} for i, p in enumerate(preps)]
    jobs = list(zip(FIGURE_TOPICS, (Path(f) for f in figure_files(out_dir, prefix))))
    map_in_workers(_draw, jobs, workers, (preps, sty))
    return [path for _, path in jobs]


def _draw(job: tuple, preps: list, sty: list) -> None:
    """Draw the figure of ``job`` (topic, path) from the prepared tests and their line styles."""
    topic, path = job
    fig = DRAWINGS[topic](preps, sty)
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=110)


def _figure_time(preps: list, sty: list) -> Figure:
    """Residual [N] in time over the measured force (grey: outside the mask), one panel per test."""
    fig = Figure(figsize=(10, 1.2 + 2.0 * len(preps)))
    axes = fig.subplots(len(preps), 1, squeeze=False)[:, 0]
    fixed_margins(fig, right=RIGHT_IN + TWIN_AXIS_IN)  # the measured force's axis on the right
    for p, st, ax in zip(preps, sty, axes):
        t, g, bx = p.t, residual_summary([p]), ax.twinx()
        bx.plot(t.time, t.measured / 1e3, color="0.75", lw=0.6)
        bx.set_ylabel("measured [kN]", color="0.6", fontsize=8)
        ax.set_zorder(bx.get_zorder() + 1)
        ax.patch.set_visible(False)
        ax.plot(t.time, p.r, lw=0.7, **st)
        for a, b in true_runs(~t.mask):
            ax.axvspan(t.time[a], t.time[b - 1], color="0.9", lw=0, zorder=0)
        _finish(ax, "time [s]", "residual [N]", f"{t.name} ({t.role}): rms residual {g['rms_residual']:.0f} N "
                f"= {g['residual_pct'] or 0:.1f} % of the force rms")
    return fig


def _figure_loops(preps: list, sty: list) -> Figure:
    """Residual [N] against velocity and stroke (the residual loops)."""
    fig = Figure(figsize=(11, 4.5))
    axs = fig.subplots(1, 2, sharey=True)
    fixed_margins(fig, wgap=0.3)  # the y axis is shared: no labels between the two
    for p, st in zip(preps, sty):
        for ax, x in zip(axs, (p.t.velocity, p.t.stroke)):
            ax.plot(np.where(p.use, x, np.nan) * 1e3, p.r, lw=0.4, alpha=0.8, **st)
    _finish(axs[0], "damper velocity [mm/s] (+ extension)", "residual measured - simulated [N] (+ tension)",
            "residual vs velocity (F-v residual loop)", legend=True)
    _finish(axs[1], "stroke [mm] (+ extension)", "", "residual vs stroke (F-x residual loop)")
    return fig


def _figure_reversals(preps: list, sty: list) -> Figure:
    """Residual x sign(v after) averaged around velocity reversals, with -F_sim."""
    tau = np.arange(*np.rint(np.array(REVERSAL_SPAN_S) * 1e3 + [0, 1]).astype(int)) * 1e-3
    fig = Figure(figsize=(9, 4.8))
    ax, rr, ff = fig.subplots(), [], []
    fixed_margins(fig)
    for p, st in zip(preps, sty):
        idx, s = p.stack(tau)
        if len(idx):
            rr.append(s[:, None] * p.r[idx])
            ff.append(-s[:, None] * p.t.simulated[idx])
            ax.plot(tau * 1e3, rr[-1].mean(0), lw=1.0, **{**st, "label": st["label"] + f", {len(idx)} reversals"})
    if rr:
        ax.plot(tau * 1e3, np.concatenate(rr).mean(0), color="k", lw=2, label="residual, all tests")
        ax.plot(tau * 1e3, np.concatenate(ff).mean(0), color="0.5", lw=2, ls=":",
                label="-F_sim, all tests (free play: the residual follows it)")
        ax.set_ylim(np.array([-1.4, 1.4]) * max(np.abs(r.mean(0)).max() for r in rr) + [-1, 1])
    ax.axvspan(0, GAP_WINDOW_S * 1e3, color="tab:blue", alpha=0.07, lw=0)
    _finish(ax, "time from velocity reversal [ms]", "force x sign(v after reversal) [N]",
            "residual averaged around velocity reversals (shaded: free-play window)"
            + ("" if rr else ": no reversals in the masked samples"), legend=bool(rr))
    return fig


def _figure_spectra(preps: list, sty: list) -> Figure:
    """Welch spectra of residual and force, and their ratio."""
    fig = Figure(figsize=(11, 4.5))
    a1, a2 = fig.subplots(1, 2, sharex=True)
    fixed_margins(fig)
    top = 0.0
    for p, st in zip(preps, sty):
        if (s := spectra(p)) is not None:
            f, pr, pf = (x[1:] for x in s)
            a1.loglog(f, pr, lw=0.9, **st)
            a1.loglog(f, pf, lw=0.6, alpha=0.3, color=st["color"])
            a2.loglog(f, pr / np.maximum(pf, 1e-300), lw=0.9, **st)
            top = max(top, pr.max(), pf.max())
    for ax in (a1, a2):
        for lo, _ in list(BANDS_HZ.values())[1:]:
            ax.axvline(lo, color="k", lw=0.6, ls=":")
    if top > 0:
        a1.set_ylim(1e-9 * top, 3 * top)
    _finish(a1, "frequency [Hz]", "PSD [N^2/Hz]", "residual (lines) and measured force (faint), Welch", True)
    _finish(a2, "frequency [Hz]", "residual / force PSD [-]", "residual-to-force spectral ratio")
    return fig


def _figure_drift(preps: list, sty: list) -> Figure:
    """Windowed rms residual and force gain against time and temperature."""
    hot = any(p.t.temperature is not None for p in preps)
    fig = Figure(figsize=(5 + 4 * hot, 6))
    axs = fig.subplots(2, 1 + hot, squeeze=False)
    fixed_margins(fig)
    for p, st in zip(preps, sty):
        w = _drift_windows(p)
        for j in range(1 + (p.t.temperature is not None)):
            for i in (0, 1):
                axs[i, j].plot(w[3 * j], w[1 + i], marker=".", ms=3, lw=0.8, **st)
    for j, xl in enumerate(["time [s]", "temperature [degC]"][:1 + hot]):
        _finish(axs[0, j], "", f"rms residual per {DRIFT_WINDOW_S:g} s [N]",
                "drift (thermal signature)" if j == 0 else "", legend=j == 0)
        _finish(axs[1, j], xl, "force gain measured / simulated [-]")
    return fig


def _map_title(summary: dict) -> str:
    """The map's shares (``map_summary``) in two lines: each region's share of the power and of the time."""
    reg, b = summary["regions"], summary["branch_asymmetry"]
    band = reg["stroke_band"]

    def share(name, d):
        return f"{name} {100 * d['power_share']:.0f} % of the power in {100 * d['time_share']:.0f} % of the time"
    return (" | ".join([share("near reversal", reg["near_reversal"]), share("stroke ends", reg["stroke_ends"]),
                        share(f"stroke {1e3 * band['stroke_from_m']:.3g} to {1e3 * band['stroke_to_m']:.3g} mm",
                              band)]) + "\n"
            + share(f"above the knee ({1e3 * reg['above_knee']['knee_velocity_m_s']:.3g} mm/s)", reg["above_knee"])
            + f" | the branches differ by {100 * b['power_share']:.0f} % of the power"
            + (" (a hysteresis)" if b["hysteresis"] else ""))


def _figure_map(preps: list, sty: list) -> Figure:
    """The restoring-force map of the identification tests' residual (``residual_map``): rms residual [N] over
    stroke x velocity, and mean and rms residual [N] over velocity on the a >= 0 and a < 0 branches."""
    fig = Figure(figsize=(12.5, 5.2))
    a1, a2 = fig.subplots(1, 2)
    fixed_margins(fig, top=TOP_IN + 2 * SUPTITLE_IN, wgap=WGAP_IN + 1.5)  # the colour bar between the panels
    ids = identification_only(preps)
    if not ids:
        fig.suptitle("no identification test: no map", fontsize=10)
        return fig
    m = residual_map(ids)
    mesh = a1.pcolormesh(m.velocity_edges_m_s * 1e3, m.stroke_edges_m * 1e3, np.ma.masked_invalid(m.rms_n),
                         cmap="viridis", shading="flat")
    fig.colorbar(mesh, cax=a1.inset_axes([1.03, 0.0, 0.035, 1.0]), label="rms residual [N]")
    _finish(a1, "damper velocity [mm/s] (+ extension)", "stroke [mm] (+ extension)",
            f"rms residual over stroke x velocity (blank: < {MIN_BIN_SAMPLES} samples)")
    v = 0.5 * (m.velocity_edges_m_s[1:] + m.velocity_edges_m_s[:-1]) * 1e3
    for row, (label, color) in enumerate((("acceleration >= 0", "C0"), ("acceleration < 0", "C3"))):
        a2.plot(v, m.branch_mean_n[row], marker="o", ms=3, color=color, label=f"mean, {label}")
        a2.plot(v, m.branch_rms_n[row], ls="--", lw=0.9, color=color, label=f"rms, {label}")
    a2.axhline(0.0, color="k", lw=0.6)
    _finish(a2, "damper velocity [mm/s] (+ extension)", "residual [N] (+ tension)",
            "residual on the two branches of the loop", legend=True)
    fig.suptitle(_map_title(map_summary(ids, knee_velocity(preps))), fontsize=9)
    return fig


#: the drawing of each figure topic (``FIGURE_TOPICS``): (prepared tests, line styles) -> Figure
DRAWINGS = {"time": _figure_time, "loops": _figure_loops, "reversals": _figure_reversals,
            "spectra": _figure_spectra, "drift": _figure_drift, "map": _figure_map}
