"""The candidates' step: every catalogue candidate screened, those the screen passes (or nonsmooth and
signalled) refitted, the others ranked at their screened point (``candidates``). SI units; forces in N."""
from __future__ import annotations

from damper_fmu.effect_catalogue import ALL_EFFECTS

from tuner.diagnosis.cost_model import refit_cost
from tuner.diagnosis.extended_parametrization import ExtendedParametrization
from tuner.diagnosis.rules import scores
from tuner.diagnosis.search.nonsmooth import series_ladder, shows_gain, signalled_nonsmooth, unearned_nonsmooth
from tuner.diagnosis.search.refits import refit_candidate, screen
from tuner.diagnosis.search.rows import held_out, log_row
from tuner.diagnosis.search.state import Fit, SearchState
from tuner.progress import advance
from tuner.time_budget import section

__all__ = ["candidates"]


def candidates(s: SearchState) -> None:
    """Every catalogue candidate screened; those predicted to win SCREEN_SHARE of the identification SSE
    (or ``signalled_nonsmooth``) are refitted, the others ranked at their screened point (refitted after all if
    that scores)."""
    exts = {e: ExtendedParametrization(s.par, e, s.peak, s.stroke_range) for e in s.settings.candidates}
    section(s.log, f"{s.kind} base: screen of the candidates")
    screened = screen(s, exts)
    signalled = signalled_nonsmooth(s)
    passed = [e for e in s.settings.candidates
              if screened.get(e) is None or screened[e].passes or e in signalled or e in s.found_elsewhere]
    s.cost.done("screen")
    s.cost.refits = sum(refit_cost(s.par.dimension, 1, s.settings, ALL_EFFECTS[e].nonsmooth) for e in passed)
    s.forecast()
    at_none = {**s.base, **s.par.to_params(s.z_none)}
    for k, effect in enumerate(s.settings.candidates):
        advance(s.log, 0.2 + 0.5 * k / len(s.settings.candidates))
        ext, scr = exts[effect], screened.get(effect)
        row = None
        if scr is not None and not scr.passes and effect not in signalled and effect not in s.found_elsewhere:
            point = {**at_none, **scr.values}
            row = held_out(s, effect, point, ext.extra, s.eid.n_samples / scr.sse_n2, 1, s.mse_none)
            row["identification_rmse_effect_off_n"] = s.none_row["identification_rmse_n"]
            s.refits[effect] = Fit(ext, ext.from_params(point), 1)
        refitted = row is None or scores(row)
        if refitted:
            section(s.log, f"{s.kind} base: refit of {effect}")
            row = refit_candidate(s, effect, ext)
            if effect in signalled or (unearned_nonsmooth(effect, row) and shows_gain(s, row)):
                section(s.log, f"{s.kind} base: {effect} profiled with the series element held")
                row = series_ladder(s, effect, ext, row)
            s.cost.refits = max(0.0, s.cost.refits - refit_cost(s.par.dimension, 1, s.settings,
                                                                ALL_EFFECTS[effect].nonsmooth))
            s.forecast()
        row["refitted"], row["screen"] = refitted, scr.to_dict() if scr is not None else None
        s.ranking.append(row)
        log_row(s, row)
