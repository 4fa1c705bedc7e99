"""The base form of a diagnosis: which forms it may run on, their identification, the choice by held-out
MSE, whether a repeat on another form can plausibly win, and the progress plan over them.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

from damper_fmu.parameters import EFFECT_MODELS, defaults

from tuner.diagnosis.cost_model import EXTENDED_COST, expected_cost, identification_cost
from tuner.diagnosis.grid_check import GRID_PART
from tuner.identification.engine import Engine
from tuner.identification.floor import ResidualFloor
from tuner.identification.fit import (RACE_RATIO, FitResult, FitSettings, IdentifyOptions, fit_order, identify,
                                      initial_guess, refinement_starts, validation_run)
from tuner.identification.restart_check import TYPICAL_RESTARTS
from tuner.identification.parametrization import Parametrization
from tuner.identification.problem import Problem
from tuner.diagnosis.settings import DiagnosisSettings
from tuner.metrics import pooled_mse
from tuner.progress import Plan

__all__ = ["BASE_MODELS", "Base", "BaseRefinement", "CoarserGrid", "FittedBases", "pooled_validation_mse",
           "choose_base", "base_kinds", "PLAN_WEIGHTS", "progress_plan", "identified_bases", "why_not_repeated",
           "seconds_per_simulation", "forecast_identified", "DiagnosisForecast", "diagnosis_forecast"]

#: base forms the diagnosis chooses from (the models that carry the effect catalogue): the lumped
#: model of the paper, and the two-chamber form of a twin-tube damper
BASE_MODELS = EFFECT_MODELS


@dataclass(frozen=True)
class BaseRefinement:
    """What the identification of a base form's values on the diagnosis's own tests and engine says:
    ``settled``, how its local refinement ended when it converged there (the polish's stop text, in the
    'improved' scheme), else None; ``seconds_per_evaluation`` [s], its wall time per simulation with the
    run's workers in its local refinement (simulations near the fit run their whole length, as the diagnosis's
    do; the search's are often cut short), for the progress display's forecast (``tuner.diagnosis.cost_model``)."""

    settled: str | None = None
    seconds_per_evaluation: float | None = None

    @classmethod
    def from_history(cls, history: dict, scheme: str = "improved") -> "BaseRefinement":
        """From an identification's history (``tuner.identification.fit.identify``) in ``scheme``."""
        n, t = history.get("polish_evaluations") or 0, history.get("polish_elapsed_s") or 0.0
        settled = history.get("polish_stop") if history.get("converged") and scheme == "improved" else None
        if settled and history.get("converged_by") == "restart check":
            settled = (f"{settled}; every restart of its restart check ended within one standard error of it "
                       f"({history['restart_check']['standard_error_n']:.2g} N)")
        elif settled and history.get("converged_by") == "residual floor":
            settled = f"{settled}; it ends at the residual floor ({history['floor_stop']['residual_floor_n']:.3g} N)"
        return cls(settled, t / n if n and t > 0 else None)


@dataclass(frozen=True)
class CoarserGrid:
    """What the diagnosis on a coarser grid hands the same diagnosis run again on a finer one
    (``diagnose._on_a_fine_enough_grid``): ``found``, the values [SI] of its final model, a start for the model of
    the causes found (``search.selection.restarted``); ``idle_ladders``, the nonsmooth effects whose series ladder
    (``search.nonsmooth.series_ladder``) it ran without a better fit: not run again; ``kept_ladders``, {effect: the
    series stiffness [N/m] held whose release its ladder kept}: the finer grid's ladder holds that value alone. The ladder looks for a gap a
    stiff mount hides (another basin of the fit), which a finer grid does not create; on the class damper of
    ``tests/test_diagnose.py``'s worn-damper case it took 38 of the 83 s of the rerun to end no better again."""

    found: dict
    idle_ladders: tuple[str, ...] = ()
    kept_ladders: dict = field(default_factory=dict)

    @classmethod
    def of(cls, run: dict) -> "CoarserGrid":
        """From the run record of the diagnosis on the coarser grid (its ``after_params`` and ``ranking``)."""
        ranking = run.get("ranking") or []
        return cls(dict(run["after_params"]), tuple(r["effect"] for r in ranking
                                                    if r.get("series_element_released") is False),
                   {r["effect"]: r["series_element_kept_from"] for r in ranking if r.get("series_element_kept_from")})


