"""The report's figures laid out with margins fixed in inches, in place of matplotlib's constrained layout.

Why: the constrained layout measures every tick label, axis label and title twice before each figure is
drawn; that was 40-45 % of the figures' time (the fit report's ten figures of a fleet row: 3.7 s of CPU, 2.2 s
without it; the diagnosis's five: 4.5 s, 2.0 s of them the layout), and the report's figures are a fixed
set whose decorations are known: tick labels of a few characters, an axis label on the left and below, a
title above each axes. The margins below hold those; a figure with more (a title over the whole figure, a
second y axis on the right, a legend below the axes) asks for more where it has it.
"""
from __future__ import annotations

from matplotlib.figure import Figure

__all__ = ["fixed_margins", "LEFT_IN", "RIGHT_IN", "BOTTOM_IN", "TOP_IN", "HGAP_IN", "WGAP_IN", "SUPTITLE_IN", "TWIN_AXIS_IN"]

LEFT_IN = 0.9      # figure edge to the axes: y tick labels and the y axis label [in]
RIGHT_IN = 0.2     # axes to the right edge [in]
BOTTOM_IN = 0.6    # x tick labels and the x axis label [in]
TOP_IN = 0.35      # an axes title [in]
HGAP_IN = 0.8      # between two rows: the upper one's x labels and the lower one's title [in]
WGAP_IN = 0.95     # between two columns: the right one's y tick and axis labels [in]
SUPTITLE_IN = 0.3  # what a title over the whole figure adds at the top [in]
TWIN_AXIS_IN = 0.6  # what a second y axis on the right (ticks and label) adds at the right [in]


def fixed_margins(fig: Figure, *, left: float = LEFT_IN, right: float = RIGHT_IN, bottom: float = BOTTOM_IN,
                  top: float = TOP_IN, hgap: float = HGAP_IN, wgap: float = WGAP_IN) -> Figure:
    """Place the grid of axes of ``fig`` (made by ``fig.subplots``) with the given margins [in]: ``left``,
    ``right``, ``bottom``, ``top`` from the figure's edges to the axes, ``hgap`` and ``wgap`` between rows and
    columns. Returns ``fig``."""
    if not fig.axes:
        return fig
    width, height = fig.get_size_inches()
    rows, cols = fig.axes[0].get_subplotspec().get_gridspec().get_geometry()
    axes_h = (height - top - bottom - (rows - 1) * hgap) / rows  # mean axes height [in]
    axes_w = (width - left - right - (cols - 1) * wgap) / cols
    if axes_h <= 0 or axes_w <= 0:
        raise ValueError(f"fixed_margins: margins of {left + right} x {top + bottom} in leave no room for "
                         f"{rows} x {cols} axes in a figure of {width} x {height} in")
    # hspace and wspace are fractions of the mean axes height and width
    fig.subplots_adjust(left=left / width, right=1.0 - right / width, bottom=bottom / height,
                        top=1.0 - top / height, hspace=hgap / axes_h, wspace=wgap / axes_w)
    return fig
