"""The reference of every score: the base model's residual floor and evidence, and the base refitted alike
('none': ``refit_none``, moved by ``set_none``, continued by ``continue_base``), with its record in
``diagnosis.json`` (``base_refit_record``). SI units; forces in N."""
from __future__ import annotations

import math

import numpy as np

from tuner.diagnosis.extended_parametrization import base_jacobian
from tuner.diagnosis.residual_tests import TestResidual
from tuner.diagnosis.residuals import evidence as residual_evidence_of, figure_files
from tuner.diagnosis.rules import rescore
from tuner.diagnosis.search.rows import held_out
from tuner.diagnosis.search.state import SearchState, base_point
from tuner.identification.fit import validation_run
from tuner.identification.polish import PolishResult
from tuner.identification.problem import Problem
from tuner.metrics import rmse_standard_error

__all__ = ["base_residuals", "residual_floor", "residual_evidence", "refit_none", "set_none", "base_settled",
           "continue_base", "base_refit_record"]


def base_residuals(kind: str, values: dict, data: Problem, settings) -> list[TestResidual]:
    """The base model's residual (measured - simulated force [N]) on every test of ``data``, identification
    then validation, simulated as the validation does (``validation_run``: the FMU at its own steps) at
    ``base_point(kind, values)``: the evidence's and the figures' series."""
    point = base_point(kind, values)
    return [TestResidual(p.name, p.role or "", p.time, p.stroke, p.stroke_velocity, p.force,
                         validation_run(kind, point, s, settings.engine)[0], s.mask, s.temperature)
            for p, s in zip([*data.prep_id, *data.prep_val], [*data.sig_id, *data.sig_val])]


def residual_floor(s: SearchState) -> None:
    """The floor of 'explained' [N rms]: the force noise and what the stroke channel's noise makes through
    the model's series stiffness (no model of the damper can remove it). A floor from a noise estimate
    that is not credible (filtered data, too few samples) decides nothing: no "N x the floor", no
    'unexplained' and no "settled" from a ratio against it."""
    s.stroke_noise_n = s.data.residual_floor(s.settings.engine).stroke_noise_n(s.kind, s.base)
    s.floor = math.hypot(s.noise, s.stroke_noise_n)
    s.credible = bool(s.data.noise.get("credible", True))
    s.not_credible = None if s.credible else s.data.noise.get("text", "noise estimate not credible")
    s.log(f"diagnosis: stroke noise through the base model {s.stroke_noise_n:.1f} N rms; residual floor "
          f"{s.floor:.1f} N" + ("" if s.credible else f" - not used to judge the residual: {s.not_credible}"))


def residual_evidence(s: SearchState) -> None:
    """Residual analysis of the base model: evidence numbers, the joint screen, and the series and file names
    of the figures (the job draws them, ``tuner.results.diagnosis_figures``)."""
    s.residuals = base_residuals(s.kind, s.base, s.data, s.settings)
    s.evidence = residual_evidence_of(s.residuals, noise_n=s.noise)
    s.figures = figure_files(s.figures_folder)
    scr = s.evidence["joint_screen"]
    s.log("diagnosis: joint screen of the residual on all catalogue signatures: "
          + (" + ".join(f"{e} ({scr['terms'][e]['contribution_n']:.3g} N)" for e in scr["kept"]) or "nothing")
          + f" above the noise, explaining {100 * scr['r2_kept']:.0f} % of the base residual; all seven "
            f"signatures together {100 * scr['r2_all']:.0f} %")


def set_none(s: SearchState, z: np.ndarray, g: float, evaluations: int, rescore_ranking: bool = True) -> None:
    """The base refitted alike ('none', the reference of every score) is now at ``z`` (fitness ``g``):
    its held-out MSE and ranking row; the ranking's scores are taken again against it (unless
    ``rescore_ranking`` is False: the lead's continuation, scored against it alone)."""
    s.z_none, s.g_none = z, g
    r = s.ev.residuals_batch([s.par.to_params(z)])[0]
    if r is not None:
        s.mse_none = float(r @ r) / sum(s.lengths)
    s.none_row = held_out(s, "none", s.par.to_params(z), [], g, evaluations, s.mse_none)
    if rescore_ranking:
        rescore([r for r in s.ranking if r["effect"] != "none"], s.mse_none)
    s.ranking[:] = [s.none_row if r["effect"] == "none" else r for r in s.ranking]


def fitted_base(s: SearchState) -> float:
    """The fitted base on both test sets (``refit_none``'s first part): its RMSEs logged, the least fall of the
    identification RMSE the data can show, the base Jacobian the refits share; returns its identification SSE
    [N^2]."""
    r_base = s.eid.residuals_batch([s.base])[0]
    sse_base = float(r_base @ r_base) if r_base is not None else math.inf
    # the least fall of the identification RMSE [N] the data can show (``tuner.metrics.rmse_standard_error``)
    s.resolvable_n = rmse_standard_error(r_base) if r_base is not None else 0.0
    s.fit_base_rmse_n = math.sqrt(sse_base / s.eid.n_samples)
    r_val = s.ev.residuals_batch([s.base])[0]
    s.mse_base = s.mse_none = float(r_val @ r_val) / sum(s.lengths)
    s.log(f"diagnosis: base model RMSE identification {math.sqrt(sse_base / s.eid.n_samples):.1f} N, "
          f"validation {math.sqrt(s.mse_base):.1f} N")
    s.jac_base = base_jacobian(s.eid, s.par, s.par.from_params(s.base))  # shared
    return sse_base