@dataclass(frozen=True)
class Base:
    """A base form to diagnose on: its parametrization (the 'improved' scheme), its values [SI], and what its
    identification on these tests says (``BaseRefinement``). A settled base is not refitted again as 'none'
    (the same refinement from the same point ends where it is). ``coarser``: what a diagnosis on a coarser grid
    found (``CoarserGrid``; None: there was none). ``found_elsewhere``: the causes the diagnosis on another base form
    named, {effect: its parameters [SI]}: each is refitted on this base from those values too (a free play the
    two-chamber base names is tried on the lumped base from its gap, ``search.refits.refit_candidate``), so that the
    bases are compared with the fault on both."""

    par: Parametrization
    values: dict
    refinement: BaseRefinement = BaseRefinement()
    coarser: CoarserGrid | None = None
    found_elsewhere: dict = field(default_factory=dict)

    @property
    def settled(self) -> str | None:
        return self.refinement.settled


@dataclass(frozen=True)
class FittedBases:
    """The base forms an earlier fit hands the diagnosis, as one record: ``kind``, the base form to diagnose on
    first, and its ``values`` [SI]; ``choice``, how it was chosen (reported in ``diagnosis.json``); ``others``,
    {kind: values} of the other fitted base forms (a repeat's bases, ``tuner.diagnosis.diagnose``); ``problem``,
    the tests the fit prepared (``tuner.identification.problem.Problem``; None: the diagnosis prepares them);
    ``refinements``, {kind: ``BaseRefinement``} of the values' identification on that problem (a settled base is
    not refitted as 'none'; its cost per simulation forecasts the time left). ``from_fit`` builds it from a
    ``FitResult``, ``from_records`` from a fit folder's ``parameters.json`` and ``metrics.json``."""

    kind: str
    values: dict
    choice: dict | None = None
    others: dict = field(default_factory=dict)
    problem: Problem | None = None
    refinements: dict = field(default_factory=dict)

    @classmethod
    def from_records(cls, parameters: dict, metrics: dict) -> "FittedBases":
        """From a fit's ``parameters.json`` and ``metrics.json`` records: the base form with the lowest held-out
        MSE first (``choose_base``), the other fitted ones beside; no problem, no refinements (ValueError when no
        base form was fitted)."""
        kind, values, choice, others = choose_base(parameters, metrics)
        return cls(kind, values, choice, others)

    @classmethod
    def from_fit(cls, result: FitResult) -> "FittedBases":
        """From a ``FitResult``: ``from_records`` of its parameters and metrics, with the problem it was fitted on
        and each model's refinement (``BaseRefinement.from_history`` in the scheme the fit refined in)."""
        scheme = result.problem.settings.parametrization
        return replace(cls.from_records(result.params, result.metrics), problem=result.problem,
                       refinements={m: BaseRefinement.from_history(h, scheme) for m, h in result.histories.items()})


def pooled_validation_mse(kind: str, params: dict, signals: list, engine: str) -> float:
    """Validation MSE [N^2] pooled over the tests (``validation_run``, the Table 3 definition)."""
    return pooled_mse([validation_run(kind, params, s, engine)[1] for s in signals])


