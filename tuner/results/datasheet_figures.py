"""The datasheet's figures (PNG), drawn from its record (``datasheet.json``, ``tuner.datasheet.sheet``): the
force-velocity characteristic of every FMU (with the measured points and the nominal band when there are), K' and
K'' against frequency per amplitude, and the loss angle. Simulated points are lines with small markers, measured
points large black-edged markers."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from damper_fmu.fmu import SLAVES
from tuner.results.figure_layout import SUPTITLE_IN, TOP_IN, fixed_margins
from tuner.results.html import MODEL_COLOR

__all__ = ["draw_datasheet_figures", "FIGURES"]

#: the figures' file names, by what they show
FIGURES = {"force_velocity": "datasheet_force_velocity.png", "dynamic_stiffness": "datasheet_dynamic_stiffness.png",
           "loss_angle": "datasheet_loss_angle.png"}
_COLORS = ("tab:purple", "tab:green", "tab:red", "tab:orange", "tab:blue", "tab:brown", "tab:olive", "tab:cyan")


def _color(label: str, i: int) -> str:
    """The report's colour of the model an FMU label names (``DamperLumped_tuned``: the lumped model's), else the
    ``i``-th of a fixed cycle."""
    kinds = sorted(SLAVES.items(), key=lambda kv: -len(kv[1]))  # the longest identifier first (MaxwellTable)
    kind = next((k for k, ident in kinds if label == ident or label.startswith(ident + "_")), None)
    return MODEL_COLOR.get(kind) or _COLORS[i % len(_COLORS)]


def _save(fig: Figure, path: Path, dpi: int) -> Path:
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=dpi)
    return path


def _measured(sheet: dict) -> list[dict]:
    """The measured points of the record (its sine tests), [] without."""
    return [p for p in (sheet.get("measured") or {}).get("points", [])]


def _outside(ax, sheet: dict) -> None:
    """Ring the points the nominal band judged outside (red circles)."""
    judged = [p for pts in ((sheet.get("nominal") or {}).get("judged") or {}).values() for p in pts
              if p["inside"] is False]
    if judged:
        ax.plot([p["velocity_m_s"] for p in judged], [p["force_n"] / 1e3 for p in judged], ls="none", marker="o",
                ms=11, mfc="none", mec="red", mew=1.2, label="outside the nominal band")


def _force_velocity(sheet: dict, path: Path, dpi: int) -> Path:
    fig = Figure(figsize=(8, 5))
    ax = fig.subplots()
    fixed_margins(fig)
    nominal = sheet.get("nominal")
    if nominal:
        for side in (-1.0, 1.0):  # each direction's band alone (none drawn across the origin)
            pts = [p for p in nominal["points"] if p["velocity_m_s"] * side > 0]
            v = np.array([p["velocity_m_s"] for p in pts])
            f = np.array([p["force_n"] for p in pts]) / 1e3
            tol = np.array([p["tolerance_pct"] for p in pts]) / 100
            tols = sorted({f"{p['tolerance_pct']:g}" for p in nominal["points"]})
            ax.fill_between(v, f - tol * np.abs(f), f + tol * np.abs(f), color="0.85", lw=0,
                            label=f"nominal ± {'/'.join(tols)} %" if side > 0 else None)
            ax.plot(v, f, color="0.5", lw=1, ls="--")
    for i, (label, ch) in enumerate(sheet["fmus"].items()):
        pts = ch["force_velocity"]
        ax.plot([p["velocity_m_s"] for p in pts], [p["force_n"] / 1e3 for p in pts], marker="o", ms=3, lw=1.3,
                color=_color(label, i), label=f"{label} (simulated)")
        twins = ch.get("measured_comparison", [])
        if twins:
            m = [c["model"] for c in twins]
            ax.plot([q["peak_velocity_m_s"] for q in m] + [-q["peak_velocity_m_s"] for q in m],
                    [q["force_extension_n"] / 1e3 for q in m] + [q["force_compression_n"] / 1e3 for q in m],
                    ls="none", marker="x", ms=7, mew=1.5, color=_color(label, i),
                    label=f"{label} at the measured points (simulated)")
    meas = _measured(sheet)
    if meas:
        v = [p["peak_velocity_m_s"] for p in meas] + [-p["peak_velocity_m_s"] for p in meas]
        f = [p["force_extension_n"] / 1e3 for p in meas] + [p["force_compression_n"] / 1e3 for p in meas]
        ax.plot(v, f, ls="none", marker="D", ms=7, mfc="none", mec="k", mew=1.5, label="measured (rig sine tests)")
    _outside(ax, sheet)
    ax.axhline(0, color="0.6", lw=0.6)
    ax.axvline(0, color="0.6", lw=0.6)
    ax.set_xlabel("peak velocity [m/s] (extension +)")
    ax.set_ylabel("force at peak velocity [kN] (tension +)")
    amp = sheet["settings"]["fv_amplitude_m"] * 1e3
    ax.set_title(f"Force-velocity characteristic (simulated: settled sines of {amp:g} mm)", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return _save(fig, path, dpi)


def _per_amplitude(sheet: dict, path: Path, dpi: int, keys: tuple, ylabels: tuple, scale: float, title: str) -> Path:
    """One row per FMU, one column per key of the dynamic points, a line per amplitude (log frequency axis)."""
    fmus = sheet["fmus"]
    rows, cols = max(1, len(fmus)), len(keys)
    fig = Figure(figsize=(4.6 * cols + 0.6, 2.6 * rows + 0.6))
    axes = np.atleast_2d(fig.subplots(rows, cols, squeeze=False))
    fixed_margins(fig, top=TOP_IN + SUPTITLE_IN)
    amplitudes = sorted({p["amplitude_m"] for ch in fmus.values() for p in ch["dynamic"]})
    meas = _measured(sheet)
    for r, (label, ch) in enumerate(fmus.items()):
        for c, key in enumerate(keys):
            ax = axes[r, c]
            for j, a in enumerate(amplitudes):
                pts = [p for p in ch["dynamic"] if p["amplitude_m"] == a]
                color = _amplitude_color(j, len(amplitudes))
                ax.plot([p["frequency_hz"] for p in pts], [p[key] * scale for p in pts], marker="o", ms=3,
                        color=color, label=f"{a * 1e3:g} mm")
            if meas:
                ax.plot([p["frequency_hz"] for p in meas], [p[key] * scale for p in meas], ls="none", marker="D",
                        ms=6, mfc="none", mec="k", mew=1.3, label="measured (its amplitude in mm beside)")
                for p in meas:
                    ax.annotate(f"{p['amplitude_m'] * 1e3:.2g}", (p["frequency_hz"], p[key] * scale), fontsize=6,
                                xytext=(4, 3), textcoords="offset points")
                twins = [c["model"] for c in ch.get("measured_comparison", [])]
                ax.plot([q["frequency_hz"] for q in twins], [q[key] * scale for q in twins], ls="none", marker="x",
                        ms=6, mew=1.3, color="k", label="model at the measured points")
            ax.set_xscale("log")
            ax.set_title(f"{label}", fontsize=9)
            ax.set_ylabel(ylabels[c])
            ax.grid(alpha=0.3, which="both")
            if r == rows - 1:
                ax.set_xlabel("frequency [Hz]")
    axes[0, -1].legend(fontsize=7, title="amplitude", title_fontsize=7)
    fig.suptitle(title, fontsize=10)
    return _save(fig, path, dpi)


def _amplitude_color(j: int, n: int):
    """The colour of the ``j``-th of ``n`` amplitudes (viridis, dark to light)."""
    return colormaps["viridis"](0.85 * j / max(1, n - 1))


def draw_datasheet_figures(sheet: dict, out: Path, dpi: int = 110) -> list[Path]:
    """The three figures of ``FIGURES`` for the datasheet record ``sheet`` into the folder ``out``."""
    out = Path(out)
    return [_force_velocity(sheet, out / FIGURES["force_velocity"], dpi),
            _per_amplitude(sheet, out / FIGURES["dynamic_stiffness"], dpi, ("storage_n_m", "loss_n_m"),
                           ("K' [MN/m]", "K'' [MN/m]"), 1e-6,
                           "Dynamic stiffness: storage K' and loss K'' against frequency, per amplitude"),
            _per_amplitude(sheet, out / FIGURES["loss_angle"], dpi, ("loss_angle_deg",), ("loss angle [deg]",), 1.0,
                           "Loss angle against frequency, per amplitude")]
