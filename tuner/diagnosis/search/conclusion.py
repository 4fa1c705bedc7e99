"""Where the ranking of one base ends (``Conclusion``): the causes from the candidates' rows (``conclude``; again
after a rescue of the nonsmooth candidates, ``concluded``), and the result fields of ``diagnosis.json`` for the
base (``result``) with the validation before and after (``before_after``). SI units; forces in N."""
from __future__ import annotations

from dataclasses import dataclass

from tuner.diagnosis.cost_model import form_pass_cost
from tuner.diagnosis.rules import indistinguishable, scores
from tuner.diagnosis.search.form_steps import forms_on_top, weigh_forms
from tuner.diagnosis.search.nonsmooth import refit_unseen_nonsmooth
from tuner.diagnosis.search.reference import base_refit_record, continue_base
from tuner.diagnosis.search.selection import rank, select
from tuner.diagnosis.search.state import SearchState
from tuner.diagnosis.verdict import NOTES, effect_parameters, unexplained_record, verdict_text
from tuner.identification.fit import validation_run
from tuner.metrics import pooled_mse

__all__ = ["Conclusion", "concluded", "conclude", "before_rescue", "delay_share", "result", "before_after"]


@dataclass
class Conclusion:
    """Where the ranking of one base ends (``conclude``): the cause ('none', an effect or a form), every cause
    named (in order), the final model's ranking row, the rows not resolved, the forward selection's steps, the
    forms' step (or None) and the forms weighed with the first cause (or None)."""

    cause: str
    causes: list
    best: dict
    unresolved: list
    selection: list
    form_step: dict | None
    weighed: dict | None


def concluded(s: SearchState) -> tuple[Conclusion, Conclusion | None]:
    """The conclusion from the candidates' rows and, when it names nothing, again after the nonsmooth candidates
    no screen passed are refitted (``refit_unseen_nonsmooth``) if one of them scores: (the conclusion, the one it
    replaced or None)."""
    end = conclude(s, [r["effect"] for r in s.ranking if r["refitted"]])
    if end.causes:
        return end, None
    rescued = refit_unseen_nonsmooth(s)
    if any(scores(r) for r in s.ranking if r["effect"] in rescued):
        return conclude(s, rescued), end
    return end, None


def conclude(s: SearchState, refitted: list[str]) -> Conclusion:
    """From the candidates' rows (``refitted``: the effects refitted since the last ranking) to the causes:
    the ranking and its first decision (``rank``), the forms weighed with it, the forward selection, the base
    refit continued before an 'unexplained', the forms on top of what was found."""
    cause, best, unresolved = rank(s, refitted)
    cause, best, weighed = weigh_forms(s, cause, best)
    if weighed is not None:  # one pass of the forms done
        s.cost.forms = max(0.0, s.cost.forms - form_pass_cost(s.par.dimension, s.settings))
    causes, selection = ([cause] if cause != "none" else []), []
    s.at("forward selection", 0.85)
    s.record["partial"].update(causes=causes, selection=selection)
    best = select(s, causes, best, selection)
    s.step_done("selection")
    if not causes:
        continue_base(s)
    form_step = weighed if weighed is not None and weighed.get("first") else None
    if form_step is None:
        cause, best, form_step = forms_on_top(s, cause, causes, best)
    s.step_done("forms")
    return Conclusion(cause, causes, best, unresolved, selection, form_step, weighed)


def before_rescue(first: Conclusion | None) -> dict | None:
    """``diagnosis.json``'s record of a conclusion a rescue replaced (``concluded``): its cause and the forms it
    tried and weighed (their rows), so that the forms tried before are not lost; None without one."""
    if first is None:
        return None
    return {"cause": first.cause, "forms_tried": first.form_step["tried"] if first.form_step else None,
            "forms_weighed": first.weighed["tried"] if first.weighed else None}


def delay_share(ranking: list[dict], selection: list[dict]) -> float:
    """The share of the named delay's signature the base absorbs (``selection.delay_absorption``), from the row that
    added the delay (the first round's or a forward step's; the latest that has one); 0 without one."""
    rows = [*ranking, *(r for step in selection for r in step.get("tried", []))]
    shares = [r["delay_absorbed_share"] for r in rows
              if r.get("added", r["effect"]) == "time_delay" and "delay_absorbed_share" in r]
    return shares[-1] if shares else 0.0