def choose_base(parameters: dict, metrics: dict) -> tuple[str, dict, dict, dict]:
    """The base form for a diagnosis after a fit: among the fitted models that carry the effect
    catalogue (BASE_MODELS), the one with the lowest held-out MSE pooled over the validation tests
    (``metrics.json`` of ``tuner.identification.fit.fit``). Returns (kind, its parameter values,
    the comparison, {kind: values} of the other fitted base forms: the diagnosis's fallbacks).
    ValueError when no such model was fitted."""
    kinds = [k for k in BASE_MODELS if k in parameters]
    if not kinds:
        raise ValueError(f"the diagnosis needs one of {', '.join(BASE_MODELS)} among the fitted models")
    mse = {k: pooled_mse([t["models"][k] for t in metrics["tests"].values() if t["role"] == "validation"])
           for k in kinds}
    kind = min(kinds, key=lambda k: mse[k])
    others = {k: parameters[k]["values"] for k in sorted(kinds, key=lambda k: mse[k]) if k != kind}
    return kind, parameters[kind]["values"], {"chosen": kind, "by": "held-out MSE of the fitted models "
                                              "(Table 3 definition)", "validation_mse": mse}, others


def base_kinds(settings: DiagnosisSettings, fitted: FittedBases | None) -> list[str]:
    """The base forms the diagnosis may run on: the ones an earlier fit gives (``fitted``: its first and the
    other fitted ones), or those it identifies (``settings.base_model``: 'auto' for every one of BASE_MODELS);
    ValueError for a form without effects."""
    if fitted is not None:
        return [fitted.kind, *(k for k in fitted.others if k != fitted.kind and k in EFFECT_MODELS)]
    kinds = list(BASE_MODELS) if settings.base_model == "auto" else [settings.base_model]
    unknown = [k for k in kinds if k not in EFFECT_MODELS]
    if unknown:
        raise ValueError(f"base model {unknown[0]!r}: choose 'auto' or one of {', '.join(EFFECT_MODELS)}")
    return kinds


#: expected relative costs of the diagnosis's parts (the progress display's plan)
PLAN_WEIGHTS = {"identification": 1.0, "diagnosis": 1.5}


def progress_plan(log, settings: DiagnosisSettings, fitted: FittedBases | None) -> Plan:
    """The progress plan: the identification of each base form (unless ``fitted`` gives them), the diagnosis on
    each one (the first, and a repeat on each other that may follow: skipped when it does not), and the diagnosis
    again on a finer grid (``tuner.diagnosis.grid_check``: skipped when the final model does not need it)."""
    kinds = base_kinds(settings, fitted)
    weights = {} if fitted is not None else {f"identification of the {k} base": PLAN_WEIGHTS["identification"] for k in kinds}
    weights.update({f"diagnosis on the {k} base": PLAN_WEIGHTS["diagnosis"] for k in kinds})
    weights[GRID_PART] = PLAN_WEIGHTS["diagnosis"]
    return Plan(log, weights)


