"""The held profile of a nonsmooth effect's magnitude (tuner.diagnosis.held_profiles.held_profile, nonsmooth_profiles)
on objectives whose minimum is known in closed form.

A fake engine: the residual [N] is a known function of the free play alone (the Maxwell base's two parameters
do not enter it, so each held value's re-fit ends where it starts), 50 samples.
"""
import math

import numpy as np
import pytest

from tuner.diagnosis.extended_parametrization import ExtendedParametrization
from tuner.diagnosis.held_profiles import (FAR_WORSE, HELD_PATIENCE, HeldSweep, SeriesTargets, held_profile,
                                           nonsmooth_profiles, series_profiles, sweep_gain)
from tuner.identification.parametrization import Parametrization

N = 50
GAP = 0.5e-3  # [m] the minimum of the profile objective


class GapEngine:
    """Residuals [N] of a function of the free play [m] only."""

    def __init__(self, residual_of_gap):
        self.residual_of_gap, self.n_samples = residual_of_gap, N

    def residuals_batch(self, points):
        return [np.full(N, self.residual_of_gap(float(p["free_play"]))) for p in points]


def ext_and_start():
    ext = ExtendedParametrization(Parametrization("maxwell", force_limit=4e4), "free_play", peak_force=2e4)
    return ext, np.full(ext.dimension, 0.5)


def coordinates(ext, gaps_m):
    lo, hi = ext.extra_bounds[0]
    return [(g - lo) / (hi - lo) for g in gaps_m]


def test_a_start_where_the_held_effect_only_makes_the_fit_worse_is_left_after_the_patience():
    """From a start that fits better without the effect (SSE sse_off) than with it at any value, the sweep stops
    after HELD_PATIENCE values and no vertex is tried; counted against the best value alone, it went one further."""
    ext, z0 = ext_and_start()
    eng = GapEngine(lambda g: 10.0 + 1e5 * g)  # 10 N without the gap, worse with any
    sse_off = N * 10.0 ** 2
    values = coordinates(ext, np.geomspace(0.1e-3, 1.5e-3, 8))
    held = held_profile(eng, ext, z0, 0, values, sse_off)
    assert len(held.points) == HELD_PATIENCE
    assert min(held.sse) > sse_off
    assert len(held_profile(eng, ext, z0, 0, values).points) == HELD_PATIENCE + 1  # no reference: the first is best
    pts = [np.r_[z0[:2], v] for v in values]
    sse = [N * eng.residual_of_gap(ext.to_params(z)["free_play"]) ** 2 for z in pts]
    out = nonsmooth_profiles(eng, ext, [z0], pts, sse, None, sse_off)
    assert len(out.points) == HELD_PATIENCE  # the sweep only: no vertex


def test_a_start_where_the_held_effect_fits_far_worse_is_left_at_once_when_a_fresh_start_follows():
    """Held at any gap, the start leaves more than FAR_WORSE x the SSE without it (the RMSE 2.2x): with a start
    that has absorbed nothing to follow, its sweep ends after the first value and the other start's whole-grid
    profile runs; alone (no other start) the sweep keeps its patience; a start only a little worse keeps it too."""
    ext, z0 = ext_and_start()
    far_worse = GapEngine(lambda g: 22.0 + 1e4 * g if g > 0 else 10.0)  # 22-37 N with the gap, 10 N without
    sse_off = N * 10.0 ** 2
    values = coordinates(ext, np.geomspace(0.1e-3, 1.5e-3, 8))
    assert far_worse.residual_of_gap(0.1e-3) ** 2 > FAR_WORSE * 10.0 ** 2
    pts = [np.r_[z0[:2], v] for v in values]
    sse = [N * far_worse.residual_of_gap(ext.to_params(z)["free_play"]) ** 2 for z in pts]
    both = nonsmooth_profiles(far_worse, ext, [z0, z0.copy()], pts, sse, None, sse_off)
    alone = nonsmooth_profiles(far_worse, ext, [z0], pts, sse, None, sse_off)
    assert len(alone.points) == HELD_PATIENCE
    # the sweep's first value, the coarse grid, two fine values (the coarse best is the smallest: it and the mean
    # with its neighbour); no vertex (nothing beat the model without the gap)
    assert len(both.points) == 1 + len(values) + 2
    a_little_worse = GapEngine(lambda g: 12.0 + 1e3 * g if g > 0 else 10.0)  # 12-13.5 N: below FAR_WORSE
    sse = [N * a_little_worse.residual_of_gap(ext.to_params(z)["free_play"]) ** 2 for z in pts]
    both = nonsmooth_profiles(a_little_worse, ext, [z0, z0.copy()], pts, sse, None, sse_off)
    assert len(both.points) == HELD_PATIENCE + len(values) + 2