def result(s: SearchState, end: Conclusion, limits: dict) -> dict:
    """What the final model of ``end`` leaves (at the floor, or 'unexplained'), the validation before and after
    in the Table 3 definition (the FMU at its own steps, so that "before" is the Table 3 figure of the same base
    model), the verdict with the detection ``limits``, and the result fields."""
    cause, causes, best, form_step, weighed = end.cause, end.causes, end.best, end.form_step, end.weighed
    final_rmse = best["identification_rmse_n"] if causes else s.none_row["identification_rmse_n"]
    stroke_noise, floor = s.floor_of(causes)
    unexplained = None
    if s.above_floor(final_rmse, floor):
        unexplained = unexplained_record(final_rmse, s.noise, floor, stroke_noise, s.evidence,
                                         s.converged.get("+".join(causes)))
        unexplained["indistinguishable"] = indistinguishable(s.ranking, end.selection, limits)
        if not causes:
            cause = "unexplained"
    if "time_delay" in causes:
        best["delay_absorbed_share"] = delay_share(s.ranking, end.selection)
    after_params = s.refits["+".join(causes)].params() if causes else s.base
    s.at("validation before and after", 0.98)
    validation, base_metrics, final_metrics = before_after(s.kind, s.base, after_params if causes else None,
                                                           s.data.sig_val, s.settings.engine)
    verdict = verdict_text(causes, best, s.none_row, end.unresolved, unexplained, s.noise, limits, form_step)
    if not s.credible:
        verdict += (f". The remaining residual, {final_rmse:.3g} N rms, is not compared with the residual floor: "
                    f"{s.not_credible}")
    return {"cause": cause, "causes": causes, "verdict": verdict, "selection": end.selection,
            "detection_limits": limits, "form": form_step["form"] if form_step else None,
            "forms_tried": form_step["tried"] if form_step else None,
            # a friction found as a pre-yield hysteresis at its Coulomb edge: that hysteresis's values (SI)
            "friction_found_as_hysteresis": form_step.get("coulomb") if form_step else None,
            "forms_weighed": weighed["tried"] if weighed else None,
            "unexplained": unexplained, "ranking": s.ranking,
            "effect_parameters": effect_parameters(best, s.size) if causes else {},
            "validation": validation, "evidence": s.evidence, "figures": s.figures,
            "note": " ".join(NOTES[c] for c in causes if c in NOTES), "noise_std_n": s.noise,
            "noise": s.data.noise,  # how the noise was estimated (tuner.data.noise.pooled_noise)
            "residual_floor_credible": s.credible,
            "stroke_noise_force_n": s.stroke_noise_n, "residual_floor_n": s.floor,
            "final_stroke_noise_force_n": stroke_noise, "final_residual_floor_n": floor,
            "base_model": s.kind, "base_parameters": {k: s.base[k] for k in s.par.names},
            "base_refit": base_refit_record(s),
            "after_params": after_params, "final_validation_mse": pooled_mse(final_metrics),
            "base_validation_mse": pooled_mse(base_metrics)}


def before_after(kind: str, base: dict, after: dict | None, signals: list, engine: str):
    """(per test {mse/ame before and after, change}, base metrics, final metrics) in the Table 3
    definition (``validation_run``: the FMU at its own steps), so that "before" is the Table 3 figure
    of the same base model; ``after`` None: nothing was added (after = before)."""
    validation, base_metrics, final_metrics = {}, [], []
    for sig in signals:
        mb = validation_run(kind, base, sig, engine)[1]
        base_metrics.append(mb)
        ma = validation_run(kind, after, sig, engine)[1] if after is not None else mb
        final_metrics.append(ma)
        validation[sig.name] = {"mse_before": mb["mse"], "ame_before": mb["ame"], "mse_after": ma["mse"],
                                "ame_after": ma["ame"], "mse_change_pct": 100 * (ma["mse"] / mb["mse"] - 1)}
    return validation, base_metrics, final_metrics