def identified_bases(problem: Problem, checkpoints: Path, settings: DiagnosisSettings, fitted: FittedBases | None,
                     log) -> tuple[str, dict, dict | None]:
    """(the first base kind, {kind: Base} in the order tried, how it was chosen): the bases an earlier fit gives
    (``fitted``: its first and its other base forms, with their refinements on this problem), or identified here (Firefly state checkpointed in the folder
    ``checkpoints``: ``diagnosis_base_<kind>.json``) as the fit identifies them: in ``fit_order``, each raced
    against the best before it (``RACE_RATIO``), none after one that reaches the residual floor (``_at_floor``)."""
    def parametrization(kind: str, given: dict | None) -> Parametrization:
        # the local solver needs monotone tables: the 'improved' scheme whatever the fit used
        return problem.parametrization(kind, fixed_from=given, scheme="improved")

    if fitted is not None:
        kind, facts = fitted.kind, fitted.refinements
        bases = {kind: Base(parametrization(kind, fitted.values), fitted.values, facts.get(kind, BaseRefinement()))}
        bases.update({k: Base(parametrization(k, v), v, facts.get(k, BaseRefinement()))
                      for k, v in fitted.others.items() if k != kind and k in EFFECT_MODELS})
        return kind, bases, fitted.choice
    fitted, floor, at_floor, rmse = {}, problem.residual_floor(settings.engine), None, {}
    kinds = fit_order(base_kinds(settings, None), problem, settings.engine)
    forecast_identified(log, problem, settings, {k: parametrization(k, None) for k in kinds})
    for kind in kinds:
        if at_floor is not None:
            log.skip(f"identification of the {kind} base")
            continue
        par_k = parametrization(kind, None)
        log(f"diagnosis: identifying the base {kind} model ...")
        fs = FitSettings(models=(kind,), data=settings.data, iterations=settings.base_iterations,
                         workers=settings.workers, seed=settings.seed, engine=settings.engine,
                         polish_jacobians=settings.base_polish_jacobians)
        found = identify(kind, problem.sig_id, fs, par_k, checkpoints / f"diagnosis_base_{kind}.json",
                         problem.digest, log.part(f"identification of the {kind} base"),
                         options=IdentifyOptions(floor=floor, rival=min(rmse.items(), key=lambda r: r[1]) if rmse
                                                 else None))
        g = found.history["best_fitness_final"]
        rmse[kind] = 1.0 / math.sqrt(g) if g > 0 else math.inf
        fitted[kind] = (Base(par_k, found.values, BaseRefinement.from_history(found.history)),
                        pooled_validation_mse(kind, found.values, problem.sig_val, settings.engine))
        if kind != kinds[-1]:
            at_floor = _at_floor(kind, found, floor, [k for k in kinds if k not in fitted], log)
    kind = min(fitted, key=lambda k: fitted[k][1])
    bases = {k: fitted[k][0] for k in sorted(fitted, key=lambda k: fitted[k][1])}
    base_choice = {"chosen": kind, "by": "held-out MSE of the identified base models (Table 3 definition)",
                   "validation_mse": {k: v[1] for k, v in fitted.items()}}
    if at_floor is not None:
        base_choice.update(by="the first base form identified reaches the residual floor", at_floor=at_floor)
    if len(fitted) > 1:
        log("diagnosis: base form " + kind + " (held-out MSE " + ", ".join(
            f"{k} {math.sqrt(v[1]):.1f} N rms" for k, v in fitted.items()) + ")")
    return kind, bases, base_choice


def _at_floor(kind: str, found, floor: ResidualFloor, others: list, log) -> dict | None:
    """When the base ``kind`` identified (``found``, an ``Identified``) reaches the residual ``floor``
    (``ResidualFloor.reached``), the record of why the base forms ``others`` are not identified (the ``log``
    says it), else None: no form can fit these tests more than the noise better."""
    g = found.history["best_fitness_final"]
    rmse = 1.0 / math.sqrt(g) if g > 0 else math.inf
    level = floor.reached(kind, found.values, rmse)
    if level is None:
        return None
    log(f"diagnosis: the {kind} base reaches the residual floor ({rmse:.2f} N against {level:.2f} N): no other form "
        f"can fit these tests more than the noise better; not identified: {', '.join(others)}")
    return {"rmse_n": rmse, "residual_floor_n": level, "not_identified": others}


def seconds_per_simulation(kind: str, par: Parametrization, problem: Problem, settings: DiagnosisSettings) -> float:
    """Wall time [s] a simulation of the identification tests takes with the run's workers, before any was run:
    one simulation of the data-driven initial guess in this process, shared among the workers."""
    guess = {**defaults(kind), **initial_guess(kind, problem.sig_id, par)}
    with Engine(kind, problem.sig_id, engine=settings.engine, workers=0) as eng:
        t0 = time.perf_counter()
        eng.sse_batch([guess])
        return (time.perf_counter() - t0) / max(1, settings.workers)