def test_a_profile_that_beats_the_model_without_the_effect_is_swept_past_its_minimum_and_refined():
    """A minimum at GAP [m] (the residual quadratic in log(gap / GAP)): the sweep runs through it, stops
    HELD_PATIENCE values after the best, and the vertex of the parabola lands on GAP."""
    ext, z0 = ext_and_start()
    eng = GapEngine(lambda g: 1.0 + 5.0 * math.log(g / GAP) ** 2 if g > 0 else 1e3)
    sse_off = N * 20.0 ** 2
    gaps = np.geomspace(0.2e-3, 2e-3, 9)
    values = coordinates(ext, gaps)
    held = held_profile(eng, ext, z0, 0, values, sse_off)
    best = int(np.argmin(held.sse))
    assert len(held.points) == best + 1 + HELD_PATIENCE
    assert abs(math.log(ext.to_params(held.points[best])["free_play"] / GAP)) <= 0.5 * math.log(gaps[1] / gaps[0])
    pts = [np.r_[z0[:2], v] for v in values]
    sse = [N * eng.residual_of_gap(ext.to_params(z)["free_play"]) ** 2 for z in pts]
    out = nonsmooth_profiles(eng, ext, [z0], pts, sse, None, sse_off)
    k = int(np.argmin(out.sse))
    assert ext.to_params(out.points[k])["free_play"] == pytest.approx(GAP, rel=0.05)


def test_a_sweep_that_creeps_below_the_datas_resolution_stops_after_the_patience_and_a_real_fall_is_followed():
    """A profile that falls by 0.01 N of RMSE per value (a flat profile on data whose RMSE has a standard error of
    1 N): counted against the best by any fall, the chained sweep runs through every value; by the data's resolution
    (``sweep_gain``: a quarter of the standard error), it stops after HELD_PATIENCE values and, its best within the
    resolution of the model without the effect, tries no vertex. A minimum whose fall from value to value is far
    above the resolution is swept to it and past it by HELD_PATIENCE values alike."""
    ext, z0 = ext_and_start()
    gaps = np.geomspace(0.05e-3, 1.5e-3, 10)
    values = coordinates(ext, gaps)
    creep = GapEngine(lambda g: 20.0 - 0.01 * float(np.searchsorted(gaps, g * (1 + 1e-9))) if g > 0 else 20.0)
    sse_off = N * 20.0 ** 2
    gain = sweep_gain(1.0)
    assert 0.01 < gain < 1.0
    every = held_profile(creep, ext, z0, 0, values, sse_off, sweep=HeldSweep(chained=True))
    resolved = held_profile(creep, ext, z0, 0, values, sse_off, sweep=HeldSweep(chained=True, gain_n=gain))
    assert len(every.points) == len(values)
    assert len(resolved.points) == HELD_PATIENCE
    pts = [np.r_[z0[:2], v] for v in values]
    sse = [N * creep.residual_of_gap(ext.to_params(z)["free_play"]) ** 2 for z in pts]
    out = nonsmooth_profiles(creep, ext, [z0], pts, sse, None, sse_off, gain)
    assert len(out.points) == HELD_PATIENCE  # no vertex: the best is within the resolution of no gap
    dip = GapEngine(lambda g: 1.0 + 5.0 * math.log(g / GAP) ** 2 if g > 0 else 1e3)
    held = held_profile(dip, ext, z0, 0, values, N * 20.0 ** 2, sweep=HeldSweep(chained=True, gain_n=gain))
    best = int(np.argmin(held.sse))
    assert abs(math.log(gaps[best] / GAP)) <= 0.5 * math.log(gaps[1] / gaps[0])
    assert len(held.points) == min(best + 1 + HELD_PATIENCE, len(values))


