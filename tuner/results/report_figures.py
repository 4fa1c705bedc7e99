"""The fit report's figures drawn in one go (``draw_report_figures``), each by its key (``figure_keys``), in this
process or, with ``workers`` >= 2, in worker processes (``tuner.worker_processes``): the figures are independent
of each other and matplotlib draws one on one core (the bundled run's fifteen: about 7 s on one core).

Keys: ("forces", test, prefix) -> (src, zoom) of ``fit_figures.fig_forces``; ("loops", test), ("fitness",),
("constants",), ("tables",), ("poly",), ("intervals",) -> the src of the figure (``figures/<name>.png``) or None
when the folder lacks what it needs (``figure_html`` says why).
"""
from __future__ import annotations

from pathlib import Path

from tuner.results.fit_figures import (fig_constants, fig_fitness, fig_forces, fig_loops, fig_polyfit,
                                       fig_populations, polyfits)
from tuner.results.fit_folder import FitFolder
from tuner.results.html import NOT_DRAWN
from tuner.results.intervals_report import fig_characteristic_bands, model_intervals_of
from tuner.worker_processes import map_in_workers

__all__ = ["figure_keys", "draw_figure", "draw_report_figures", "undrawn_figures"]


def figure_keys(run: FitFolder) -> list[tuple]:
    """The keys of the figures of ``run``'s report (module docstring), the slowest first (three panels each)."""
    keys = []
    if run.sims is not None:
        for prefix, names in (("fig09_10", run.validation), ("fit", run.identification)):
            keys += [("forces", test, prefix) for test in names]
        keys += [("loops", test) for test in run.validation]
    keys.append(("fitness",))
    if "lumped" in run.models:
        keys += [("constants",), ("tables",), ("poly",)]
    keys.append(("intervals",))
    return keys


def draw_figure(key: tuple, run: FitFolder, fdir: Path, dpi: int):
    """Draw the figure ``key`` of ``run`` into ``fdir`` at ``dpi`` [dots/inch]; returns what the key gives."""
    kind = key[0]
    if kind == "forces":
        return fig_forces(run, key[1], fdir, dpi, key[2])
    if kind == "loops":
        return fig_loops(run, key[1], fdir, dpi)
    if kind == "fitness":
        return fig_fitness(run, fdir, dpi)
    if kind == "constants":
        return fig_constants(run, fdir, dpi)
    if kind == "tables":
        return fig_populations(run, fdir, dpi)
    if kind == "poly":
        return fig_polyfit(polyfits(run), fdir, dpi)
    if kind == "intervals":
        return fig_characteristic_bands(model_intervals_of(run), fdir, dpi)
    raise ValueError(f"no report figure {key!r}")


def draw_report_figures(run: FitFolder, fdir: Path, dpi: int, workers: int = 0) -> dict:
    """{key: what ``draw_figure`` gives} for every figure of ``run``'s report, drawn into ``fdir``; with ``workers``
    >= 2 in that many processes (the figures are the same files either way)."""
    keys = figure_keys(run)
    return dict(zip(keys, map_in_workers(draw_figure, keys, workers, (run, fdir, dpi))))


def undrawn_figures(run: FitFolder) -> dict:
    """The figures of a report written without them: ``draw_report_figures``'s keys, each ``html.NOT_DRAWN`` (the
    forces' with no zoom)."""
    return {key: (NOT_DRAWN, None) if key[0] == "forces" else NOT_DRAWN for key in figure_keys(run)}
