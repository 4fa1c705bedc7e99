"""Overview figure of a dataset folder: stroke, force and force-velocity of every test."""
from __future__ import annotations

from pathlib import Path

import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from scipy.signal import savgol_filter

from damper_dataset.format import read_manifest

__all__ = ["plot_dataset"]

#: window of the Savitzky-Golay differentiator of the stroke velocity in the force-velocity panel [s]
VELOCITY_WINDOW_S = 0.02
#: the figure's margins [in]: left (y tick and axis labels), right, bottom (x labels), top (the two-line title),
#: between rows (the row's x tick labels and the next row's title) and between columns (y tick and axis labels).
#: Fixed, in place of matplotlib's tight layout, which measured every label first: 1.2 s of the figure's 2.6 s
MARGINS_IN = {"left": 0.7, "right": 0.15, "bottom": 0.5, "top": 0.95, "hgap": 0.55, "wgap": 0.75}


def plot_dataset(folder, filename: str = "overview.png") -> Path:
    """Write ``folder/filename``: one row per test (stroke [mm], force [kN], force vs velocity), read as
    ``damper_dataset.writer`` wrote it (SI units, manifest order)."""
    folder = Path(folder)
    manifest = read_manifest(folder)
    tests = manifest["tests"]
    fig = Figure(figsize=(13, 2.3 * len(tests) + 0.6))
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(tests), 3, squeeze=False, gridspec_kw={"width_ratios": [2.2, 2.2, 1.2]})
    for row, t in zip(axes, tests):
        d = pd.read_csv(folder / t["file"], comment="#")
        time, stroke, force = (d[c].to_numpy(float) for c in ("time", "stroke", "force"))
        rate = float(t["sample_rate_hz"])
        window = max(5, int(VELOCITY_WINDOW_S * rate) | 1)
        velocity = savgol_filter(stroke, window, 2, deriv=1, delta=1.0 / rate)
        row[0].plot(time, 1e3 * stroke, lw=0.8, color="tab:blue")
        row[0].set_ylabel("stroke [mm]")
        row[0].set_title(f"{t['name']} ({t['role']}): {t['scenario']}", fontsize=8, loc="left")
        row[1].plot(time, 1e-3 * force, lw=0.6, color="tab:red")
        row[1].set_ylabel("force [kN]")
        row[2].plot(1e3 * velocity, 1e-3 * force, ".", ms=0.8, color="tab:purple", alpha=0.5)
        row[2].set_ylabel("force [kN]")
        for ax in row:
            ax.grid(alpha=0.3)
            ax.tick_params(labelsize=8)
    axes[-1][0].set_xlabel("time [s]")
    axes[-1][1].set_xlabel("time [s]")
    axes[-1][2].set_xlabel("stroke velocity [mm/s]")
    title = manifest.get("description", "dataset")
    fig.suptitle(f"{title}\nstrokes (extension +) and forces (tension +)", fontsize=9)
    _fixed_margins(fig, len(tests))
    out = folder / filename
    fig.savefig(out, dpi=90, metadata={"Software": None})
    return out


def _fixed_margins(fig: Figure, rows: int) -> None:
    """Place the overview's grid of axes (``rows`` rows, three columns) with the margins ``MARGINS_IN`` [in]
    (wspace is a fraction of the mean axes width)."""
    m, (width, height) = MARGINS_IN, fig.get_size_inches()
    axes_h = (height - m["top"] - m["bottom"] - (rows - 1) * m["hgap"]) / rows
    axes_w = (width - m["left"] - m["right"] - 2 * m["wgap"]) / 3  # the mean axes width
    fig.subplots_adjust(left=m["left"] / width, right=1.0 - m["right"] / width, bottom=m["bottom"] / height,
                        top=1.0 - m["top"] / height, hspace=m["hgap"] / axes_h, wspace=m["wgap"] / axes_w)
