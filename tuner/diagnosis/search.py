"""The diagnosis on one base form: residual evidence, the candidates' screen and refits, promotion,
continuation, intervals, forward selection, the forms and the detection limits (SI units; forces in N).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from damper_fmu.fmu import ensure_fmu
from damper_fmu.effect_catalogue import ALL_EFFECTS, EFFECT_PARAMETERS, effect_of, search_bounds
from damper_fmu.parameters import SERIES_ELEMENT, defaults, parameter_group

from tuner.diagnosis.bases import Base, BaseRefinement
from tuner.diagnosis.cost_model import (EXTENDED_COST, DiagnosisCost, after_ranking, expected_cost, form_pass_cost,
                                         refit_cost, series_cost)
from tuner.diagnosis.detection import detection_limits
from tuner.diagnosis.effect_sizes import REFERENCE, DamperSize, meaningful_floor, typical_range
from tuner.diagnosis.forms import FORM_LABELS, screen, settings_text, shape_grid
from tuner.diagnosis.refit import (ExtendedParametrization, base_jacobian, effect_intervals, grid, refit,
                                   series_profiles)
from tuner.diagnosis.residuals import TestResidual, evidence as residual_evidence, figure_files
from tuner.diagnosis.rules import (ACCEPT_SCORE, FORM_EXCESS_SHARE, PENALTY_PER_PARAMETER, UNEXPLAINED_RATIO,
                                   cross_check, decide, earned, excess_explained, rescore, score, scores,
                                   indistinguishable, within_bounds)
from tuner.diagnosis.screen import SCREEN_SHARE, profile_screen

#: a form's shape is refitted only when the screen predicts it to win at least this share of the identification
#: residual power above the floor: a fifth of the held-out share a form must remove to be named
#: (FORM_EXCESS_SHARE), since the linear screen under-predicts what a refit realises (a rebound orifice of the
#: twin-tube rig: 21 % predicted, 66 % realised; half the naming share there left the groove unrefitted)
FORM_REFIT_EXCESS = 0.2 * FORM_EXCESS_SHARE
#: the fit's cost per simulation counts as this many simulations of the diagnosis's own (``forecast``): the first
#: batches also start the engines' workers (2-5 s), which would otherwise read as a slow model
PRIOR_EVALUATIONS = 200
from tuner.diagnosis.settings import DiagnosisSettings
from tuner.diagnosis.verdict import (NOTES, UNITS, effect_parameters, interval_text, limit_text,
                                     unexplained_record, verdict_text)
from tuner.formatting import fmt_quantity
from tuner.identification.engine import Engine
from tuner.identification.fit import initial_guess, validation_run
from tuner.identification.parametrization import Parametrization
from tuner.identification.polish import PolishResult, polish
from tuner.identification.problem import Problem
from tuner.metrics import pooled_mse, rmse_standard_error
from tuner.progress import advance, expect

__all__ = ["CandidateSearch", "Fit", "BaseRun", "diagnose_on", "base_point", "base_residuals"]


def base_point(kind: str, values: dict) -> dict:
    """The base model's full parameter point (SI): the preset of ``kind`` with ``values`` (the identified
    base, keys of other models ignored) and every effect element off."""
    point = defaults(kind)
    point.update({k: v for k, v in values.items() if k in point})
    point.update({p.name: p.default for p in EFFECT_PARAMETERS})
    return point


def base_residuals(kind: str, values: dict, data: Problem, settings) -> list[TestResidual]:
    """The base model's residual (measured - simulated force [N]) on every test of ``data``, identification
    then validation, simulated as the validation does (``validation_run``: the FMU at its own steps) at
    ``base_point(kind, values)``: the evidence's and the figures' series."""
    point = base_point(kind, values)
    return [TestResidual(p.name, p.role or "", p.time, p.stroke, p.stroke_velocity, p.force,
                         validation_run(kind, point, s, settings.engine)[0], s.mask, s.temperature)
            for p, s in zip([*data.prep_id, *data.prep_val], [*data.sig_id, *data.sig_val])]


def split_mse(residual: np.ndarray | None, lengths: list[int]) -> list[tuple[float, float]]:
    """(MSE [N^2], AME [N]) per test from a concatenated residual vector."""
    if residual is None:
        return [(math.inf, math.inf)] * len(lengths)
    out, k = [], 0
    for n in lengths:
        r = residual[k:k + n]
        out.append((float(r @ r) / n, float(np.mean(np.abs(r)))))
        k += n
    return out


def attach_interval(row: dict, ci: dict, ext: ExtendedParametrization, new) -> None:
    """The row's 95 % intervals of ``ext.extra`` from ``effect_intervals``' ``ci``; significant when the
    interval of every ``new`` magnitude excludes zero; plausible when none of them lies wholly above the
    top of its effect's typical range on this damper (``effect_sizes.typical_range``): a magnitude no damper
    of this size has patches another error (a form gap), it is not that effect."""
    size = DamperSize(ext.peak_force, ext.stroke_range_m or REFERENCE.stroke_range_m)
    row["interval"] = {n: [ci[n]["low"], ci[n]["high"]] for n in ext.extra}
    row["significant"] = all(ci[n]["excludes_zero"] for n in new)
    row["interval_blocks"] = ci["_blocks"]
    nearest = {n: 0.0 if ci[n]["low"] <= 0.0 <= ci[n]["high"] else min(abs(ci[n]["low"]), abs(ci[n]["high"]))
               for n in new if n in effect_of(n).typical}
    row["plausible"] = all(v <= typical_range(n, size)[1] for n, v in nearest.items())


@dataclass
class Fit:
    """One refitted model: its parametrization (the base extended by its effects), scaled coordinates ``z``
    and the evaluations its refit took."""

    ext: object
    z: np.ndarray
    evaluations: int

    def params(self) -> dict:
        return self.ext.to_params(self.z)


@dataclass
class Conclusion:
    """Where the ranking of one base ends (``CandidateSearch.conclude``): the cause ('none', an effect or a form),
    every cause named (in order), the final model's ranking row, the rows not resolved, the forward selection's
    steps, the forms' step (or None) and the forms weighed with the first cause (or None)."""

    cause: str
    causes: list
    best: dict
    unresolved: list
    selection: list
    form_step: dict | None
    weighed: dict | None


