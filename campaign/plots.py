"""Overview figure of a dataset folder: stroke, force and force-velocity of every test."""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["plot_dataset"]


def plot_dataset(folder, filename: str = "overview.png") -> Path:
    """Write ``folder/filename``: one row per test (stroke [mm], force [kN], force vs velocity)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from tuner.data.reading import load_dataset
    from tuner.data.preprocess import prepare

    tests = load_dataset(folder)
    fig = Figure(figsize=(13, 2.3 * len(tests) + 0.6))
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(tests), 3, squeeze=False, gridspec_kw={"width_ratios": [2.2, 2.2, 1.2]})
    for row, t in zip(axes, tests):
        p = prepare(t, t.sample_rate)
        row[0].plot(t.time, 1e3 * t.stroke, lw=0.8, color="tab:blue")
        row[0].set_ylabel("stroke [mm]")
        row[0].set_title(f"{t.name} ({t.role}): {t.scenario}", fontsize=8, loc="left")
        row[1].plot(t.time, 1e-3 * t.force, lw=0.6, color="tab:red")
        row[1].set_ylabel("force [kN]")
        row[2].plot(1e3 * p.stroke_velocity, 1e-3 * p.force, ".", ms=0.8, color="tab:purple", alpha=0.5)
        row[2].set_ylabel("force [kN]")
        for ax in row:
            ax.grid(alpha=0.3)
            ax.tick_params(labelsize=8)
    axes[-1][0].set_xlabel("time [s]")
    axes[-1][1].set_xlabel("time [s]")
    axes[-1][2].set_xlabel("stroke velocity [mm/s]")
    from tuner.data.reading import read_manifest

    title = read_manifest(folder).get("description", "dataset")
    fig.suptitle(f"{title}\nstrokes (extension +) and forces (tension +)", fontsize=9)
    fig.tight_layout()
    out = Path(folder) / filename
    fig.savefig(out, dpi=90, metadata={"Software": None})
    return out