def test_the_start_that_absorbed_nothing_profiles_the_whole_grid_and_finds_a_minimum_beyond_a_flat_stretch():
    """Flat (slowly rising) over the small gaps, a narrow minimum at GAP: the sweep from the grid profile's best
    (the base re-balanced linearly pointed at the smallest value, as on a base that had absorbed the gap) gives up
    on the flat stretch; the whole-grid profile of the second start finds GAP."""
    ext, z0 = ext_and_start()
    eng = GapEngine(lambda g: 10.0 + 1e3 * g - 9.5 * math.exp(-(math.log(g / GAP) / 0.3) ** 2) if g > 0 else 10.0)
    sse_off = N * 10.0 ** 2
    values = coordinates(ext, np.geomspace(0.04e-3, 2e-3, 7))
    pts = [np.r_[z0[:2], v] for v in values]
    sse = [sse_off * (0.9 + 0.01 * j) for j in range(len(pts))]  # the base re-balanced pointed at the smallest
    swept_only = nonsmooth_profiles(eng, ext, [z0], pts, sse, None, sse_off)
    assert max(ext.to_params(p)["free_play"] for p in swept_only.points) < 0.2e-3  # gave up on the flat stretch
    both = nonsmooth_profiles(eng, ext, [z0, z0.copy()], pts, sse, None, sse_off)
    k = int(np.argmin(both.sse))
    assert ext.to_params(both.points[k])["free_play"] == pytest.approx(GAP, rel=0.1)


class AbsorbingEngine:
    """Residuals [N] of a base that absorbs the gap: the base coordinate u (the first search coordinate) fits
    best at u*(g) = U0 + SLOPE * g / 1 mm, inside a ripple of local minima every RIPPLE in u (the
    first 25 samples), with a weak pull to u*(g) (the next 24) and the gap's own term, least at GAP (the last)."""

    U0, SLOPE, RIPPLE = 0.3, 0.14, 0.03

    def __init__(self, ext):
        self.ext, self.n_samples = ext, N

    def residuals_batch(self, points):
        out = []
        for p in points:
            g = float(p["free_play"])
            d = float(self.ext.from_params(p)[0]) - (self.U0 + self.SLOPE * g / 1e-3)
            out.append(np.r_[np.full(25, 100.0 * math.sin(math.pi * d / self.RIPPLE)), np.full(24, 100.0 * d),
                             [50.0 * (g - GAP) / GAP]])
        return out


def test_a_chained_profile_follows_what_the_base_absorbed_where_a_refit_from_the_start_is_caught():
    """The base's best coordinate moves with the gap (u*(g), known in closed form) across a ripple of local
    minima: held at GAP, a re-fit from the start (u*(0)) stops in the ripple's nearest minimum, away from u*(GAP);
    chained through gaps that move u* by a quarter of the ripple at a time, the profile stays on u*(g) and ends
    at the global minimum (SSE 0)."""
    ext, z0 = ext_and_start()
    z0[0] = AbsorbingEngine.U0
    eng = AbsorbingEngine(ext)
    sse_off = float(np.sum(eng.residuals_batch([ext.to_params(np.r_[z0[:2], 0.0])])[0] ** 2))
    values = coordinates(ext, np.linspace(0.05e-3, GAP, 10))
    alone = held_profile(eng, ext, z0, 0, values[-1:], sse_off)
    chained = held_profile(eng, ext, z0, 0, values, sse_off, sweep=HeldSweep(chained=True))
    u_star = AbsorbingEngine.U0 + AbsorbingEngine.SLOPE * GAP / 1e-3
    assert abs(alone.points[0][0] - u_star) > 0.5 * AbsorbingEngine.RIPPLE  # caught in the ripple
    assert alone.sse[0] > 0.1 * sse_off
    assert chained.points[-1][0] == pytest.approx(u_star, abs=1e-3)
    assert chained.sse[-1] < 1e-3 * alone.sse[0]


class SeriesEngine:
    """Residuals [N] of a model whose series stiffness k_s [N/m] fits best at K_STAR inside a ripple of local
    minima every RIPPLE in its search coordinate u (log-scaled: 0.25 a decade; the first 25 samples), with a weak
    pull to K_STAR (the next 24) and the gap's own term, least at GAP (the last)."""

    K_STAR, RIPPLE = 6.31e7, 0.05

    def __init__(self, ext):
        self.ext, self.n_samples = ext, N
        self.u_star = float(ext.base.from_params({"k_s": self.K_STAR, "c": 5e5})[0])

    def residuals_batch(self, points):
        out = []
        for p in points:
            g = float(p["free_play"])
            d = float(self.ext.base.from_params(p)[0]) - self.u_star
            out.append(np.r_[np.full(25, 100.0 * math.sin(math.pi * d / self.RIPPLE)), np.full(24, 100.0 * d),
                             [50.0 * (g - GAP) / GAP]])
        return out