def refit_none(s: SearchState) -> None:
    """'none' is a candidate like the others: the base model refitted from the same starts (the fitted
    base and, with ``guess_start`` where the fitted base is not settled, the data-driven guess) with the
    same local effort, so that an unfinished base fit is never credited to an effect. A settled base (its
    refinement converged on these tests: ``Base.settled``) is its own refit: the same refinement from the
    point where it ended would end there again."""
    sse_base = fitted_base(s)
    s.starts = [(s.base, sse_base, s.jac_base)]
    s.share = max(1, s.settings.polish_jacobians // 2)  # the Jacobian budget, split between two starts
    if s.settled_by:  # the same refinement from the point where it converged ends there: not run again
        pol = PolishResult(z=s.par.from_params(s.base), fitness=s.eid.n_samples / sse_base, evaluations=0,
                           stop=f"settled: {s.settled_by}", converged=True, rule="settled", jacobians=0,
                           predicted=0.0, budget_spent=False)
        s.log(f"  none           the fitted base is settled (its refinement on these tests: {s.settled_by}): "
              f"it is the base refitted alike")
    else:
        pol = s.polish_quietly(s.par, s.par.from_params(s.base), s.share)
    z_none, g_none, evals = pol.z, pol.fitness, pol.evaluations
    # the data-driven guess has absorbed no effect into the tables; it is a second start only where the
    # fitted base is not settled (its refit spent the budget still improving): from a settled base the
    # profile line search re-balances what the tables absorbed
    s.one_start = bool(pol.converged) or not s.settings.guess_start
    if pol.converged:  # the base refit met its rule: an 'unexplained' can rest on it
        s.converged[""] = s.settled(pol, g_none)
        s.z_settled = pol.z if s.converged[""] else None
    if not s.one_start:
        s.starts.append((s.guess, math.inf, None))
        pol = s.polish_quietly(s.par, s.par.from_params(s.guess), s.share)
        evals += pol.evaluations
        if pol.fitness > g_none:
            z_none, g_none = pol.z, pol.fitness
    set_none(s, z_none, g_none, evals)
    s.log(f"  {'none':14s} (base refitted alike)  identification RMSE "
          f"{s.none_row['identification_rmse_n']:.1f} N, validation MSE "
          f"{100 * (s.mse_none / s.mse_base - 1):+6.1f} % vs the base fit"
          + ("; the fitted base is settled: one start for every refit" if s.one_start else ""))


def base_settled(s: SearchState) -> bool:
    """The base refit ('none') is where it settled (``refit_none``): not moved since (``selection.promote``)."""
    return s.z_settled is not None and s.converged.get("") is True and np.array_equal(s.z_settled, s.z_none)


def continue_base(s: SearchState) -> None:
    """An 'unexplained' verdict (a model-form error) must rest on a converged fit: with nothing named and
    the residual above the floor, the base refit is continued until its first-order test holds (or the
    cap, reported)."""
    if not (s.above_floor(s.none_row["identification_rmse_n"]) and s.settings.final_jacobians > 0
            and "" not in s.converged):
        return
    s.at("base refit continued")
    pol = s.polish_quietly(s.par, s.z_none, s.settings.final_jacobians)
    s.converged[""] = s.settled(pol, pol.fitness)
    s.log(f"  none           base refit continued before any 'unexplained': identification RMSE "
          f"{s.none_row['identification_rmse_n']:.1f} -> {1 / math.sqrt(pol.fitness):.1f} N, {pol.stop}")
    if pol.fitness > s.g_none:
        set_none(s, pol.z, pol.fitness, s.none_row["evaluations"] + pol.evaluations)


def base_refit_record(s: SearchState) -> dict:
    """``diagnosis.json``'s ``base_refit``: the fitted base's identification RMSE [N] beside the base refitted
    alike at the end ('none', after any promotion), and one standard error of the RMSE [N]. ``fit_converged``:
    the refit ends no more than that below the fit (else the fit had stopped short of its minimum and the
    diagnosis ran from a better base; the job then continues the fit from the refit's point,
    ``tuner.identification.best_point``, and rebuilds the FMUs and the report there). ``refit_values``: that point
    (the base's identified parameters [SI]); ``found_by``: the stage that found it."""
    refit = s.none_row["identification_rmse_n"]
    converged = not (s.fit_base_rmse_n - refit > s.resolvable_n)
    source = s.none_row.get("from_refit_of")
    found_by = (f"the diagnosis on the {s.kind} base: the {source} refit with its effect off" if source else
                f"the diagnosis on the {s.kind} base: the base refitted alike")
    if not converged:
        s.log(f"diagnosis: the base refitted alike ends at {refit:.2f} N, {s.fit_base_rmse_n - refit:.2f} N "
              f"below the fit's {s.fit_base_rmse_n:.2f} N (more than one standard error, "
              f"{s.resolvable_n:.2g} N): the fit was not converged (found by {found_by})")
    fit = s.fit_base_rmse_n if math.isfinite(s.fit_base_rmse_n) else None
    return {"fit_rmse_n": fit, "refit_rmse_n": refit, "standard_error_n": s.resolvable_n,
            "fit_converged": converged if fit is not None else None, "found_by": found_by,
            "refit_values": {k: float(v) for k, v in s.par.to_params(s.z_none).items() if k in s.par.names}}
