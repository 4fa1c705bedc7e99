"""Piecewise-linear characteristic tables F(x) with F(0) = 0.

A table is given by its non-zero abscissae and ordinates; the origin is inserted. Outside the
abscissa range the first/last segment is extended linearly. Evaluation is written for scalar
Python floats (the hot path of every engine): ``segment(x)`` returns the index of the linear
piece, and ``F(x) = intercept[i] + slope[i] * x`` on piece ``i``.
"""
from __future__ import annotations

from bisect import bisect_right
from typing import Sequence

__all__ = ["PwlTable"]


class PwlTable:
    """Piecewise-linear table through the origin.

    Parameters
    ----------
    abscissae : strictly increasing, with negative and positive values, zero excluded
        (element elongation [m] or elongation rate [m/s]).
    ordinates : forces [N] at ``abscissae``.
    """

    __slots__ = ("xs", "fs", "breaks", "intercept", "slope", "_p_anchor", "peak")

    def __init__(self, abscissae: Sequence[float], ordinates: Sequence[float]):
        if len(abscissae) != len(ordinates):
            raise ValueError("table abscissae and ordinates differ in length")
        xs = [float(x) for x in abscissae]
        fs = [float(f) for f in ordinates]
        pts = sorted(zip(xs, fs))
        if any(b[0] <= a[0] for a, b in zip(pts, pts[1:])) or xs != [p[0] for p in pts]:
            raise ValueError(f"table abscissae must be strictly increasing, got {xs}")
        if not (xs[0] < 0.0 < xs[-1]) or 0.0 in xs:
            raise ValueError("table abscissae must straddle zero and exclude it (F(0) = 0 is implied)")
        k = next(i for i, x in enumerate(xs) if x > 0.0)
        xs.insert(k, 0.0)
        fs.insert(k, 0.0)
        self.xs, self.fs = xs, fs
        #: the largest |ordinate| [N] (a model's force scale; the table does not change after it is made)
        self.peak = max(abs(f) for f in fs)
        # Interior breakpoints: piece i covers [breaks[i-1], breaks[i]); pieces 0 and n-2 extend
        # to -inf / +inf (linear extrapolation with the end segments).
        self.breaks = xs[1:-1]
        self.slope, self.intercept = [], []
        for i in range(len(xs) - 1):
            s = (fs[i + 1] - fs[i]) / (xs[i + 1] - xs[i])
            self.slope.append(s)
            self.intercept.append(fs[i] - s * xs[i])
        # primitive P(x) = integral of F from 0 to x at every node (exact: trapezoids)
        k0 = xs.index(0.0)
        p = [0.0] * len(xs)
        for i in range(k0 + 1, len(xs)):
            p[i] = p[i - 1] + 0.5 * (fs[i] + fs[i - 1]) * (xs[i] - xs[i - 1])
        for i in range(k0 - 1, -1, -1):
            p[i] = p[i + 1] - 0.5 * (fs[i] + fs[i + 1]) * (xs[i + 1] - xs[i])
        self._p_anchor = p

    def segment(self, x: float) -> int:
        """Index of the linear piece that contains ``x``."""
        return bisect_right(self.breaks, x)

    def __call__(self, x: float) -> float:
        i = bisect_right(self.breaks, x)
        return self.intercept[i] + self.slope[i] * x

    def primitive(self, x: float) -> float:
        """Integral of F from 0 to x (elastic energy [J] of a spring table, or the convex
        potential of a dashpot table) -- continuous and piecewise quadratic. Taken from the end of x's
        piece nearer the origin: from the far end, the node's primitive (joules) cancelled down to that of a
        micrometre stroke (1e-13 J) lost every digit of it."""
        i = bisect_right(self.breaks, x)
        j = i + 1 if self.xs[i + 1] <= 0.0 else i  # the node of piece i nearer the origin
        x0 = self.xs[j]
        return self._p_anchor[j] + self.intercept[i] * (x - x0) + 0.5 * self.slope[i] * (x * x - x0 * x0)

    def evaluate(self, x):
        """Vectorised evaluation for plotting and analysis (numpy array in, array out)."""
        import numpy as np

        x = np.asarray(x, dtype=float)
        i = np.searchsorted(np.asarray(self.breaks), x, side="right")
        return np.asarray(self.intercept)[i] + np.asarray(self.slope)[i] * x

    @property
    def is_monotonic(self) -> bool:
        """True when every piece has a non-negative slope (a passive, well-posed element)."""
        return min(self.slope) >= 0.0
