"""The best point is the result: a fit continued from a lower point that a later stage found.

A stage after the fit (the diagnosis's base refitted alike, a profile's point with its effect off) can end
lower than the fit on the same identification tests. When it does by more than one standard error of the RMSE
(``tuner.metrics.rmse_standard_error``: the least fall the data resolve), the fit had stopped short of its
minimum, and the user would get the FMU, intervals and report of a point the tool itself knows is not the
minimum. ``continue_fit`` continues the fit of that model from the lower point with its local refinement's usual
rules (``tuner.identification.polish``: projected Levenberg-Marquardt until its rule holds, the fit's Jacobian
budget), then takes the intervals and the validation through the FMU again, so that ``parameters.json``,
``metrics.json``, ``history_<model>.json`` and the tuned FMUs the job writes next are those of the final point.
The history says which stage found it (``best_point``). SI units; forces in N.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

from damper_fmu.fmu import ensure_fmu

from tuner.identification.engine import Engine
from tuner.identification.fit import FitResult, FitSettings, revalidate, model_intervals
from tuner.identification.polish import polish
from tuner.metrics import rmse_of_fitness
from tuner.time_budget import section

__all__ = ["LowerPoint", "lower_points", "continue_fit"]


@dataclass(frozen=True)
class LowerPoint:
    """A point of ``model`` [SI values of its identified parameters] that a later ``stage`` (words) found at the
    identification RMSE ``rmse_n`` [N], against the fit's ``fit_rmse_n`` [N] and one standard error
    ``standard_error_n`` [N] of the RMSE."""

    model: str
    values: dict
    rmse_n: float
    fit_rmse_n: float
    standard_error_n: float
    stage: str

    @property
    def lower_by_n(self) -> float:
        """How far [N] below the fit the point ends."""
        return self.fit_rmse_n - self.rmse_n


def lower_points(base_refits: dict, fitted: dict) -> list[LowerPoint]:
    """The points of the diagnosis's ``base_refits`` ({model: ``diagnosis.json``'s ``base_refit`` record}) that end
    more than one standard error below the fit (``fit_converged`` False), for the models the fit identified
    (``fitted``: ``FitResult.params``)."""
    out = []
    for model, rec in (base_refits or {}).items():
        if model not in fitted or rec.get("fit_converged") is not False or not rec.get("refit_values"):
            continue
        out.append(LowerPoint(model, dict(rec["refit_values"]), float(rec["refit_rmse_n"]), float(rec["fit_rmse_n"]),
                              float(rec["standard_error_n"]), rec.get("found_by") or "a later stage"))
    return out


def continue_fit(result: FitResult, lower: LowerPoint, settings: FitSettings, log=print) -> FitResult:
    """``result`` with the fit of ``lower.model`` continued from ``lower``'s point (module docstring): its values,
    intervals and history (``best_point``: the stage that found the point, the RMSEs [N] of the fit, the point and
    the continued fit, the refinement's rule) and every test's validation metrics, Table 3 and quality gate taken
    again. The continued fit is kept only where it ends below the fit (it starts lower, and the
    refinement never returns a point worse than its start). Changes ``result`` in place and returns it."""
    model, problem = lower.model, result.problem
    section(log, f"{model}: fit continued from a lower point")
    log(f"[{model}] {lower.stage} ended at {lower.rmse_n:.2f} N, {lower.lower_by_n:.2f} N below the fit's "
        f"{lower.fit_rmse_n:.2f} N (one standard error {lower.standard_error_n:.2g} N): the fit continues from there "
        f"with its usual rules, and its report, intervals and FMUs are rebuilt at the final point")
    par = problem.parametrization(model)
    t0 = time.perf_counter()
    with Engine(model, problem.sig_id, engine=settings.engine, workers=settings.workers,
                fmu_path=ensure_fmu(model) if settings.engine == "fmu" else None,
                max_internal_step=settings.data.internal_step_s) as eng:
        pol = polish(eng, par, par.from_params({**result.params[model]["values"], **lower.values}),
                     max_jacobians=max(1, settings.polish_jacobians), log=log)
        final = rmse_of_fitness(pol.fitness)
        kept = final < lower.fit_rmse_n
        values = par.to_params(pol.z)
        intervals = model_intervals(eng, model, problem.sig_id, par, values, log) if kept else {}
    hist = result.histories[model]
    hist["best_point"] = {"found_by": lower.stage, "fit_rmse_n": lower.fit_rmse_n, "found_rmse_n": lower.rmse_n,
                          "standard_error_n": lower.standard_error_n, "final_rmse_n": final, "kept": kept,
                          "rule": pol.rule, "stop": pol.stop, "converged": bool(pol.converged),
                          "jacobians": int(pol.jacobians), "evaluations": int(pol.evaluations),
                          "elapsed_s": time.perf_counter() - t0}
    if not kept:  # e.g. the point was outside this fit's bounds and clipped: the fit's own point stands
        log(f"[{model}] the fit continued from {lower.stage} ends at {final:.2f} N, not below the fit's "
            f"{lower.fit_rmse_n:.2f} N on its own design space: the fit's point is kept")
        return result
    hist.update({"best_fitness_final": float(pol.fitness), "identification_rmse_n": final,
                 "converged": bool(pol.converged), "converged_by": pol.rule if pol.converged else None,
                 "evaluation_count": int(hist.get("evaluation_count", 0)) + int(pol.evaluations)})
    result.params[model].pop("intervals_note", None)
    result.params[model].update({"values": values, **intervals})
    revalidate(result)
    log(f"[{model}] fit continued from {lower.stage}: identification RMSE {lower.fit_rmse_n:.2f} -> {final:.2f} N "
        f"({pol.stop}); {result.metrics['quality'][model]['text']}")
    return result