class CandidateSearch:
    """The diagnosis on one base form (steps 2-5 of ``tuner.diagnosis.diagnose``): it owns the engines, the
    parametrization, the residual floor, the refits and the ranking, with one method per step. ``run()``
    returns the result fields of ``diagnosis.json`` for this base, plus ``after_params`` (the final model's
    values) and ``final_validation_mse`` [N^2] (pooled, Table 3 definition). ``record`` (as
    ``tuner.diagnosis.diagnose``) follows its stages: 'stage' names the one running, 'partial' holds the
    ranking, selection steps, causes and forms tried so far (the live lists). Units SI; forces in N."""

    def __init__(self, kind: str, par: Parametrization, base_params: dict, data: Problem,
                 settings: DiagnosisSettings, figures: str, log, record: dict | None = None,
                 refinement: BaseRefinement = BaseRefinement()):
        self.kind, self.par, self.data, self.settings, self.log = kind, par, data, settings, log
        self.settled_by = refinement.settled  # how the refinement of base_params on these tests ended
        rate = refinement.seconds_per_evaluation  # [s per simulation], the fit's
        self.rate_prior = None if rate is None else rate * EXTENDED_COST  # the diagnosis's, expected
        self.cost: DiagnosisCost | None = None  # the steps still to come (``forecast``)
        self.t_engines = time.perf_counter()  # when the engines opened (``run``): the live cost per simulation
        self.figures_folder = figures  # where the job draws the figures, relative to the output folder
        self.record = record if record is not None else {}
        self.record.setdefault("partial", {})
        self.peak, self.stroke_range, self.noise = data.peak_n, data.stroke_range_m, data.noise_n
        self.size = DamperSize(self.peak, self.stroke_range)  # typical effect sizes scale with it
        self.stroke_limits = (min(float(s.stroke[s.mask].min()) for s in data.sig_id),
                              max(float(s.stroke[s.mask].max()) for s in data.sig_id))  # [m]
        self.base = base_point(kind, base_params)  # the base model has every effect off
        self.guess = {**defaults(kind), **initial_guess(kind, data.sig_id, par)}
        for p in EFFECT_PARAMETERS:
            self.guess[p.name] = p.default
        self.lengths = [int(s.mask.sum()) for s in data.sig_val]
        self.ranking: list[dict] = []
        self.refits: dict[str, Fit] = {}
        #: {causes key: (stroke noise through that model [N rms], its residual floor [N])} (``floor_of``)
        self.floors: dict[str, tuple[float, float]] = {}
        #: {causes key ('' for none): whether its last refit settled (``settled``)}
        self.converged: dict[str, bool] = {}
        self.z_settled: np.ndarray | None = None  # the base refit's point when it settled (``refit_none``)
        self.resolvable_n = 0.0  # one standard error of the base's identification RMSE [N] (``refit_none``)
        self.fit_base_rmse_n = math.nan  # the fitted base's identification RMSE [N] (``refit_none``)
        self.eid = self.ev = None

    # -- bookkeeping --------------------------------------------------------------------------------------
    def forecast(self) -> None:
        """The seconds this diagnosis still expects (``tuner.diagnosis.cost_model``: the simulations of the steps
        to come, at the wall time per simulation measured so far, or the fit's before any) to the progress
        display."""
        if self.cost is None:
            return
        share = sum(self.lengths) / self.eid.n_samples
        evaluations = self.eid.evaluations + share * self.ev.evaluations
        spent = time.perf_counter() - self.t_engines
        if self.rate_prior is not None:  # the fit's, worth PRIOR_EVALUATIONS (the first batch starts the workers)
            evaluations, spent = evaluations + PRIOR_EVALUATIONS, spent + PRIOR_EVALUATIONS * self.rate_prior
        if evaluations > 0:
            expect(self.log, self.cost.total * spent / evaluations)

    def step_done(self, step: str) -> None:
        """Step ``step`` of the cost model (a ``DiagnosisCost`` field) is finished: the time left said again."""
        self.cost.done(step)
        self.forecast()

    def expect_after_ranking(self) -> None:
        """The cost of the steps the ranking decides (``tuner.diagnosis.cost_model.after_ranking``): a leading
        candidate's continuation, the intervals, the forward selection, the passes of the forms (they run where
        the lead, or the base when nothing scores, leaves a residual above the floor: ``weigh_forms``,
        ``forms_on_top``)."""
        scoring = [r for r in self.ranking if r["effect"] != "none" and scores(r)]
        lead = max(scoring, key=lambda r: r["score"]) if scoring else self.none_row
        after_ranking(self.cost, self.par.dimension, self.settings, scoring=len(scoring),
                      forms_run=self.above_floor(self.none_row["identification_rmse_n"])
                      and self.above_floor(lead["identification_rmse_n"]))
        self.forecast()

    def tick(self) -> None:
        """After every batch of simulations: the progress display may say the time left again (counting down
        from the last forecast), so a long step (a ladder, a refit) is not a silence."""
        advance(self.log, 0.0)

    def at(self, stage: str, fraction: float | None = None) -> None:
        self.record["stage"] = f"{stage} on the {self.kind} base"
        if fraction is not None:
            advance(self.log, fraction)

    def residual_floor(self) -> None:
        """The floor of 'explained' [N rms]: the force noise and what the stroke channel's noise makes through
        the model's series stiffness (no model of the damper can remove it). A floor from a noise estimate
        that is not credible (filtered data, too few samples) decides nothing: no "N x the floor", no
        'unexplained' and no "settled" from a ratio against it."""
        self.stroke_noise_n = self.data.residual_floor(self.settings.engine).stroke_noise_n(self.kind, self.base)
        self.floor = math.hypot(self.noise, self.stroke_noise_n)
        self.credible = bool(self.data.noise.get("credible", True))
        self.not_credible = None if self.credible else self.data.noise.get("text", "noise estimate not credible")
        self.log(f"diagnosis: stroke noise through the base model {self.stroke_noise_n:.1f} N rms; residual floor "
                 f"{self.floor:.1f} N" + ("" if self.credible else f" - not used to judge the residual: "
                                                                     f"{self.not_credible}"))

    def residual_evidence(self) -> None:
        """Residual analysis of the base model: evidence numbers, the joint screen, and the series and file names
        of the figures (the job draws them, ``tuner.results.diagnosis_figures``)."""
        self.residuals = base_residuals(self.kind, self.base, self.data, self.settings)
        self.evidence = residual_evidence(self.residuals, noise_n=self.noise)
        self.figures = figure_files(self.figures_folder)
        scr = self.evidence["joint_screen"]
        self.log("diagnosis: joint screen of the residual on all catalogue signatures: "
                 + (" + ".join(f"{e} ({scr['terms'][e]['contribution_n']:.3g} N)" for e in scr["kept"]) or "nothing")
                 + f" above the noise, explaining {100 * scr['r2_kept']:.0f} % of the base residual; all seven "
                   f"signatures together {100 * scr['r2_all']:.0f} %")

    def held_out(self, effect: str, params: dict, extra, g: float, evals: int, mse_ref: float, new=None,
                 n_params=None) -> dict:
        """Ranking entry of a refitted model: validation MSE/AME, score against the validation MSE ``mse_ref``
        [N^2] of the reference (the base refitted alike, or the model of the causes already selected), and
        the force contribution [N rms] of the ``new`` effect parameters (default all of ``extra``) on the
        identification tests (the fitted model minus the same with them off); ``g``: its identification
        fitness N / SSE; n_params: the parameters the score is penalised for (default as many as ``new``: a
        form is switched off by its magnitude but has more)."""
        new = list(extra) if new is None else list(new)
        r_val = self.ev.residuals_batch([params])[0]
        per_test = split_mse(r_val, self.lengths)
        mse = math.inf if r_val is None else float(r_val @ r_val) / sum(self.lengths)
        contribution = 0.0
        if new:
            r_on, r_off = self.eid.residuals_batch([params, {**params, **{n: 0.0 for n in new}}])
            if r_on is not None and r_off is not None:
                contribution = float(np.sqrt(np.mean((r_off - r_on) ** 2)))
        values = {n: params[n] for n in extra}
        return {"effect": effect, "score": score(mse, mse_ref, len(new) if n_params is None else n_params),
                "validation_mse": mse, "validation_mse_change_pct": 100 * (mse / mse_ref - 1),
                "identification_rmse_n": 1 / math.sqrt(g) if g > 0 else math.inf,
                "parameters": values, "units": {n: UNITS[n] for n in values},
                "effect_rms_n": contribution, "resolved": bool(contribution >= self.noise) if new else True,
                "meaningful": all(abs(params[n]) >= meaningful_floor(n, self.size) for n in new),
                "within_bounds": within_bounds({n: params[n] for n in new}, {
                    n: search_bounds(n, self.peak, self.stroke_range, self.stroke_limits) for n in new}),
                "validation": {s.name: {"mse": m, "ame": a} for s, (m, a) in zip(self.data.sig_val, per_test)},
                "evaluations": int(evals)}

    def settled(self, pol: PolishResult, g: float) -> bool:
        """A refit settled: it met its first-order test, or stalled (no damped step helps) where the gain its
        Gauss-Newton step still predicts cannot bring it within UNEXPLAINED_RATIO x the floor; a spent
        budget never settles (``pol`` of ``polish``, ``g`` its fitness N / SSE)."""
        reachable = math.sqrt(max(0.0, 1.0 - pol.predicted) / g) if g > 0 else math.inf
        return bool(pol.converged or (self.credible and not pol.budget_spent
                                          and reachable > UNEXPLAINED_RATIO * self.floor))

    def set_none(self, z: np.ndarray, g: float, evaluations: int, rescore_ranking: bool = True) -> None:
        """The base refitted alike ('none', the reference of every score) is now at ``z`` (fitness ``g``):
        its held-out MSE and ranking row; the ranking's scores are taken again against it (unless
        ``rescore_ranking`` is False: the lead's continuation, scored against it alone)."""
        self.z_none, self.g_none = z, g
        r = self.ev.residuals_batch([self.par.to_params(z)])[0]
        if r is not None:
            self.mse_none = float(r @ r) / sum(self.lengths)
        self.none_row = self.held_out("none", self.par.to_params(z), [], g, evaluations, self.mse_none)
        if rescore_ranking:
            rescore([r for r in self.ranking if r["effect"] != "none"], self.mse_none)
        self.ranking[:] = [self.none_row if r["effect"] == "none" else r for r in self.ranking]

    def polish_quietly(self, par, z: np.ndarray, jacobians: int) -> PolishResult:
        return polish(self.eid, par, z, max_jacobians=jacobians, log=lambda m: None)

    # -- the steps ----------------------------------------------------------------------------------------
    def refit_none(self) -> None:
        """'none' is a candidate like the others: the base model refitted from the same starts (the fitted
        base and, with ``guess_start`` where the fitted base is not settled, the data-driven guess) with the
        same local effort, so that an unfinished base fit is never credited to an effect. A settled base (its
        refinement converged on these tests: ``Base.settled``) is its own refit: the same refinement from the
        point where it ended would end there again."""
        r_base = self.eid.residuals_batch([self.base])[0]
        sse_base = float(r_base @ r_base) if r_base is not None else math.inf
        # the least fall of the identification RMSE [N] the data can show (``tuner.metrics.rmse_standard_error``)
        self.resolvable_n = rmse_standard_error(r_base) if r_base is not None else 0.0
        self.fit_base_rmse_n = math.sqrt(sse_base / self.eid.n_samples)
        r_val = self.ev.residuals_batch([self.base])[0]
        self.mse_base = self.mse_none = float(r_val @ r_val) / sum(self.lengths)
        self.log(f"diagnosis: base model RMSE identification {math.sqrt(sse_base / self.eid.n_samples):.1f} N, "
                 f"validation {math.sqrt(self.mse_base):.1f} N")
        self.jac_base = base_jacobian(self.eid, self.par, self.par.from_params(self.base))  # shared
        self.starts = [(self.base, sse_base, self.jac_base)]
        self.share = max(1, self.settings.polish_jacobians // 2)  # the Jacobian budget, split between two starts
        if self.settled_by:  # the same refinement from the point where it converged ends there: not run again
            pol = PolishResult(z=self.par.from_params(self.base), fitness=self.eid.n_samples / sse_base, evaluations=0,
                               stop=f"settled: {self.settled_by}", converged=True, rule="settled", jacobians=0,
                               predicted=0.0, budget_spent=False)
            self.log(f"  none           the fitted base is settled (its refinement on these tests: {self.settled_by}): "
                     f"it is the base refitted alike")
        else:
            pol = self.polish_quietly(self.par, self.par.from_params(self.base), self.share)
        z_none, g_none, evals = pol.z, pol.fitness, pol.evaluations
        # the data-driven guess has absorbed no effect into the tables; it is a second start only where the
        # fitted base is not settled (its refit spent the budget still improving): from a settled base the
        # profile line search re-balances what the tables absorbed
        self.one_start = bool(pol.converged) or not self.settings.guess_start
        if pol.converged:  # the base refit met its rule: an 'unexplained' can rest on it
            self.converged[""] = self.settled(pol, g_none)
            self.z_settled = pol.z if self.converged[""] else None
        if not self.one_start:
            self.starts.append((self.guess, math.inf, None))
            pol = self.polish_quietly(self.par, self.par.from_params(self.guess), self.share)
            evals += pol.evaluations
            if pol.fitness > g_none:
                z_none, g_none = pol.z, pol.fitness
        self.set_none(z_none, g_none, evals)
        self.log(f"  {'none':14s} (base refitted alike)  identification RMSE "
                 f"{self.none_row['identification_rmse_n']:.1f} N, validation MSE "
                 f"{100 * (self.mse_none / self.mse_base - 1):+6.1f} % vs the base fit"
                 + ("; the fitted base is settled: one start for every refit" if self.one_start else ""))

    def screen(self, exts: dict) -> dict:
        """The better of two screens (``tuner.diagnosis.screen``) per candidate: at the base refitted alike
        (its own Jacobian) and at the fitted base the refits start from (one screen when they are the same
        point: a settled base)."""
        at_none = {**self.base, **self.par.to_params(self.z_none)}
        points = [(self.base, self.jac_base)]
        if not np.array_equal(self.z_none, self.par.from_params(self.base)):  # the refit moved: both points
            points.insert(0, (at_none, base_jacobian(self.eid, self.par, self.z_none)))
        screened = {}
        for at_point, jac in points:
            for e, r in profile_screen(self.eid, exts, at_point, jac, self.settings.grid_points).items():
                if e not in screened or r.share > screened[e].share:
                    screened[e] = r
        self.log("  screen (identification SSE a refit could win, base re-balanced linearly): " + ", ".join(
            f"{e} {100 * r.share:.1f} %" for e, r in screened.items()) + f"; refitted: at least "
            f"{100 * SCREEN_SHARE:g} %")
        return screened

    def refit_candidate(self, effect: str, ext: ExtendedParametrization) -> dict:
        """The candidate's full refit: from each start, a profile line search of the effect with the base
        re-balanced (the fitted base may have absorbed part of the effect into its tables) and a joint
        polish; the better identification fit wins. Returns its ranking row."""
        best_z, g, evals = None, -math.inf, 0
        # one start (a settled base): its nonsmooth effects' held profiles also from the guess (``refit``'s fresh)
        fresh = ext.from_params(self.guess) if self.one_start else None
        for start, sse_start, svd in self.starts:
            fit = refit(self.eid, ext, ext.from_params(start), sse_start, svd, self.settings, self.share, fresh=fresh)
            evals += fit.evaluations
            if fit.fitness > g:
                best_z, g = fit.z, fit.fitness
        self.refits[effect] = Fit(ext, best_z, evals)
        return self.held_out(effect, ext.to_params(best_z), ext.extra, g, evals, self.mse_none)

    def series_ladder(self, effect: str, ext: ExtendedParametrization, row: dict) -> dict:
        """A nonsmooth effect signalled above the noise (``signalled_nonsmooth``) or refitted without earning a
        score (``unearned_nonsmooth``) whose refit still leaves a residual above the floor is profiled again with
        the element in series with it (``SERIES_ELEMENT``) held a decade and two above the data-driven guess's
        stiffness, at the guess's damping (``refit.series_profiles``; a mount fitted as a dashpot carries a gap's
        lost motion; the second only when the first leaves the residual above the floor), then polished jointly;
        the better refit of the effect is kept. Returns its ranking row (``series_element_held``: the values held
        [SI])."""
        names = SERIES_ELEMENT.get(self.kind)
        if names is None or not self.above_floor(row["identification_rmse_n"]):
            return row
        k, c = names
        held = []
        for decades in (1, 2):
            value = min(self.guess[k] * 10.0 ** decades, self.par.bounds[k][1])
            if all(h[k] != value for h in held):
                held.append({k: value, c: self.guess[c]})
        i = ext.extra.index(ALL_EFFECTS[effect].magnitude)
        lo, hi = ext.extra_bounds[i]
        values = [(v - lo) / (hi - lo) for v in grid(lo, hi, self.settings.grid_points, ext.floors[i]) if v > lo]
        cost = series_cost(self.par.dimension, self.settings, len(held))
        self.cost.refits += cost
        self.forecast()
        self.log(f"  {effect:14s} at {row['identification_rmse_n']:.1f} N, above the floor: profiled "
                 f"with the {k} held at " + ", ".join(f"{h[k]:.3g}" for h in held) + f" N/m ({c} {self.guess[c]:.3g} "
                 f"N s/m), released where a gap fits better")
        start = ext.from_params({**self.base, **self.par.to_params(self.z_none)})
        enough = self.eid.n_samples * (UNEXPLAINED_RATIO * self.floor) ** 2 if self.credible else 0.0
        sse_none = self.eid.n_samples / self.g_none
        prof = series_profiles(self.eid, ext, start, i, values, sse_none, held, enough)
        fit = self.refits[effect]
        if not min(prof.sse) < sse_none:  # no gap value fits better with the element held (``series_profiles``)
            self.cost.refits = max(0.0, self.cost.refits - cost)
            self.refits[effect] = Fit(fit.ext, fit.z, fit.evaluations + prof.evaluations)
            self.log(f"  {effect:14s} no gap fits better than the base refit with the series element held: "
                     f"not released")
            return {**row, "evaluations": fit.evaluations + prof.evaluations, "series_element_held": held}
        pol = self.polish_quietly(ext, prof.points[int(np.argmin(prof.sse))], self.share)
        self.cost.refits = max(0.0, self.cost.refits - cost)
        evals = fit.evaluations + prof.evaluations + pol.evaluations
        if not pol.fitness > 1.0 / row["identification_rmse_n"] ** 2:
            self.refits[effect] = Fit(fit.ext, fit.z, evals)
            self.log(f"  {effect:14s} no better with the series element held: "
                     f"{1.0 / math.sqrt(pol.fitness):.1f} N")
            return {**row, "evaluations": evals, "series_element_held": held}
        self.refits[effect] = Fit(ext, pol.z, evals)
        new = self.held_out(effect, ext.to_params(pol.z), ext.extra, pol.fitness, evals, self.mse_none)
        return {**new, "series_element_held": held}

    @staticmethod
    def unearned_nonsmooth(effect: str, row: dict) -> bool:
        """A nonsmooth effect refitted on the profile screen's prediction whose refit did not earn a cause's score
        (``ACCEPT_SCORE``, with a force above the noise): the screen points at it, the refits from the base and
        from the guess cannot reach it. A 0.50 mm gap in stiff two-chamber mounts (4.0e8 N/m): the joint screen
        kept no free play, the profile screen predicted 7.5 % of the SSE, the refit ended at 0.05 mm (score
        +0.015, 964 N rms against 1030 N without it); with the mount held a decade stiffer (``series_ladder``)
        0.555 mm, held-out MSE -92 %."""
        return ALL_EFFECTS[effect].nonsmooth and not scores(row)

    def shows_gain(self, row: dict) -> bool:
        """Whether the refit of ``row`` lowered the identification RMSE below the base refitted alike ('none') by
        more than the data resolve (one standard error of the RMSE, ``resolvable_n``): the evidence that a nonsmooth
        effect's refit is held off by the series element (``series_ladder``) rather than absent. The 0.50 mm gap of
        ``unearned_nonsmooth`` had its refit at 964 against 1030 N, far above it; on a real MR damper (0.25 A, a
        residual nobody's free play explains) the free play's refit ended 0.2 N below 'none' with a standard error
        of 0.75 N, and its ladder then took 90 s of a 4.5-minute job to end no lower."""
        return self.none_row["identification_rmse_n"] - row["identification_rmse_n"] > self.resolvable_n

    def signalled_nonsmooth(self) -> set:
        """The nonsmooth effects (``Effect.nonsmooth``: a free play) whose residual signature the joint screen
        finds above the noise: refitted whatever the profile screen predicts. The screen re-balances the base
        linearly; what a base gives back of a nonsmooth effect it absorbed is not linear in it (a 0.114 mm gap in
        stiff two-chamber mounts: screened at 0.0 % of the SSE, its signature 37 N rms above the noise, the refit's
        continuation in the gap from 123 to 39 N rms, the truth's own)."""
        kept = self.evidence["joint_screen"]["kept"]
        found = {e for e in kept if e in ALL_EFFECTS and ALL_EFFECTS[e].nonsmooth and e in self.settings.candidates}
        if found:
            self.log(f"  refitted whatever the screen predicts (nonsmooth, signature above the noise): "
                     f"{', '.join(sorted(found))}")
        return found

    def candidates(self) -> None:
        """Every catalogue candidate screened; those predicted to win SCREEN_SHARE of the identification SSE
        (or ``signalled_nonsmooth``) are refitted, the others ranked at their screened point (refitted after all if
        that scores)."""
        exts = {e: ExtendedParametrization(self.par, e, self.peak, self.stroke_range)
                for e in self.settings.candidates}
        screened = self.screen(exts)
        signalled = self.signalled_nonsmooth()
        passed = [e for e in self.settings.candidates
                  if screened.get(e) is None or screened[e].passes or e in signalled]
        self.cost.done("screen")
        self.cost.refits = sum(refit_cost(self.par.dimension, 1, self.settings, ALL_EFFECTS[e].nonsmooth)
                               for e in passed)
        self.forecast()
        at_none = {**self.base, **self.par.to_params(self.z_none)}
        for k, effect in enumerate(self.settings.candidates):
            advance(self.log, 0.2 + 0.5 * k / len(self.settings.candidates))
            ext, scr = exts[effect], screened.get(effect)
            row = None
            if scr is not None and not scr.passes and effect not in signalled:
                point = {**at_none, **scr.values}
                row = self.held_out(effect, point, ext.extra, self.eid.n_samples / scr.sse_n2, 1, self.mse_none)
                row["identification_rmse_effect_off_n"] = self.none_row["identification_rmse_n"]
                self.refits[effect] = Fit(ext, ext.from_params(point), 1)
            refitted = row is None or scores(row)
            if refitted:
                row = self.refit_candidate(effect, ext)
                if effect in signalled or (self.unearned_nonsmooth(effect, row) and self.shows_gain(row)):
                    row = self.series_ladder(effect, ext, row)
                self.cost.refits = max(0.0, self.cost.refits - refit_cost(self.par.dimension, 1, self.settings,
                                                                          ALL_EFFECTS[effect].nonsmooth))
                self.forecast()
            row["refitted"], row["screen"] = refitted, scr.to_dict() if scr is not None else None
            self.ranking.append(row)
            self.log_row(row)

    def log_row(self, row: dict) -> None:
        """One candidate's ranking row, as the log shows it."""
        self.log(f"  {row['effect']:14s} " + ", ".join(f"{n} = {v:.4g} {UNITS[n]}" for n, v in row["parameters"].items())
                 + f"  validation MSE {row['validation_mse_change_pct']:+6.1f} %  score {row['score']:+.3f}"
                 + f"  effect {row['effect_rms_n']:.3g} N rms{'' if row['resolved'] else ' (below the noise)'}"
                 + ("" if row["refitted"] else "  (screened: not refitted)"))

    def refit_unseen_nonsmooth(self) -> list[str]:
        """Before a residual above the floor is left without a cause (neither a catalogue effect nor a form named:
        ``run``), every nonsmooth candidate (``Effect.nonsmooth``: a free play) that no screen passed is refitted
        (``refit_unseen``: the ladder first, the full refit if needed), and the ranking concluded again if one scores:
        the profile screen re-balances the base linearly, and what a base absorbed of a gap does not come back
        linearly. A 0.54 mm gap in stiff two-chamber mounts (1.8e8 N/m): screened at 1.3 % of the SSE, no signature
        kept by the joint screen, 'unexplained' at 528 N rms (24 x the floor); refitted with the ladder, 0.541 mm at
        21 N rms. Returns the effects refitted (none when the base refit is within the floor's reach)."""
        if not self.above_floor(self.none_row["identification_rmse_n"]):
            return []
        rows = [r for r in self.ranking if r["effect"] != "none" and not r["refitted"]
                and ALL_EFFECTS[r["effect"]].nonsmooth]
        for row in rows:
            effect = row["effect"]
            self.log(f"  {effect:14s} screened out, but nonsmooth and the base leaves "
                     f"{self.none_row['identification_rmse_n']:.1f} N: refitted before the residual is left without a "
                     f"cause")
            new = self.refit_unseen(effect, self.refits[effect].ext, row)
            new["refitted"], new["screen"] = True, row["screen"]
            self.ranking[self.ranking.index(row)] = new
            self.log_row(new)
        return [r["effect"] for r in rows]

    def refit_unseen(self, effect: str, ext: ExtendedParametrization, screened: dict) -> dict:
        """``refit_unseen_nonsmooth``'s refit of one effect from its ``screened`` row: the ``series_ladder`` first
        (what a screen that re-balances the base linearly misses is a gap the base absorbed into its mounts), then,
        unless it leaves no residual above the floor with a cause's score, the full ``refit_candidate`` (the ladder
        starts from the base whatever a refit found: it is not run again); the better identification fit is kept.
        The 0.54 mm gap of ``refit_unseen_nonsmooth``: the full refit took 117 s to end at 473 N rms, the ladder
        after it 211 s to reach 21 N."""
        ladder = self.series_ladder(effect, ext, screened)
        if scores(ladder) and not self.above_floor(ladder["identification_rmse_n"]):
            return ladder
        laddered = self.refits[effect]
        cost = refit_cost(self.par.dimension, 1, self.settings, True)
        self.cost.refits += cost
        self.forecast()
        row = self.refit_candidate(effect, ext)
        self.cost.refits = max(0.0, self.cost.refits - cost)
        evaluations = laddered.evaluations + self.refits[effect].evaluations
        kept, row = (laddered, ladder) if ladder["identification_rmse_n"] < row["identification_rmse_n"] else (
            self.refits[effect], row)
        self.refits[effect] = Fit(kept.ext, kept.z, evaluations)
        return {**row, "evaluations": evaluations}

    def rank(self, refitted: list[str]) -> tuple:
        """From the candidates' rows: ``promote`` among the ``refitted`` effects, the lead's continuation, the
        intervals, the ranking sorted with 'none' last, and its first decision (``rules.decide``: the cause, its
        row, the unresolved rows)."""
        self.ranking[:] = [r for r in self.ranking if r["effect"] != "none"]
        self.promote(refitted)
        self.expect_after_ranking()
        self.continue_lead()
        self.step_done("continuation")
        self.at("intervals of the candidates", 0.8)
        self.intervals()
        self.step_done("intervals")
        self.ranking.sort(key=lambda r: -r["score"])
        self.ranking.append(self.none_row)
        return decide(self.ranking)

    def promote(self, effects) -> None:
        """One best model: when a refit of one of ``effects`` fits the identification data better with its
        effect switched off than the base refit does, that point is the base ('none') and every score is
        taken against it again, so 'none' never loses to an effect of size zero."""
        offs = [(e, {**self.refits[e].params(), **{n: 0.0 for n in self.refits[e].ext.extra}}) for e in effects]
        if not offs:
            return
        sse = self.eid.sse_batch([p for _, p in offs])
        for (effect, _), sse_e in zip(offs, sse):
            row = next(r for r in self.ranking if r["effect"] == effect)
            row["identification_rmse_effect_off_n"] = math.sqrt(sse_e / self.eid.n_samples)
        k = int(np.argmin(sse))
        if not (np.isfinite(sse[k]) and self.eid.n_samples / sse[k] > self.g_none):
            return
        effect, params = offs[k]
        self.set_none(self.par.from_params(params), self.eid.n_samples / float(sse[k]),
                      self.none_row["evaluations"] + len(offs))
        self.none_row["from_refit_of"] = effect
        self.log(f"  none           the {effect} refit with its effect off fits better than the base refit: it is "
                 f"the base now (identification RMSE {self.none_row['identification_rmse_n']:.1f} N); scores "
                 f"taken again")

    def continue_lead(self) -> None:
        """The leading candidate's refit is continued to convergence (absorbed effects converge slowly), and
        so is the base refit, so that the continuation is not credited to the effect; a base refit that settled
        where it still is (``refit_none``) is not continued: its own rule says more Jacobians would not move it
        beyond the data's resolution (on a hidden 0.52 mm gap, 3 Jacobians of the two-chamber base, 10 s, left
        it at 847.0 N)."""
        lead = max(self.ranking, key=lambda r: r["score"] if r["resolved"] else -math.inf, default=None)
        if not (lead and scores(lead) and self.settings.final_jacobians > 0):
            return
        if not self.base_settled():
            pol = self.polish_quietly(self.par, self.z_none, self.settings.final_jacobians)
            self.converged[""] = self.settled(pol, pol.fitness)
            self.set_none(pol.z, pol.fitness, self.none_row["evaluations"] + pol.evaluations, rescore_ranking=False)
        fit = self.refits[lead["effect"]]
        pol = self.polish_quietly(fit.ext, fit.z, self.settings.final_jacobians)
        g = pol.fitness
        fit = self.refits[lead["effect"]] = Fit(fit.ext, pol.z, fit.evaluations + pol.evaluations)
        self.converged[lead["effect"]] = self.settled(pol, g)
        row = self.held_out(lead["effect"], fit.params(), fit.ext.extra, g, fit.evaluations, self.mse_none)
        row.update({k: lead[k] for k in ("refitted", "screen") if k in lead})
        self.ranking[self.ranking.index(lead)] = row
        self.log(f"  {lead['effect']:14s} refined (base refit continued alike): " + ", ".join(
            f"{k} = {v:.4g} {UNITS[k]}" for k, v in row["parameters"].items())
            + f"  validation MSE {row['validation_mse_change_pct']:+6.1f} %  score {row['score']:+.3f}"
            + f"  identification RMSE {row['identification_rmse_n']:.1f} N (none: "
            + f"{self.none_row['identification_rmse_n']:.1f} N)")
        self.promote([lead["effect"]])

    def base_settled(self) -> bool:
        """The base refit ('none') is where it settled (``refit_none``): not moved since (``promote``)."""
        return self.z_settled is not None and self.converged.get("") is True \
            and np.array_equal(self.z_settled, self.z_none)

    def intervals(self) -> None:
        """Significance: a 95 % interval of the magnitude (correlated residuals: block sandwich) for every
        extension that earned its score with a force above the noise; then the cross-check of a fitted
        delay with the one the base residual shows (the refit alone can trade a delay for table changes)."""
        for row in self.ranking:
            if row["effect"] != "none" and scores(row):
                fit = self.refits[row["effect"]]
                ci = effect_intervals(self.eid, fit.ext, fit.z)
                attach_interval(row, ci, fit.ext, fit.ext.extra)
                self.log(f"  {row['effect']:14s} 95 % interval " + ", ".join(
                    f"{n} {fmt_quantity(ci[n]['low'], UNITS[n])} .. {fmt_quantity(ci[n]['high'], UNITS[n])}"
                    for n in fit.ext.extra) + f" ({ci['_blocks']} residual blocks of "
                    f"{3 * ci['_correlation_time_s']:.2g} s): " + ("excludes zero" if row["significant"]
                                                                    else "NOT distinct from zero"))
        for r in cross_check(self.ranking, self.evidence):
            self.log(f"  time_delay {1e3 * r['parameters']['time_delay']:.3g} ms disagrees with the residual's "
                     f"delay: not a cause")

    def above_floor(self, rmse: float, floor: float | None = None) -> bool:
        """An identification RMSE [N] above UNEXPLAINED_RATIO x a credible floor (``floor`` [N], the base's when
        None): a structured residual."""
        return self.credible and rmse > UNEXPLAINED_RATIO * (self.floor if floor is None else floor)

    def floor_of(self, causes: list[str]) -> tuple[float, float]:
        """(stroke noise through the model [N rms], its residual floor [N]) of the base with ``causes``: each model
        is judged against what the stroke channel's noise makes through it. A free play's contact is a stiffer
        path from the stroke to the force than the soft table the base absorbed the gap into (a 0.057 mm gap
        between 9e7 N/m silent blocks: 297 N rms through the true model, 16 N through the base); its residual
        left at that level is measurement noise, not a model-form error."""
        if not causes:
            return self.stroke_noise_n, self.floor
        key = "+".join(causes)
        if key not in self.floors:
            sn = self.data.residual_floor(self.settings.engine).stroke_noise_n(self.kind, self.refits[key].params())
            self.floors[key] = (sn, math.hypot(self.noise, sn))
            if abs(sn - self.stroke_noise_n) > 0.1 * self.floor:
                self.log(f"diagnosis: stroke noise through the model with {key} {sn:.1f} N rms (the base's "
                         f"{self.stroke_noise_n:.1f} N); its residual floor {self.floors[key][1]:.1f} N")
        return self.floors[key]

    def fit_form(self, form: str, ext: ExtendedParametrization, jac, current: dict, sse_cur: float):
        """One form on top of the model ``current`` (its values; identification SSE ``sse_cur`` [N^2]): the
        shape screen picks two shapes, those predicted to win SCREEN_SHARE of the SSE are refitted (profile
        of the magnitude with the model re-balanced, joint polish), best predicted first, the better kept
        (by identification fitness, as between the shapes). A shape is refitted only when its predicted
        gain is also at least FORM_REFIT_EXCESS of the identification residual power above the floor: a form
        is named only when it removes FORM_EXCESS_SHARE of the held-out one, and a shape predicted to win
        less than a fifth of that cannot plausibly get there (on the real MR damper a hysteresis predicted 6 %
        of an error at 9 x the floor took 70 s of refits and won 1 %). A later shape is refitted only when its
        predicted gain exceeds the gain the best refit so far realised: otherwise it could win only if its
        linearised prediction fell short, and on real data it is the refit that costs (two-chamber, 30 s).
        With none predicted to win SCREEN_SHARE, the form is ranked at its best screened point. Returns
        (Fit or None, fitness, screen rows, whether a shape was refitted); each screen row says whether it
        was refitted."""
        magnitude = ALL_EFFECTS[form].identified[0]
        knee = self.evidence.get("knee_velocity")
        shapes = screen(self.eid, ext, form, current, jac, knee_m_s=knee)
        for cand in shapes:
            cand["predicted_share"] = cand["gain_n2"] / sse_cur if sse_cur > 0 else 0.0
            cand["refitted"] = False
        best, g = None, -math.inf
        evals = len(shape_grid(form, dict(zip(ext.extra, ext.extra_bounds)), knee)) + 1
        excess = sse_cur - self.eid.n_samples * self.floor ** 2  # the identification residual power above the floor
        to_refit = [c for c in shapes if c["predicted_share"] >= SCREEN_SHARE
                    and c["gain_n2"] >= FORM_REFIT_EXCESS * max(excess, 0.0)]
        for cand in to_refit or shapes[:1]:  # the shape's settings (direction, fade speed) are fixed in its model
            ext_c = ExtendedParametrization(self.par, ext.effect, self.peak, self.stroke_range, self.stroke_limits,
                                            fixed={k: v for k, v in cand["shape"].items() if k not in ext.extra})
            if not to_refit:  # ranked at its best screened shape, the magnitude that fits best with the model held
                z = ext_c.from_params({**current, **cand["shape"], magnitude: cand["held_magnitude"]})
                best, g = Fit(ext_c, z, evals), self.eid.n_samples / float(self.eid.sse_batch([ext_c.to_params(z)])[0])
                break
            if best is not None and not cand["gain_n2"] > sse_cur - self.eid.n_samples / g:
                continue  # predicted to win less than the refit already realised
            z0 = ext_c.from_params({**current, **cand["shape"], magnitude: 0.0})
            fit = refit(self.eid, ext_c, z0, sse_cur, jac, self.settings, self.share,
                        profile=[ext.extra.index(magnitude)])
            evals += fit.evaluations
            cand["refitted"] = True
            if fit.fitness > g:
                best, g = Fit(ext_c, fit.z, 0), fit.fitness
        if best is not None:
            best.evaluations = evals
        return best, g, shapes, bool(to_refit)

    def forms(self, current: dict, current_row: dict, causes: list[str]) -> dict:
        """The forms beyond the catalogue (``settings.forms``, ``tuner.diagnosis.forms``) on top of the current
        model (values ``current``, ranking row ``current_row``: the base refit, or the model of the causes
        named). The best form is continued to convergence (``final_jacobians``) and given its interval; it
        is named on the rules of a cause (``earned``) against the current model, its magnitude standing for
        it and the score penalised for all its parameters, and when it removes at least FORM_EXCESS_SHARE of
        the held-out residual power above the floor. Returns {"form": name or None, "tried": rows, and for a
        named form "row", "refit" (a Fit) and "settled"}."""
        t0 = time.perf_counter()
        self.log(f"diagnosis: {' + '.join(causes) or 'the base'} leaves a residual above the floor: trying the forms "
                 f"beyond the catalogue ({', '.join(self.settings.forms)})")
        sse_cur = float(self.eid.sse_batch([current])[0])
        rows, fits, jac = [], {}, None
        for form in self.settings.forms:
            ext = ExtendedParametrization(self.par, "+".join([*causes, form]), self.peak, self.stroke_range,
                                          self.stroke_limits)
            if jac is None:  # the current model's Jacobian (its causes included), shared by the forms
                z_off = ext.from_params({**current, ALL_EFFECTS[form].identified[0]: 0.0})
                jac = base_jacobian(self.eid, ext, z_off, dims=ext.dimension - len(ALL_EFFECTS[form].identified))
            fit, g, shapes, refitted = self.fit_form(form, ext, jac, current, sse_cur)
            if fit is None:
                self.log(f"  form {form:10s} cannot be simulated on these tests")
                continue
            row = self.form_row(form, fit, g, current_row)
            row["screen"], row["refitted"], row["elapsed_s"] = shapes, refitted, time.perf_counter() - t0
            fits[form] = fit
            rows.append(row)
            names = ALL_EFFECTS[form].identified
            self.log(f"  form {form:10s} " + ", ".join(f"{n} = {fmt_quantity(row['parameters'][n], UNITS[n])}"
                                                       for n in names)
                     + (f" ({settings_text(fit.ext.fixed)})" if fit.ext.fixed else "")
                     + f"  validation MSE {row['validation_mse_change_pct']:+6.1f} %  score {row['score']:+.3f}"
                     + f"  effect {row['effect_rms_n']:.3g} N rms{'' if row['resolved'] else ' (below the noise)'}"
                     + f"  [{row['elapsed_s']:.0f} s]")
        if not rows:
            return {"form": None, "tried": rows}
        return self.name_form(rows, fits, current_row)

    def form_row(self, form: str, fit: Fit, g: float, current_row: dict) -> dict:
        """The ranking row of a form's refit against the current model's row (its magnitude is what is new;
        the score is penalised for all its parameters)."""
        row = self.held_out(fit.ext.effect, fit.params(), fit.ext.extra, g, fit.evaluations,
                            current_row["validation_mse"], new=ALL_EFFECTS[form].identified[:1],
                            n_params=len(ALL_EFFECTS[form].identified))
        row["added"], row["form"], row["settings"] = form, FORM_LABELS[form], dict(fit.ext.fixed)
        row["excess_explained"] = excess_explained(row, current_row, self.floor)
        return row

    def name_form(self, rows: list[dict], fits: dict, current_row: dict) -> dict:
        """The best form of ``rows`` continued, given its interval and named when it earns it (``forms``)."""
        lead = max(rows, key=lambda r: r["score"] if r["resolved"] else -math.inf)
        form = lead["added"]
        fit = fits[form]
        pol = None  # not continued: not settled
        if scores(lead):
            if self.settings.final_jacobians > 0:
                pol = self.polish_quietly(fit.ext, fit.z, self.settings.final_jacobians)
                fit = fits[form] = Fit(fit.ext, pol.z, fit.evaluations + pol.evaluations)
                row = self.form_row(form, fit, pol.fitness, current_row)
                row.update({k: lead[k] for k in ("screen", "refitted", "elapsed_s")})
                rows[rows.index(lead)] = lead = row
            attach_interval(lead, effect_intervals(self.eid, fit.ext, fit.z), fit.ext, ALL_EFFECTS[form].identified[:1])
        if lead["score"] > ACCEPT_SCORE and earned(lead) and lead["excess_explained"] >= FORM_EXCESS_SHARE:
            self.log(f"  form earns its parameters: {FORM_LABELS[form]} (" + interval_text(lead, ALL_EFFECTS[form].identified)
                     + f"), validation MSE {lead['validation_mse_change_pct']:+.0f} %, score {lead['score']:+.3f}")
            return {"form": form, "tried": rows, "row": lead, "refit": fit,
                    "settled": pol is not None and self.settled(pol, lead["identification_rmse_n"] ** -2)}
        self.log("  no form beyond the catalogue earns its parameters" + (
            f" (the best, {form}, removes {100 * lead['excess_explained']:.0f} % of the held-out residual above the "
            f"floor)" if lead["score"] > ACCEPT_SCORE and earned(lead) else ""))
        return {"form": None, "tried": rows}

    def next_cause(self, current: Fit, current_row: dict) -> dict:
        """One forward-selection step from the current model (``current``: the Fit of the causes selected so
        far, ``current_row`` its ranking row). Every catalogue effect not selected yet that earned its score
        alone with a resolved force, and every other one the screen on top of the current model passes
        (``rescreened``), is added to the current model and refitted as in the first round; the best is
        continued to convergence. It is named when, against
        the current model, it earns a cause's rules. Returns {"cause": effect or 'none', "tried": rows, and
        for a named cause "row" and "refit"}."""
        others = [r["effect"] for r in self.ranking if r["effect"] not in current.ext.effects and r["effect"] != "none"
                  and "+" not in r["effect"] and scores(r)]
        left = [e for e in self.settings.candidates if e not in current.ext.effects and e not in others]
        exts = {e: ExtendedParametrization(self.par, f"{current.ext.effect}+{e}", self.peak, current.ext.stroke_range_m,
                                           current.ext.stroke_limits, fixed=current.ext.fixed) for e in others + left}
        if not exts:
            return {"cause": "none", "tried": []}
        params_cur = current.params()
        sse_cur = float(self.eid.sse_batch([params_cur])[0])
        first = next(iter(exts.values()))  # every new effect is off at the current point: its Jacobian, shared
        jac = base_jacobian(self.eid, first, first.from_params(params_cur), dims=self.par.dimension)
        others += self.rescreened(params_cur, {e: exts[e] for e in left}, jac, current.ext.effect)
        if not others:
            return {"cause": "none", "tried": []}
        rows, fits = [], {}
        for e in others:
            ext = exts[e]
            z0 = ext.from_params({**params_cur, **{n: 0.0 for n in ALL_EFFECTS[e].identified}})
            fit = refit(self.eid, ext, z0, sse_cur, jac, self.settings, self.share,
                        profile=range(len(current.ext.extra), len(ext.extra)))
            fits[ext.effect] = Fit(ext, fit.z, fit.evaluations)
            row = self.held_out(ext.effect, ext.to_params(fit.z), ext.extra, fit.fitness, fit.evaluations,
                                current_row["validation_mse"],
                                new=ALL_EFFECTS[e].identified)
            row["added"] = e
            rows.append(row)
            self.log(f"  + {e:12s} on {current.ext.effect}: " + ", ".join(
                f"{k} = {row['parameters'][k]:.4g} {UNITS[k]}" for k in ALL_EFFECTS[e].identified)
                + f"  validation MSE {row['validation_mse_change_pct']:+6.1f} %  score {row['score']:+.3f}"
                + f"  effect {row['effect_rms_n']:.3g} N rms{'' if row['resolved'] else ' (below the noise)'}")
        return self.name_next(rows, fits, current_row)

    def rescreened(self, current: dict, exts: dict, jac, key: str) -> list[str]:
        """The candidates that did not score alone (``exts``: {effect: the current model extended by it}), screened
        again on top of the current model (its values ``current``, Jacobian ``jac``; ``key`` its causes): a fault
        hidden beside another one can be screened out, or refitted without earning its score, while the other is
        unexplained (a worn damper's 180 N rod-seal friction beside a 0.35 mm free play: its refit on the base
        scored -3.3 %). Returns those predicted to win SCREEN_SHARE of the current identification SSE: they are
        refitted on the current model with the candidates that scored alone."""
        if not exts:
            return []
        screened = profile_screen(self.eid, exts, current, jac, self.settings.grid_points)
        passed = [e for e in exts if e in screened and screened[e].passes]
        self.log(f"  screen on top of {key} (the candidates that did not score alone): " + ", ".join(
            f"{e} {100 * r.share:.1f} %" for e, r in screened.items()) + "; refitted: "
            + (", ".join(passed) or "none"))
        return passed

    def name_next(self, rows: list[dict], fits: dict, current_row: dict) -> dict:
        """The best of a forward-selection step's rows continued, given intervals, and named if earned."""
        lead = max(rows, key=lambda r: r["score"] if r["resolved"] else -math.inf)
        if scores(lead) and self.settings.final_jacobians > 0:
            fit = fits[lead["effect"]]
            pol = self.polish_quietly(fit.ext, fit.z, self.settings.final_jacobians)
            fit = fits[lead["effect"]] = Fit(fit.ext, pol.z, fit.evaluations + pol.evaluations)
            row = self.held_out(fit.ext.effect, fit.params(), fit.ext.extra, pol.fitness, fit.evaluations,
                                current_row["validation_mse"], new=ALL_EFFECTS[lead["added"]].identified)
            row["added"] = lead["added"]
            rows[rows.index(lead)] = row
        cross_check(rows, self.evidence)
        for row in rows:
            if scores(row):
                fit = fits[row["effect"]]
                attach_interval(row, effect_intervals(self.eid, fit.ext, fit.z), fit.ext,
                                ALL_EFFECTS[row["added"]].identified)
        named = [r for r in sorted(rows, key=lambda r: -r["score"]) if r["score"] > ACCEPT_SCORE and earned(r)]
        if not named:
            self.log(f"  no further cause on top of {current_row['effect']}")
            return {"cause": "none", "tried": rows}
        self.log(f"  further cause: {named[0]['added']} (" + interval_text(named[0])
                 + f"), score {named[0]['score']:+.3f}")
        return {"cause": named[0]["added"], "tried": rows, "row": named[0], "refit": fits[named[0]["effect"]]}

    def weigh_forms(self, cause: str, best: dict):
        """Forms weighed with the causes: where the base leaves a residual above the floor and the cause's
        model still does, the catalogue's cause may only patch a form gap; the forms are fitted on the base
        refitted alike, and a form named on its own rules that scores above the cause is the first cause (the
        catalogue effects then have to earn their place on top of it). A cause whose model reaches the floor
        patches nothing: the forms are not weighed (on a 0.114 mm gap in stiff two-chamber mounts, named at
        1.02 x the floor, they took 80 s for nothing). Returns (cause, its row, the forms' step or None)."""
        if not (cause != "none" and self.settings.forms and self.above_floor(self.none_row["identification_rmse_n"])):
            return cause, best, None
        floor = self.floor_of([cause])[1]
        if not self.above_floor(best["identification_rmse_n"], floor):
            # the cause leaves no structured residual: it patches no gap, and a form in its place could only tie
            self.log(f"  {cause} leaves no residual above the floor ({best['identification_rmse_n']:.1f} N, floor "
                     f"{floor:.1f} N): no form is weighed against it")
            return cause, best, None
        self.at("forms weighed with the causes")
        weighed = self.forms(self.par.to_params(self.z_none), self.none_row, [])
        if weighed["form"] is not None and not weighed["row"]["score"] > best["score"]:
            self.log(f"  {cause} scores above the form {weighed['form']} on the base ({best['score']:+.3f} against "
                     f"{weighed['row']['score']:+.3f}): {cause} stays the first cause")
        if weighed["form"] is not None and weighed["row"]["score"] > best["score"]:
            self.log(f"  the form {weighed['form']} scores above {cause} on the base ({weighed['row']['score']:+.3f} "
                     f"against {best['score']:+.3f}): it is the first cause")
            cause, best = weighed["form"], weighed["row"]
            self.refits[cause] = weighed.pop("refit")
            self.converged[cause] = weighed.pop("settled")
            weighed["first"] = True
        return cause, best, weighed

    def select(self, causes: list[str], best: dict, selection: list) -> dict:
        """Forward selection: add the best significant effect to the causes found, refit, repeat (up to
        ``max_causes``); returns the final model's row (``causes`` and ``selection`` grow in place)."""
        while causes and len(causes) < self.settings.max_causes:
            step = self.next_cause(self.refits["+".join(causes)], best)
            selection.append(step)
            if step["cause"] == "none":
                break
            causes.append(step["cause"])
            self.refits["+".join(causes)] = step.pop("refit")
            best = step.pop("row")
        return best

    def continue_base(self) -> None:
        """An 'unexplained' verdict (a model-form error) must rest on a converged fit: with nothing named and
        the residual above the floor, the base refit is continued until its first-order test holds (or the
        cap, reported)."""
        if not (self.above_floor(self.none_row["identification_rmse_n"]) and self.settings.final_jacobians > 0
                and "" not in self.converged):
            return
        self.at("base refit continued")
        pol = self.polish_quietly(self.par, self.z_none, self.settings.final_jacobians)
        self.converged[""] = self.settled(pol, pol.fitness)
        self.log(f"  none           base refit continued before any 'unexplained': identification RMSE "
                 f"{self.none_row['identification_rmse_n']:.1f} -> {1 / math.sqrt(pol.fitness):.1f} N, {pol.stop}")
        if pol.fitness > self.g_none:
            self.set_none(pol.z, pol.fitness, self.none_row["evaluations"] + pol.evaluations)

    def forms_on_top(self, cause: str, causes: list[str], best: dict):
        """The forms beyond the catalogue on top of what the catalogue found, when that leaves a residual above
        the floor on a settled fit (an unfinished one is no evidence of a missing element). Returns (cause,
        the final row, the forms' step or None); a form named joins ``causes``."""
        key = "+".join(causes)
        rmse_now = best["identification_rmse_n"] if causes else self.none_row["identification_rmse_n"]
        if not (self.settings.forms and self.above_floor(rmse_now, self.floor_of(causes)[1])
                and self.converged.get(key) is not False):
            return cause, best, None
        current = self.refits[key].params() if causes else self.par.to_params(self.z_none)
        self.at("forms beyond the catalogue", 0.9)
        step = self.forms(current, best if causes else self.none_row, causes)
        if step["form"] is not None:
            causes.append(step["form"])
            key = "+".join(causes)
            self.refits[key] = step.pop("refit")
            self.converged[key] = step.pop("settled")
            best = step["row"]
            if cause in ("none", "unexplained"):
                cause = step["form"]
        return cause, best, step

    def run(self) -> dict:
        """The steps in order (class docstring); the result fields for this base."""
        self.at("residual analysis")
        self.residual_floor()
        self.residual_evidence()
        kw = dict(engine=self.settings.engine, workers=self.settings.workers,
                  fmu_path=ensure_fmu(self.kind) if self.settings.engine == "fmu" else None)
        with Engine(self.kind, self.data.sig_id, **kw) as self.eid, Engine(self.kind, self.data.sig_val, **kw) as self.ev:
            self.eid.after_batch = self.ev.after_batch = self.tick
            self.at("candidate refits")
            self.record["partial"]["ranking"] = self.ranking
            self.t_engines = time.perf_counter()
            self.refit_none()
            self.cost = expected_cost(self.par.dimension, self.settings, settled=True, held_out_share=sum(
                self.lengths) / self.eid.n_samples, forms_run=bool(self.settings.forms) and self.above_floor(
                self.none_row["identification_rmse_n"]))
            self.cost.done("reference")
            self.forecast()
            advance(self.log, 0.2)
            self.candidates()
            advance(self.log, 0.7)
            end, first = self.concluded()
            self.at("detection limits", 0.95)
            limits = detection(self.eid, self.ev, self.par, self.z_none,
                               [e for e in self.settings.candidates if e not in end.causes], self.peak,
                               self.stroke_range, self.mse_none, self.noise, self.lengths,
                               [s.name for s in self.data.sig_val], self.log)
            self.step_done("detection")
            self.log(f"diagnosis on the {self.kind} base: {self.eid.evaluations} simulations of the identification "
                     f"tests and {self.ev.evaluations} of the held-out ones in {time.perf_counter() - self.t_engines:.0f} s")
        return {**self.result(end, limits), "before_rescue": before_rescue(first)}

    def concluded(self) -> tuple[Conclusion, Conclusion | None]:
        """The conclusion from the candidates' rows and, when it names nothing, again after the nonsmooth candidates
        no screen passed are refitted (``refit_unseen_nonsmooth``) if one of them scores: (the conclusion, the one it
        replaced or None)."""
        end = self.conclude([r["effect"] for r in self.ranking if r["refitted"]])
        if end.causes:
            return end, None
        rescued = self.refit_unseen_nonsmooth()
        if any(scores(r) for r in self.ranking if r["effect"] in rescued):
            return self.conclude(rescued), end
        return end, None

    def conclude(self, refitted: list[str]) -> Conclusion:
        """From the candidates' rows (``refitted``: the effects refitted since the last ranking) to the causes:
        the ranking and its first decision (``rank``), the forms weighed with it, the forward selection, the base
        refit continued before an 'unexplained', the forms on top of what was found."""
        cause, best, unresolved = self.rank(refitted)
        cause, best, weighed = self.weigh_forms(cause, best)
        if weighed is not None:  # one pass of the forms done
            self.cost.forms = max(0.0, self.cost.forms - form_pass_cost(self.par.dimension, self.settings))
        causes, selection = ([cause] if cause != "none" else []), []
        self.at("forward selection", 0.85)
        self.record["partial"].update(causes=causes, selection=selection)
        best = self.select(causes, best, selection)
        self.step_done("selection")
        if not causes:
            self.continue_base()
        form_step = weighed if weighed is not None and weighed.get("first") else None
        if form_step is None:
            cause, best, form_step = self.forms_on_top(cause, causes, best)
        self.step_done("forms")
        return Conclusion(cause, causes, best, unresolved, selection, form_step, weighed)

    def base_refit_record(self) -> dict:
        """``diagnosis.json``'s ``base_refit``: the fitted base's identification RMSE [N] beside the base refitted
        alike at the end ('none', after any promotion), and one standard error of the RMSE [N]. ``fit_converged``:
        the refit ends no more than that below the fit (else the fit had stopped short of its minimum and the
        diagnosis ran from a better base than the fit's report and FMUs carry; the log says so)."""
        refit = self.none_row["identification_rmse_n"]
        converged = not (self.fit_base_rmse_n - refit > self.resolvable_n)
        if not converged:
            self.log(f"diagnosis: the base refitted alike ends at {refit:.2f} N, {self.fit_base_rmse_n - refit:.2f} N "
                     f"below the fit's {self.fit_base_rmse_n:.2f} N (more than one standard error, "
                     f"{self.resolvable_n:.2g} N): the fit was not converged; its report and FMUs carry the higher point")
        fit = self.fit_base_rmse_n if math.isfinite(self.fit_base_rmse_n) else None
        return {"fit_rmse_n": fit, "refit_rmse_n": refit, "standard_error_n": self.resolvable_n,
                "fit_converged": converged if fit is not None else None}

    def result(self, end: Conclusion, limits: dict) -> dict:
        """What the final model of ``end`` leaves (at the floor, or 'unexplained'), the validation before and after
        in the Table 3 definition (the FMU at its own steps, so that "before" is the Table 3 figure of the same base
        model), the verdict with the detection ``limits``, and the result fields."""
        cause, causes, best, form_step, weighed = end.cause, end.causes, end.best, end.form_step, end.weighed
        final_rmse = best["identification_rmse_n"] if causes else self.none_row["identification_rmse_n"]
        stroke_noise, floor = self.floor_of(causes)
        unexplained = None
        if self.above_floor(final_rmse, floor):
            unexplained = unexplained_record(final_rmse, self.noise, floor, stroke_noise, self.evidence,
                                             self.converged.get("+".join(causes)))
            unexplained["indistinguishable"] = indistinguishable(self.ranking, end.selection, limits)
            if not causes:
                cause = "unexplained"
        after_params = self.refits["+".join(causes)].params() if causes else self.base
        self.at("validation before and after", 0.98)
        validation, base_metrics, final_metrics = before_after(self.kind, self.base, after_params if causes else None,
                                                               self.data.sig_val, self.settings.engine)
        verdict = verdict_text(causes, best, self.none_row, end.unresolved, unexplained, self.noise, limits, form_step)
        if not self.credible:
            verdict += (f". The remaining residual, {final_rmse:.3g} N rms, is not compared with the residual floor: "
                        f"{self.not_credible}")
        return {"cause": cause, "causes": causes, "verdict": verdict, "selection": end.selection,
                "detection_limits": limits, "form": form_step["form"] if form_step else None,
                "forms_tried": form_step["tried"] if form_step else None,
                "forms_weighed": weighed["tried"] if weighed else None,
                "unexplained": unexplained, "ranking": self.ranking,
                "effect_parameters": effect_parameters(best, self.size) if causes else {},
                "validation": validation, "evidence": self.evidence, "figures": self.figures,
                "note": " ".join(NOTES[c] for c in causes if c in NOTES), "noise_std_n": self.noise,
                "noise": self.data.noise,  # how the noise was estimated (tuner.data.noise.pooled_noise)
                "residual_floor_credible": self.credible,
                "stroke_noise_force_n": self.stroke_noise_n, "residual_floor_n": self.floor,
                "final_stroke_noise_force_n": stroke_noise, "final_residual_floor_n": floor,
                "base_model": self.kind, "base_parameters": {k: self.base[k] for k in self.par.names},
                "base_refit": self.base_refit_record(),
                "after_params": after_params, "final_validation_mse": pooled_mse(final_metrics),
                "base_validation_mse": pooled_mse(base_metrics)}


def before_rescue(first: Conclusion | None) -> dict | None:
    """``diagnosis.json``'s record of a conclusion a rescue replaced (``CandidateSearch.concluded``): its cause and
    the forms it tried and weighed (their rows), so that the forms tried before are not lost; None without one."""
    if first is None:
        return None
    return {"cause": first.cause, "forms_tried": first.form_step["tried"] if first.form_step else None,
            "forms_weighed": first.weighed["tried"] if first.weighed else None}


@dataclass
class BaseRun:
    """The diagnosis on one base form: ``run``, the result fields of ``diagnosis.json`` for this base plus
    ``after_params``, ``final_validation_mse`` and ``base_validation_mse`` (``CandidateSearch``); ``figures``,
    the folder of its figures (relative to the output folder; ``run['figures']`` names the files); ``residuals``,
    the base model's residual on every test (``base_residuals``), which they show."""

    run: dict
    figures: str
    residuals: list[TestResidual]


def diagnose_on(kind: str, base: Base, data: Problem, settings: DiagnosisSettings, figures: str, log,
                record: dict | None = None) -> BaseRun:
    """The diagnosis on one base form (``CandidateSearch(...).run()``), its figures named in the folder
    ``figures``."""
    search = CandidateSearch(kind, base.par, base.values, data, settings, figures, log, record,
                             refinement=base.refinement)
    return BaseRun(search.run(), figures, search.residuals)


def detection(eid: Engine, ev: Engine, par: Parametrization, z: np.ndarray, candidates: list[str], peak: float,
               stroke_range: float, mse_ref: float, noise: float, lengths: list[int], tests: list[str], log) -> dict:
    """``tuner.diagnosis.detection.detection_limits`` of ``candidates`` at the base refit ``z`` with the
    diagnosis's rules (acceptance score, penalty, search bounds, physical range); logged, units added."""
    names = {e: ALL_EFFECTS[e].identified[0] for e in candidates}
    size = DamperSize(peak, stroke_range)
    limits = detection_limits(eid, ev, par, z, names, {n: typical_range(n, size)[0] for n in names.values()},
                              {n: search_bounds(n, peak, stroke_range) for n in names.values()},
                              {n: meaningful_floor(n, size) for n in names.values()}, mse_ref, noise,
                              ACCEPT_SCORE, PENALTY_PER_PARAMETER, lengths, tests)
    for e, r in limits.items():
        r["unit"], r["covers"] = UNITS[r["parameter"]], ALL_EFFECTS[e].kind
        r["absorbed_by"] = absorbing_groups(par, r.pop("absorbed_by_coordinate"))
    if limits:
        log("diagnosis: detection limits on these tests (the smallest magnitude that would have been named): "
            + ", ".join(f"{e} {limit_text(r)}" for e, r in limits.items()))
    return limits


def absorbing_groups(par: Parametrization, parts: list[float]) -> dict[str, float]:
    """{element: its share of the absorbed force} (``tuner.diagnosis.detection.absorption``'s parts per coordinate
    of ``par`` summed by ``damper_fmu.parameters.parameter_group``), the elements carrying at least 10 %, largest
    first."""
    groups: dict[str, float] = {}
    for name, part in zip(par.names, parts):
        g = parameter_group(par.model, name)
        groups[g] = groups.get(g, 0.0) + float(part)
    return dict(sorted(((g, v) for g, v in groups.items() if v >= 0.1), key=lambda kv: -kv[1]))


def before_after(kind: str, base: dict, after: dict | None, signals: list, engine: str):
    """(per test {mse/ame before and after, change}, base metrics, final metrics) in the Table 3
    definition (``validation_run``: the FMU at its own steps), so that "before" is the Table 3 figure
    of the same base model; ``after`` None: nothing was added (after = before)."""
    validation, base_metrics, final_metrics = {}, [], []
    for s in signals:
        mb = validation_run(kind, base, s, engine)[1]
        base_metrics.append(mb)
        ma = validation_run(kind, after, s, engine)[1] if after is not None else mb
        final_metrics.append(ma)
        validation[s.name] = {"mse_before": mb["mse"], "ame_before": mb["ame"], "mse_after": ma["mse"],
                              "ame_after": ma["ame"], "mse_change_pct": 100 * (ma["mse"] / mb["mse"] - 1)}
    return validation, base_metrics, final_metrics