def test_the_series_element_held_a_decade_up_lets_the_gap_profile_reach_what_a_refit_from_the_base_cannot():
    """The base's series stiffness is caught in the ripple far below K_STAR: held at GAP, a re-fit from the base
    ends in the nearest local minimum. Held at a stiffness within half a ripple of K_STAR, the gap's profile finds
    GAP and the series element, released there, ends on K_STAR (SSE 0); held a decade away, it is caught again."""
    ext, z0 = ext_and_start()
    eng = SeriesEngine(ext)
    z0[0] = eng.u_star - 0.4  # 1.6 decades soft of K_STAR
    sse_off = float(np.sum(eng.residuals_batch([ext.to_params(np.r_[z0[:2], 0.0])])[0] ** 2))
    values = coordinates(ext, np.geomspace(0.1e-3, 1.5e-3, 8))
    from_base = held_profile(eng, ext, z0, 0, coordinates(ext, [GAP]), sse_off)
    assert from_base.sse[0] > 0.1 * sse_off
    near = series_profiles(eng, ext, z0, 0, values, [{"k_s": 6.0e7}], SeriesTargets(sse_off))
    k = int(np.argmin(near.sse))
    assert ext.to_params(near.points[k])["k_s"] == pytest.approx(SeriesEngine.K_STAR, rel=0.01)
    assert ext.to_params(near.points[k])["free_play"] == pytest.approx(GAP, rel=0.05)
    assert near.sse[k] < 1e-3 * from_base.sse[0]
    far = series_profiles(eng, ext, z0, 0, values, [{"k_s": 6.0e6}], SeriesTargets(sse_off))
    assert min(far.sse) > 0.1 * from_base.sse[0]


def test_the_coarse_passes_on_the_windows_decide_the_release_and_the_releases_run_on_every_sample():
    """With the coarse passes on another engine (the search's windows of the tests), the release is judged by its
    own SSE there (``coarse_sse_off``): a bar no gap clears there releases nothing, whatever the tests would show;
    a bar it clears releases, and the release on the tests' engine ends on K_STAR and GAP. The coarse points are
    not among the profile's (their SSE is not on the tests' samples)."""
    ext, z0 = ext_and_start()
    eng, windows = SeriesEngine(ext), SeriesEngine(ext)
    z0[0] = eng.u_star - 0.4
    sse_off = float(np.sum(eng.residuals_batch([ext.to_params(np.r_[z0[:2], 0.0])])[0] ** 2))
    values = coordinates(ext, np.geomspace(0.1e-3, 1.5e-3, 8))
    held = [{"k_s": 6.0e7}]
    unreachable = series_profiles(eng, ext, z0, 0, values, held, SeriesTargets(sse_off, coarse=windows,
                                                                               coarse_sse_off=0.0))
    assert not unreachable.released and unreachable.points == [] and unreachable.evaluations > 0
    assert 0.0 < unreachable.coarse_best < sse_off  # on the tests it would have been released
    released = series_profiles(eng, ext, z0, 0, values, held, SeriesTargets(sse_off, coarse=windows,
                                                                            coarse_sse_off=sse_off))
    assert released.released
    k = int(np.argmin(released.sse))
    assert ext.to_params(released.points[k])["k_s"] == pytest.approx(SeriesEngine.K_STAR, rel=0.01)
    assert ext.to_params(released.points[k])["free_play"] == pytest.approx(GAP, rel=0.05)
    alone = series_profiles(eng, ext, z0, 0, values, held, SeriesTargets(sse_off))
    assert len(released.points) < len(alone.points)  # the coarse points are the tests' only without windows


def test_the_series_ladder_holds_decades_across_the_range_never_one_value():
    """The series element's held values (``series_values``): a guess whose decades above are capped at the bound
    still gets the bound and the decades below it, decades apart, none softer than a tenth of the stroke's
    deflection at the peak force; a guess well inside the range gets the stiffer decades first."""
    from types import SimpleNamespace

    from tuner.diagnosis.search.nonsmooth import series_values
    from tuner.identification.restart_check import SOFTEST_SERIES

    par = SimpleNamespace(bounds={"k_B": (1e2, 1e9)})
    s = SimpleNamespace(par=par, guess={"k_B": 2.5e8}, peak=20e3, stroke_range=0.04)
    held = series_values(s, "k_B")
    assert held[0] == 1e9 and len(held) >= 3
    assert all(a / b >= 2.0 or b / a >= 2.0 for a, b in zip(held, held[1:]))  # apart, not the same value again
    assert min(held) <= 2.5e8 / 5 and min(held) >= SOFTEST_SERIES * 20e3 / 0.04
    s = SimpleNamespace(par=par, guess={"k_B": 1e6}, peak=20e3, stroke_range=0.04)
    held = series_values(s, "k_B")
    assert held[:2] == [1e7, 1e8] and max(held) <= 1e9 and min(held) >= SOFTEST_SERIES * 20e3 / 0.04