def forecast_identified(plan, problem: Problem, settings: DiagnosisSettings, pars: dict) -> None:
    """Every part of the progress ``plan`` of a diagnosis that identifies its bases (``pars``: {kind: its
    parametrization}) says its expected seconds before the first starts (``tuner.diagnosis.cost_model``: the
    identification's and the diagnosis's simulations, at the cost per simulation one run measures; the forms
    counted until they are known not to run), so the time left covers every base from the start. Which base
    the diagnosis runs on is chosen after the identifications: until then the cheapest diagnosis is counted and
    what each other would add is said beside (``Plan.maybe``)."""
    diagnosis = {}
    for kind, par in pars.items():
        rate = seconds_per_simulation(kind, par, problem, settings)
        ident = identification_cost(par.dimension, refinement_starts(kind) + TYPICAL_RESTARTS,
                                    settings.base_iterations, FitSettings().population)
        plan.part(f"identification of the {kind} base").expect(ident * rate)
        diagnosis[kind] = _diagnosis_seconds(par, problem, settings, rate).total
    cheapest = min(diagnosis, key=diagnosis.get)
    for kind, seconds in diagnosis.items():
        plan.maybe(f"diagnosis on the {kind} base", None if kind == cheapest else f"the diagnosis runs on the {kind} base")
        plan.part(f"diagnosis on the {kind} base").expect(seconds)


@dataclass(frozen=True)
class DiagnosisForecast:
    """What a diagnosis is expected to take [s]: ``seconds`` without the forms, and ``forms_s`` more if they run
    (only where the base leaves a residual above the floor: not on clean data); ``total`` both."""

    seconds: float
    forms_s: float

    @property
    def total(self) -> float:
        return self.seconds + self.forms_s


def _diagnosis_seconds(par: Parametrization, problem: Problem, settings: DiagnosisSettings,
                       rate: float) -> DiagnosisForecast:
    """Expected seconds of a diagnosis on a base of ``par`` at ``rate`` [s per simulation of its identification]
    (``tuner.diagnosis.cost_model``: its extended models EXTENDED_COST x slower), the forms apart."""
    share = sum(int(s.mask.sum()) for s in problem.sig_val) / sum(int(s.mask.sum()) for s in problem.sig_id)
    cost = expected_cost(par.dimension, settings, settled=True, forms_run=bool(settings.forms), held_out_share=share)
    per_simulation = rate * EXTENDED_COST
    return DiagnosisForecast((cost.total - cost.forms) * per_simulation, cost.forms * per_simulation)


def diagnosis_forecast(problem: Problem, settings: DiagnosisSettings, kinds) -> DiagnosisForecast:
    """The diagnosis after a fit of the base forms ``kinds``, before the fit: the costliest base's (the one it runs
    on is chosen on the fit's held-out errors), a repeat not counted; one simulation of each base form's initial
    guess prices them (``seconds_per_simulation``). The job's display counts ``seconds`` for the diagnosis stage
    while the fit runs, in place of a planned share, and says the forms beside: counted in, the bundled job's
    display said 107 s for a diagnosis of 26 s (the forms do not run on data the base fits to the floor)."""
    pars = {k: problem.parametrization(k, scheme="improved") for k in kinds}
    ahead = [_diagnosis_seconds(par, problem, settings, seconds_per_simulation(k, par, problem, settings))
             for k, par in pars.items()]
    return max(ahead, key=lambda f: f.seconds)


def why_not_repeated(kind: str, other: str, first_run: dict, other_values: dict, problem: Problem,
                      settings: DiagnosisSettings) -> str | None:
    """Why the diagnosis is not repeated on the ``other`` base after the ``kind`` one left a residual
    above the floor (None: it is repeated)."""
    if first_run["unexplained"].get("fit_converged") is False:
        return "the first base's refit did not converge: its residual is no evidence of a wrong form"
    # the other form can plausibly win only if its bare fit was not clearly worse (the fit's race rule)
    rmse_first = math.sqrt(first_run["base_validation_mse"])
    rmse_other = math.sqrt(pooled_validation_mse(other, other_values, problem.sig_val, settings.engine))
    if rmse_other > RACE_RATIO * rmse_first:
        return (f"its bare fit validates at {rmse_other:.3g} N rms, {rmse_other / rmse_first:.1f} x "
                f"the {kind} base's {rmse_first:.3g} N (more than {RACE_RATIO:g} x: it cannot plausibly win)")
    return None
