"""The ranking row of a refitted model (``held_out``): its held-out MSE and score, its effect's force and
whether its magnitude is meaningful and within its bounds; its intervals (``attach_interval``) and its line in
the log. A ranking row is a dict (``tuner.diagnosis.rules`` reads it). SI units; forces in N."""
from __future__ import annotations

import math

import numpy as np

from damper_fmu.effect_catalogue import effect_of, search_bounds

from tuner.diagnosis.effect_sizes import REFERENCE, DamperSize, meaningful_floor, plausible_range
from tuner.diagnosis.extended_parametrization import ExtendedParametrization
from tuner.diagnosis.rules import score, within_bounds
from tuner.diagnosis.search.state import SearchState
from tuner.diagnosis.verdict import UNITS

__all__ = ["split_mse", "held_out", "attach_interval", "log_row"]


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


def held_out(s: SearchState, effect: str, params: dict, extra, g: float, evals: int, mse_ref: float,
             new=None) -> dict:
    """Ranking entry of a refitted model: validation MSE/AME, score against the validation MSE ``mse_ref``
    [N^2] of the reference (the base refitted alike, or the model of the causes already selected), and
    the force contribution [N rms] of the ``new`` effect parameters (default all of ``extra``) on the
    identification tests (the fitted model minus the same with them off); ``g``: its identification
    fitness N / SSE. The score is penalised for as many parameters as ``new`` (a form's row is scored again
    for all of its own: ``form_steps.form_row``). When the held-out tests cannot be simulated at its point, its
    held-out MSE is infinite (no score: it cannot be named) and ``validation_failure`` says why."""
    new = list(extra) if new is None else list(new)
    r_val = s.ev.residuals_batch([params])[0]
    per_test = split_mse(r_val, s.lengths)
    mse = math.inf if r_val is None else float(r_val @ r_val) / sum(s.lengths)
    contribution = 0.0
    if new:
        r_on, r_off = s.eid.residuals_batch([params, {**params, **{n: 0.0 for n in new}}])
        if r_on is not None and r_off is not None:
            contribution = float(np.sqrt(np.mean((r_off - r_on) ** 2)))
    values = {n: params[n] for n in extra}
    return {"effect": effect, "score": score(mse, mse_ref, len(new)),
            "validation_mse": mse, "validation_mse_change_pct": 100 * (mse / mse_ref - 1),
            "identification_rmse_n": 1 / math.sqrt(g) if g > 0 else math.inf,
            "parameters": values, "units": {n: UNITS[n] for n in values},
            "effect_rms_n": contribution, "resolved": bool(contribution >= s.noise) if new else True,
            "meaningful": all(abs(params[n]) >= meaningful_floor(n, s.size) for n in new),
            "within_bounds": within_bounds({n: params[n] for n in new}, {
                n: search_bounds(n, s.peak, s.stroke_range, s.stroke_limits) for n in new}),
            "validation": {t.name: {"mse": m, "ame": a} for t, (m, a) in zip(s.data.sig_val, per_test)},
            "evaluations": int(evals),
            **({"validation_failure": s.ev.last_failure or "no reason given"} if r_val is None else {})}


def attach_interval(row: dict, ci: dict, ext: ExtendedParametrization, new) -> None:
    """The row's 95 % intervals of ``ext.extra`` from ``effect_intervals``' ``ci``; significant when the
    interval of every ``new`` magnitude excludes zero; plausible when none of them lies wholly above the
    top of its effect's plausible range on this damper (``effect_sizes.plausible_range``: twice the top of the
    typical range): a magnitude no damper of this size has patches another error (a form gap), it is not that
    effect."""
    size = DamperSize(ext.peak_force, ext.stroke_range_m or REFERENCE.stroke_range_m)
    row["interval"] = {n: [ci[n]["low"], ci[n]["high"]] for n in ext.extra}
    row["significant"] = all(ci[n]["excludes_zero"] for n in new)
    row["interval_blocks"] = ci["_blocks"]
    if "_not_computed" in ci:
        row["interval_not_computed"] = ci["_not_computed"]
    nearest = {n: 0.0 if ci[n]["low"] <= 0.0 <= ci[n]["high"] else min(abs(ci[n]["low"]), abs(ci[n]["high"]))
               for n in new if n in effect_of(n).typical}
    row["plausible"] = all(v <= plausible_range(n, size)[1] for n, v in nearest.items())


def log_row(s: SearchState, row: dict) -> None:
    """One candidate's ranking row, as the log shows it."""
    s.log(f"  {row['effect']:14s} " + ", ".join(f"{n} = {v:.4g} {UNITS[n]}" for n, v in row["parameters"].items())
          + (f"  the held-out tests cannot be simulated at this point ({row['validation_failure']}): not a cause"
             if "validation_failure" in row else
             f"  validation MSE {row['validation_mse_change_pct']:+6.1f} %  score {row['score']:+.3f}")
          + f"  effect {row['effect_rms_n']:.3g} N rms{'' if row['resolved'] else ' (below the noise)'}"
          + ("" if row["refitted"] else "  (screened: not refitted)"))
