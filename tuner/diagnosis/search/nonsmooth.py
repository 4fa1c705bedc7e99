"""The nonsmooth candidates (``Effect.nonsmooth``: a free play), whose refit a screen that re-balances the base
linearly can miss: which are refitted whatever the screen predicts (``signalled_nonsmooth``), the profile with
the series element held (``series_ladder``), and the refit of those no screen passed before a residual above the
floor is left without a cause (``refit_unseen_nonsmooth``). SI units; forces in N."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from damper_fmu.effect_catalogue import ALL_EFFECTS
from damper_fmu.parameters import SERIES_ELEMENT

from tuner.diagnosis.cost_model import refit_cost, series_cost
from tuner.diagnosis.extended_parametrization import ExtendedParametrization, grid
from tuner.diagnosis.held_profiles import SERIES_HELD_JACOBIANS, SeriesTargets, series_profiles
from tuner.diagnosis.rules import UNEXPLAINED_RATIO, scores
from tuner.diagnosis.search.refits import refit_candidate
from tuner.diagnosis.search.rows import held_out, log_row
from tuner.diagnosis.search.state import Fit, SearchState
from tuner.identification.polish import polish
from tuner.identification.restart_check import SOFTEST_SERIES, series_decades
from tuner.metrics import rmse_standard_error

__all__ = ["series_ladder", "unearned_nonsmooth", "shows_gain", "signalled_nonsmooth", "refit_unseen_nonsmooth",
           "refit_unseen"]


def series_values(s: SearchState, k: str) -> list[float]:
    """The series stiffness values [N/m] the ladder holds (``series_ladder``), in order: ``series_decades`` of the
    data-driven guess's stiffness (the rule the fit's restart check holds the element by), none softer than
    ``SOFTEST_SERIES`` x peak force / stroke range."""
    return series_decades(s.par.bounds[k], s.guess[k], SOFTEST_SERIES * s.peak / max(s.stroke_range, 1e-12))


def series_ladder(s: SearchState, effect: str, ext: ExtendedParametrization, row: dict,
                  gain_n: float = 0.0) -> dict:
    """A nonsmooth effect signalled above the noise (``signalled_nonsmooth``) or refitted without earning a
    score (``unearned_nonsmooth``) whose refit still leaves a residual above the floor is profiled again with
    the element in series with it (``SERIES_ELEMENT``) held at each of ``series_values`` (decades apart across
    its range), at the guess's damping (``tuner.diagnosis.held_profiles.series_profiles``; a mount fitted as a
    dashpot carries a gap's lost motion; the next value only while the residual stays above the floor), then
    polished jointly, when the profile's best fits better than the base refit by more than ``gain_n`` [N of
    identification RMSE] (the profile itself releases and sweeps only such a held value); the better refit of the
    effect is kept. The coarse passes with the element held run on the search's windows of the tests where they
    cut them (``coarse_gate``: judged against the base re-fitted there); the releases on every sample. On the
    0.25 A MR current that took the ladder from 45 to 13 s (docs/measurements.md). Returns its ranking row
    (``series_element_held``: the values held [SI]; ``series_element_released``: whether the ladder's refit was
    kept). Not run again in a diagnosis on a finer grid when the coarser grid's ladder kept nothing
    (``CoarserGrid.idle_ladders``)."""
    names = SERIES_ELEMENT.get(s.kind)
    if names is None or not s.above_floor(row["identification_rmse_n"]):
        return row
    if s.coarser is not None and effect in s.coarser.idle_ladders:
        s.log(f"  {effect:14s} at {row['identification_rmse_n']:.1f} N, above the floor: the series element held "
              f"fitted no better on the coarser grid: not profiled again")
        return {**row, "series_element_released": False}
    k, c = names
    kept = s.coarser.kept_ladders.get(effect) if s.coarser is not None else None
    held = [{k: value, c: s.guess[c]} for value in ([kept] if kept else series_values(s, k))]
    i = ext.extra.index(ALL_EFFECTS[effect].magnitude)
    lo, hi = ext.extra_bounds[i]
    values = [(v - lo) / (hi - lo) for v in grid(lo, hi, s.settings.grid_points, ext.floors[i]) if v > lo]
    windows = s.ew.n_samples / s.eid.n_samples if s.ew is not None else 1.0
    cost = series_cost(s.par.dimension, s.settings, len(held), windows)
    s.cost.refits += cost
    s.forecast()
    s.log(f"  {effect:14s} at {row['identification_rmse_n']:.1f} N, above the floor: profiled "
          f"with the {k} held at " + ", ".join(f"{h[k]:.3g}" for h in held) + f" N/m ({c} {s.guess[c]:.3g} "
          f"N s/m), released where a gap fits better")
    start = ext.from_params({**s.base, **s.par.to_params(s.z_none)})
    enough = s.eid.n_samples * (UNEXPLAINED_RATIO * s.floor) ** 2 if s.credible else 0.0
    whole = CoarseGate.of(None, s.eid.n_samples, math.sqrt(1.0 / s.g_none), gain_n)  # on every sample
    coarse = coarse_gate(s, ext, start, ALL_EFFECTS[effect].magnitude, whole)
    prof = series_profiles(s.eid, ext, start, i, values, held,
                           SeriesTargets(whole.sse_beat, enough, coarse.engine, coarse.sse_beat,
                                         s.sweep_gain_n))
    fit = s.refits[effect]
    if not prof.released:  # no gap value fits better with the element held (``series_profiles``)
        s.cost.refits = max(0.0, s.cost.refits - cost)
        s.refits[effect] = Fit(fit.ext, fit.z, fit.evaluations + prof.evaluations)
        gain = coarse.rmse_n - math.sqrt(prof.coarse_best / coarse.n_samples)  # [N]
        s.log(f"  {effect:14s} no gap fits better than the base refit with the series element held"
              + (f" by more than the data resolve ({gain:.2g} N, one standard error {coarse.gain_n:.2g} N"
                 + (f", on the search's windows of the tests)" if coarse.engine is not None else ")")
                 if gain_n > 0 else "") + ": not released")
        return {**row, "evaluations": fit.evaluations + prof.evaluations, "series_element_held": held,
                "series_element_released": False, "gap_fits_better": False}
    pol = s.polish_quietly(ext, prof.points[int(np.argmin(prof.sse))], s.share)
    s.cost.refits = max(0.0, s.cost.refits - cost)
    evals = fit.evaluations + prof.evaluations + pol.evaluations
    if not pol.fitness > 1.0 / row["identification_rmse_n"] ** 2:
        s.refits[effect] = Fit(fit.ext, fit.z, evals)
        s.log(f"  {effect:14s} no better with the series element held: {1.0 / math.sqrt(pol.fitness):.1f} N")
        return {**row, "evaluations": evals, "series_element_held": held, "series_element_released": False}
    s.refits[effect] = Fit(ext, pol.z, evals)
    new = held_out(s, effect, ext.to_params(pol.z), ext.extra, pol.fitness, evals, s.mse_none)
    # the held value the kept refit came from: the one nearest (in decades) to where its release went
    start_k = ext.to_params(prof.points[int(np.argmin(prof.sse))])[k]
    source = min((h[k] for h in held), key=lambda v: abs(math.log(v / start_k)))
    return {**new, "series_element_held": held, "series_element_released": True, "series_element_kept_from": source}


@dataclass(frozen=True)
class CoarseGate:
    """Where the ladder's coarse passes run and what they must beat (``coarse_gate``): ``engine`` (the search's
    windows of the identification tests; None: the tests themselves), its ``n_samples``, the base refit's RMSE
    ``rmse_n`` [N] on it, the gain ``gain_n`` [N] a gap must show there and the SSE ``sse_beat`` [N^2] that is."""

    engine: object
    n_samples: int
    rmse_n: float
    gain_n: float
    sse_beat: float

    @classmethod
    def of(cls, engine, n_samples: int, rmse_n: float, gain_n: float) -> "CoarseGate":
        """The gate whose SSE to beat is that of an RMSE ``gain_n`` [N] below ``rmse_n`` [N] on ``n_samples``."""
        return cls(engine, n_samples, rmse_n, gain_n, n_samples * max(rmse_n - gain_n, 0.0) ** 2)


def coarse_gate(s: SearchState, ext: ExtendedParametrization, none: np.ndarray, magnitude: str,
                whole: CoarseGate) -> CoarseGate:
    """The coarse passes' gate of ``series_ladder``. Where the search's windows cut the identification tests
    (``SearchState.ew``; ``tuner.identification.search_window``): the base refit at ``none`` (``ext``'s search
    coordinates, the effect off) re-fitted on the windows as each coarse value is (``SERIES_HELD_JACOBIANS``, the
    ``magnitude`` held at zero, the series element free), and a gap must fit better than that by one standard error
    of its RMSE when ``whole.gain_n`` > 0 (the data's resolution, as it is on every sample), else at all. Not the
    base point itself: fitted on every sample, it is not a minimum on the windows, and any re-fit there gains (on
    the 0.25 A MR current the coarse passes beat it by more than a standard error, and the release and full refit
    took 132 s for a 2.2 N gap force). Where the windows cut nothing (or the re-fit cannot be simulated on them):
    ``whole``, the gate on every sample."""
    r = None
    if s.ew is not None and s.ew is not s.eid:
        held = ext.holding({magnitude: 0.0})
        pol = polish(s.ew, held, held.from_params(ext.to_params(none)), max_jacobians=SERIES_HELD_JACOBIANS,
                     log=lambda m: None)
        r = s.ew.residuals_batch([held.to_params(pol.z)])[0] if pol.fitness > 0 else None
    if r is None:
        return whole
    gain = rmse_standard_error(r) if whole.gain_n > 0 else 0.0
    return CoarseGate.of(s.ew, s.ew.n_samples, math.sqrt(float(r @ r) / s.ew.n_samples), gain)


def unearned_nonsmooth(effect: str, row: dict) -> bool:
    """A nonsmooth effect refitted on the profile screen's prediction whose refit did not earn a cause's score
    (``ACCEPT_SCORE``, with a force above the noise): the screen points at it, the refits from the base and
    from the guess cannot reach it. A 0.50 mm gap in stiff two-chamber mounts (4.0e8 N/m): the joint screen
    kept no free play, the profile screen predicted 7.5 % of the SSE, the refit ended at 0.05 mm (score
    +0.015, 964 N rms against 1030 N without it); with the mount held a decade stiffer (``series_ladder``)
    0.555 mm, held-out MSE -92 %."""
    return ALL_EFFECTS[effect].nonsmooth and not scores(row)


def shows_gain(s: SearchState, row: dict) -> bool:
    """Whether the refit of ``row`` lowered the identification RMSE below the base refitted alike ('none') by
    more than the data resolve (one standard error of the RMSE, ``resolvable_n``): the evidence that a nonsmooth
    effect's refit is held off by the series element (``series_ladder``) rather than absent. The 0.50 mm gap of
    ``unearned_nonsmooth`` had its refit at 964 against 1030 N, far above it; on a real MR damper (0.25 A, a
    residual nobody's free play explains) the free play's refit ended 0.2 N below 'none' with a standard error
    of 0.75 N, and its ladder then took 90 s of a 4.5-minute job to end no lower."""
    return s.none_row["identification_rmse_n"] - row["identification_rmse_n"] > s.resolvable_n


def signalled_nonsmooth(s: SearchState) -> set:
    """The nonsmooth effects (``Effect.nonsmooth``: a free play) whose residual signature the joint screen
    finds above the noise: refitted whatever the profile screen predicts. The screen re-balances the base
    linearly; what a base gives back of a nonsmooth effect it absorbed is not linear in it (a 0.114 mm gap in
    stiff two-chamber mounts: screened at 0.0 % of the SSE, its signature 37 N rms above the noise, the refit's
    continuation in the gap from 123 to 39 N rms, the truth's own)."""
    kept = s.evidence["joint_screen"]["kept"]
    found = {e for e in kept if e in ALL_EFFECTS and ALL_EFFECTS[e].nonsmooth and e in s.settings.candidates}
    if found:
        s.log(f"  refitted whatever the screen predicts (nonsmooth, signature above the noise): "
              f"{', '.join(sorted(found))}")
    return found


def refit_unseen_nonsmooth(s: SearchState) -> list[str]:
    """Before a residual above the floor is left without a cause (neither a catalogue effect nor a form named:
    ``conclusion.concluded``), every nonsmooth candidate (``Effect.nonsmooth``: a free play) that no screen passed
    is refitted (``refit_unseen``: the ladder first, the full refit if needed), and the ranking concluded again if
    one scores: the profile screen re-balances the base linearly, and what a base absorbed of a gap does not come
    back linearly. A 0.54 mm gap in stiff two-chamber mounts (1.8e8 N/m): screened at 1.3 % of the SSE, no
    signature kept by the joint screen, 'unexplained' at 528 N rms (24 x the floor); refitted with the ladder,
    0.541 mm at 21 N rms. Returns the effects refitted (none when the base refit is within the floor's reach)."""
    if not s.above_floor(s.none_row["identification_rmse_n"]):
        return []
    rows = [r for r in s.ranking if r["effect"] != "none" and not r["refitted"]
            and ALL_EFFECTS[r["effect"]].nonsmooth]
    for row in rows:
        effect = row["effect"]
        s.at(f"{effect} refitted, screened out")  # the time budget's section: not the forms' before it
        s.log(f"  {effect:14s} screened out, but nonsmooth and the base leaves "
              f"{s.none_row['identification_rmse_n']:.1f} N: refitted before the residual is left without a "
              f"cause")
        new = refit_unseen(s, effect, s.refits[effect].ext, row)
        new["refitted"], new["screen"] = True, row["screen"]
        s.ranking[s.ranking.index(row)] = new
        log_row(s, new)
    return [r["effect"] for r in rows]


def refit_unseen(s: SearchState, effect: str, ext: ExtendedParametrization, screened: dict) -> dict:
    """``refit_unseen_nonsmooth``'s refit of one effect from its ``screened`` row: the ``series_ladder`` first
    (what a screen that re-balances the base linearly misses is a gap the base absorbed into its mounts), then,
    unless it leaves no residual above the floor with a cause's score, the full ``refit_candidate`` (the ladder
    starts from the base whatever a refit found: it is not run again); the better identification fit is kept.
    The 0.54 mm gap of ``refit_unseen_nonsmooth``: the full refit took 117 s to end at 473 N rms, the ladder
    after it 211 s to reach 21 N. When the ladder's profile finds no gap that fits better than the base refit at
    any held stiffness by more than the data resolve (one standard error of the RMSE, ``resolvable_n``;
    ``gap_fits_better`` False), it is not released and the full refit is not run: the screen (the base
    re-balanced) and the profile (the element held decades apart) both found none the data can show. Where no
    gap fitted better at all (the MR currents, the physical benchmark's clean damper) the full refit took 37 s of
    a 191 s job on the two-chamber base and ended below the noise every time; on the 0.25 A MR current a profile
    0.003 N better (one standard error 0.81 N) was released and refitted in full, 157 s of a 348 s job, to end at
    0.185 mm with 2.2 N of force, below the noise. No unseen free play in the class or physical benchmarks' logs
    was released at all, and the 0.54 mm gap above ended at 21 N rms against 528 N without it
    (docs/measurements.md)."""
    ladder = series_ladder(s, effect, ext, screened, s.resolvable_n)
    if scores(ladder) and not s.above_floor(ladder["identification_rmse_n"]):
        return ladder
    if ladder.get("gap_fits_better") is False:  # the screen and the profile at every held stiffness found no gap
        s.log(f"  {effect:14s} not refitted from the base either: the screen and the profile with the series "
              f"element held found no gap that fits better")
        return ladder
    laddered = s.refits[effect]
    cost = refit_cost(s.par.dimension, 1, s.settings, True)
    s.cost.refits += cost
    s.forecast()
    row = refit_candidate(s, effect, ext)
    s.cost.refits = max(0.0, s.cost.refits - cost)
    evaluations = laddered.evaluations + s.refits[effect].evaluations
    kept, row = (laddered, ladder) if ladder["identification_rmse_n"] < row["identification_rmse_n"] else (
        s.refits[effect], row)
    s.refits[effect] = Fit(kept.ext, kept.z, evaluations)
    return {**row, "evaluations": evaluations}
