"""The global search's window of each identification test: the shortest start of the test that holds its whole
range twice.

The Firefly search ranks candidates to find the basin; the local refinement then solves on the whole tests. A
periodic rig test repeats its cycle: the 0.1 Hz sine of the real MR damper is 4.75 cycles, 47.5 s of the 76 s
of identification tests, and the search spent its 70 s mostly simulating repeats of one loop. Repeats average the
noise (the refinement's job, on all samples) but show the search no part of the characteristic it has not seen.

The window of a test: from its start to the counted sample by which the stroke and the stroke velocity have
reached both their extremes (within ``REACH`` of their span) a second time, all of it when they do not. Twice: the
first cover carries the start-up (rest, the warm-up of a lab filter), the second the settled loop.
A random or multibody-simulated stroke reaches its extremes late, so its window is (near) the whole test; a sine
is cut to about two cycles. The samples the low-pass cannot cover at the window's new end are not counted
(``Signals.band_limited_span``). Nothing else changes: same samples, same filters, same mask before the cut.
"""
from __future__ import annotations

import contextlib
import dataclasses

import numpy as np

from tuner.identification.engine import Engine, Signals

__all__ = ["search_window", "REACH", "SearchWindows", "search_windows"]

#: an extreme counts as reached within this fraction of the channel's span (noise, the sampling of a peak)
REACH = 0.05


@dataclasses.dataclass(frozen=True)
class SearchWindows:
    """The search's tests (``tests``: each a window of one identification test) and the durations [s] of the
    whole tests and of their windows, for the log."""

    tests: list
    whole_s: float
    window_s: float

    @property
    def cut(self) -> bool:
        """Whether any test is shorter than its whole length."""
        return self.window_s < self.whole_s

    def to_dict(self) -> dict:
        """The record in ``history_<model>.json``: the tests' and the windows' durations [s] (the search's fitness
        G, its Fig. 6, is on the windows)."""
        return {"whole_s": self.whole_s, "window_s": self.window_s,
                "tests": {s.name: _duration(s) for s in self.tests}}

    def keyed(self, data_digest: str) -> str:
        """The data's digest for the search's resume key: itself when nothing is cut (a search on whole tests
        resumes as before), else with the windows' length (a state searched on other windows is not resumed)."""
        if not self.cut:
            return data_digest
        return f"{data_digest}/search on {self.window_s:.9g} of {self.whole_s:.9g} s"

    def engine(self, whole, model: str, **kw):
        """A context manager giving an engine of ``model`` on the windows (``Engine`` keyword arguments ``kw``), or
        the engine ``whole`` of the whole tests itself when nothing is cut (one engine, no second worker pool)."""
        return Engine(model, self.tests, **kw) if self.cut else contextlib.nullcontext(whole)

    def text(self) -> str:
        """What the log says."""
        return (f"global search on each test's first {self.window_s:.3g} s of {self.whole_s:.3g} s (the start of each "
                f"test that covers its stroke and velocity range twice; the refinements use every sample)")


def search_window(s: Signals) -> Signals:
    """The window of ``s`` for the global search (module docstring): ``s`` itself when the window is the whole
    test, else a new ``Signals`` of the first samples with the low-pass's uncovered end not counted."""
    counted = np.flatnonzero(s.mask)
    if counted.size < 2:
        return s
    first = _covered(s, counted, 0)
    second = _covered(s, counted, first + 1) if first is not None else None
    if second is None:
        return s
    end = counted[second] + 1  # samples [0, end)
    if end >= len(s.time) - 1:
        return s
    cut = dataclasses.replace(
        s, time=s.time[:end], stroke=s.stroke[:end], stroke_velocity=s.stroke_velocity[:end], force=s.force[:end],
        mask=s.mask[:end].copy(), temperature=None if s.temperature is None else s.temperature[:end])
    k0, n = cut.band_limited_span()
    cut.mask[k0 + n:] = False
    cut.mask[:k0] = False
    return cut if cut.mask.sum() >= 2 else s


def search_windows(tests: list[Signals]) -> SearchWindows:
    """The windows of every identification test (``search_window``)."""
    cut = [search_window(s) for s in tests]
    return SearchWindows(cut, sum(_duration(s) for s in tests), sum(_duration(s) for s in cut))


def _covered(s: Signals, counted: np.ndarray, start: int) -> int | None:
    """The first of the ``counted`` samples, from the ``start``-th on, by which the stroke and the stroke velocity
    have come within ``REACH`` x their span of both the extremes they reach over all counted samples; None if they
    do not from there."""
    ends = []
    for x in (s.stroke[counted], s.stroke_velocity[counted]):
        tol = REACH * float(np.ptp(x))
        for near in (x[start:] >= x.max() - tol, x[start:] <= x.min() + tol):
            if not near.any():
                return None
            ends.append(start + int(np.argmax(near)))
    return max(ends)


def _duration(s: Signals) -> float:
    """The test's length [s]."""
    return float(s.time[-1] - s.time[0])
