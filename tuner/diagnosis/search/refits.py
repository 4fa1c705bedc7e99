"""A catalogue candidate's screen (the better of two, ``screen``) and its full refit from every start
(``refit_candidate``). SI units; forces in N."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from tuner.diagnosis.extended_parametrization import ExtendedParametrization, base_jacobian
from tuner.diagnosis.refit import RefitProfile, refit
from tuner.diagnosis.screen import SCREEN_SHARE, profile_screen
from tuner.diagnosis.search.rows import held_out
from tuner.diagnosis.search.state import Fit, SearchState
from tuner.identification.polish import PolishResult
from tuner.metrics import rmse_of_fitness

__all__ = ["screen", "refit_candidate"]


def screen(s: SearchState, exts: dict) -> dict:
    """The better of two screens (``tuner.diagnosis.screen``) per candidate: at the base refitted alike
    (its own Jacobian) and at the fitted base the refits start from (one screen when they are the same
    point: a settled base)."""
    at_none = {**s.base, **s.par.to_params(s.z_none)}
    points = [(s.base, s.jac_base)]
    if not np.array_equal(s.z_none, s.par.from_params(s.base)):  # the refit moved: both points
        points.insert(0, (at_none, base_jacobian(s.eid, s.par, s.z_none)))
    screened = {}
    for at_point, jac in points:
        for e, r in profile_screen(s.eid, exts, at_point, jac, s.settings.grid_points).items():
            if e not in screened or r.share > screened[e].share:
                screened[e] = r
    s.log("  screen (identification SSE a refit could win, base re-balanced linearly): " + ", ".join(
        f"{e} {100 * r.share:.1f} %" for e, r in screened.items()) + f"; refitted: at least "
        f"{100 * SCREEN_SHARE:g} %")
    return screened


def refit_candidate(s: SearchState, effect: str, ext: ExtendedParametrization) -> dict:
    """The candidate's full refit: from each start, a profile line search of the effect with the base
    re-balanced (the fitted base may have absorbed part of the effect into its tables) and a joint
    polish; the better identification fit wins. Returns its ranking row."""
    best_z, g, evals = None, -math.inf, 0
    # one start (a settled base): its nonsmooth effects' held profiles also from the guess (``refit``'s fresh)
    fresh = ext.from_params(s.guess) if s.one_start else None
    for start, sse_start, svd in s.starts:
        fit = refit(s.eid, ext, ext.from_params(start), sse_start, svd, s.settings, s.share,
                    profile=RefitProfile(fresh=fresh, sweep_gain_n=s.sweep_gain_n))
        evals += fit.evaluations
        if fit.fitness > g:
            best_z, g = fit.z, fit.fitness
    elsewhere = s.found_elsewhere.get(effect)
    if elsewhere:  # named on another base form: from its values too (held, the rest refitted; then released)
        pol = _from_elsewhere(s, ext, elsewhere)
        z, fitness = pol.z, pol.fitness
        evals += pol.evaluations
        s.log(f"  {effect:14s} refitted from the values the other base form named ("
              + ", ".join(f"{k} = {v:.4g}" for k, v in elsewhere.items()) + f"): identification RMSE "
              f"{rmse_of_fitness(fitness):.1f} N against {rmse_of_fitness(g):.1f} N from this base's own starts"
              + ("; kept" if fitness > g else ""))
        if fitness > g:
            best_z, g = z, fitness
    s.refits[effect] = Fit(ext, best_z, evals)
    return held_out(s, effect, ext.to_params(best_z), ext.extra, g, evals, s.mse_none)


def _from_elsewhere(s: SearchState, ext: ExtendedParametrization, values: dict) -> PolishResult:
    """The refinement (its point in ``ext``'s coordinates, fitness N / SSE [1/N^2], the simulations of both stages)
    of the effect refitted from ``values`` [SI] another base form named: the base refitted alike with the effect's parameters held there (what this base
    absorbed of the effect given back), then every coordinate released, each to its rule
    (``final_jacobians`` at most)."""
    start = {**s.base, **s.par.to_params(s.z_none), **values}
    held = ext.holding({k: v for k, v in values.items() if k in ext.extra})
    first = s.polish_quietly(held, held.from_params(start), s.settings.final_jacobians)
    pol = s.polish_quietly(ext, ext.from_params(held.to_params(first.z)), s.settings.final_jacobians)
    return replace(pol, evaluations=first.evaluations + pol.evaluations)
