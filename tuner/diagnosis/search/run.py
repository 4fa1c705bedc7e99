"""The diagnosis on one base form, its steps in order (``run``; ``tuner.diagnosis.search`` lists the modules
that hold them), and its detection limits (``detection``). SI units; forces in N."""
from __future__ import annotations

import time
from dataclasses import dataclass

from damper_fmu.effect_catalogue import ALL_EFFECTS, search_bounds
from damper_fmu.fmu import ensure_fmu
from damper_fmu.parameters import parameter_group

from tuner.diagnosis.bases import Base
from tuner.diagnosis.cost_model import expected_cost
from tuner.diagnosis.detection import EffectMagnitude, NamingRule, detection_limits
from tuner.diagnosis.effect_sizes import plausible_range, typical_range
from tuner.diagnosis.residual_tests import TestResidual
from tuner.diagnosis.rules import ACCEPT_SCORE, PENALTY_PER_PARAMETER
from tuner.diagnosis.search.candidates import candidates
from tuner.diagnosis.search.conclusion import before_rescue, concluded, result
from tuner.diagnosis.search.reference import refit_none, residual_evidence, residual_floor
from tuner.diagnosis.search.state import SearchState
from tuner.diagnosis.settings import DiagnosisSettings
from tuner.diagnosis.verdict import UNITS, limit_text
from tuner.identification.engine import Engine
from tuner.identification.problem import Problem
from tuner.identification.search_window import search_windows
from tuner.progress import advance

__all__ = ["BaseRun", "diagnose_on", "run", "detection", "absorbing_groups"]


@dataclass
class BaseRun:
    """The diagnosis on one base form: ``run``, the result fields of ``diagnosis.json`` for this base plus
    ``after_params`` (the final model's values), ``final_validation_mse`` and ``base_validation_mse`` [N^2]
    (pooled, Table 3 definition) (``run``); ``figures``, the folder of its figures (relative to the output
    folder; ``run['figures']`` names the files); ``residuals``, the base model's residual on every test
    (``reference.base_residuals``), which they show; ``seconds``, the wall time it took [s]."""

    run: dict
    figures: str
    residuals: list[TestResidual]
    seconds: float = 0.0


def diagnose_on(kind: str, base: Base, data: Problem, settings: DiagnosisSettings, figures: str, log,
                record: dict | None = None) -> BaseRun:
    """The diagnosis on one base form (``run``), its figures named in the folder ``figures``; ``record`` (as
    ``tuner.diagnosis.diagnose``) follows its stages (``SearchState``)."""
    s = SearchState.start(kind, base, data, settings, figures, log, record)
    return BaseRun(run(s), figures, s.residuals)


def run(s: SearchState) -> dict:
    """The steps in order: the residual floor and evidence, the base refitted alike, the candidates, the
    conclusion (ranking, forms, forward selection), the detection limits; the result fields for this base."""
    s.at("residual analysis")
    residual_floor(s)
    residual_evidence(s)
    kw = dict(engine=s.settings.engine, workers=s.settings.workers, max_internal_step=s.data.settings.internal_step_s,
              fmu_path=ensure_fmu(s.kind) if s.settings.engine == "fmu" else None)
    windows = search_windows(s.data.sig_id)
    with Engine(s.kind, s.data.sig_id, **kw) as s.eid, Engine(s.kind, s.data.sig_val, **kw) as s.ev, \
            windows.engine(s.eid, s.kind, **kw) as s.ew:
        s.eid.after_batch = s.ev.after_batch = s.ew.after_batch = s.tick
        s.at("candidate refits")
        s.record["partial"]["ranking"] = s.ranking
        s.t_engines = time.perf_counter()
        refit_none(s)
        s.cost = expected_cost(s.par.dimension, s.settings, settled=True, held_out_share=sum(
            s.lengths) / s.eid.n_samples, forms_run=bool(s.settings.forms) and s.above_floor(
            s.none_row["identification_rmse_n"]))
        s.cost.done("reference")
        s.forecast()
        advance(s.log, 0.2)
        candidates(s)
        advance(s.log, 0.7)
        end, first = concluded(s)
        s.at("detection limits", 0.95)
        limits = detection(s, [e for e in s.settings.candidates if e not in end.causes])
        s.step_done("detection")
        s.log(f"diagnosis on the {s.kind} base: {s.eid.evaluations} simulations of the identification "
              f"tests and {s.ev.evaluations} of the held-out ones in {time.perf_counter() - s.t_engines:.0f} s")
    return {**result(s, end, limits), "before_rescue": before_rescue(first)}


def detection(s: SearchState, candidates: list[str]) -> dict:
    """``tuner.diagnosis.detection.detection_limits`` of ``candidates`` at the base refit with the diagnosis's
    rules (acceptance score, penalty, search bounds, physical range); logged, units added."""
    names = {e: ALL_EFFECTS[e].identified[0] for e in candidates}
    magnitudes = {e: EffectMagnitude(n, typical_range(n, s.size)[0], search_bounds(n, s.peak, s.stroke_range),
                                     *plausible_range(n, s.size)) for e, n in names.items()}
    limits = detection_limits(s.eid, s.ev, s.par, s.z_none, magnitudes,
                              NamingRule(s.mse_none, s.noise, ACCEPT_SCORE, PENALTY_PER_PARAMETER))
    for e, r in limits.items():
        r["unit"], r["covers"] = UNITS[r["parameter"]], ALL_EFFECTS[e].kind
        r["absorbed_by"] = absorbing_groups(s.par, r.pop("absorbed_by_coordinate"))
    if limits:
        s.log("diagnosis: detection limits on these tests (the smallest magnitude that would have been named): "
              + ", ".join(f"{e} {limit_text(r)}" for e, r in limits.items()))
    return limits


def absorbing_groups(par, parts: list[float]) -> dict[str, float]:
    """{element: its share of the absorbed force} (``tuner.diagnosis.detection.absorption``'s parts per coordinate
    of the parametrization ``par`` summed by ``damper_fmu.parameters.parameter_group``), the elements carrying at
    least 10 %, largest first; a share is at most 1 (the parts of elements working against the others, negative,
    are left out: the damping table at 101.5 % beside -1.5 % elsewhere reads 100 %)."""
    groups: dict[str, float] = {}
    for name, part in zip(par.names, parts):
        g = parameter_group(par.model, name)
        groups[g] = groups.get(g, 0.0) + float(part)
    return dict(sorted(((g, min(v, 1.0)) for g, v in groups.items() if v >= 0.1), key=lambda kv: -kv[1]))
