"""Diagnosis: what the fitted base model gets wrong, which physical effect causes it, the model
extended by that effect, and the gain measured on held-out data.

Procedure (``diagnose``; the steps on one base form are the modules of ``tuner.diagnosis.search``
(``run``: the steps in order), the decision rules are in ``tuner.diagnosis.rules``, the words in
``tuner.diagnosis.verdict``, the base forms in ``tuner.diagnosis.bases``):
1. Base model: the base form with the lowest held-out MSE among BASE_MODELS (the paper's lumped
   model and the two-chamber form of a twin-tube damper: a base that cannot represent the damper
   leaves a form error larger than the effects), identified on the identification tests (taken
   from an earlier fit, ``choose_base``, or identified here: the seeded Firefly's first population and
   least-squares refinements from its best and from the data-driven guess, as ``tuner.identification.fit``
   with ``DiagnosisSettings.base_iterations``, default none). The choice is made before any effect is added; when the
   diagnosis on it (steps 2-5) leaves a residual above the floor, it is repeated on the other base
   form and the final model with the lowest held-out MSE is kept (a large effect can make both bare
   bases fit badly, and then the wrong form may validate better) - but only when the other form can
   plausibly win (its bare fit validates within ``RACE_RATIO`` x the first's RMSE) and the first
   base's refit converged (an unfinished fit is no evidence of a wrong form).
2. Residuals (measured - simulated force) of the base model on every test: evidence numbers
   (``tuner.diagnosis.residuals``), and the series of the figures the job draws from them
   (``tuner.results.diagnosis_figures``): in time, against velocity and stroke, around velocity
   reversals, against frequency, drift over the test and against the temperature channel.
3. For every candidate of the catalogue (``damper_fmu.effects``): a screen (``tuner.diagnosis.screen``)
   predicts from one batch what its refit could win; those predicted to win 2 % of the identification
   SSE are extended by that effect, refitted on the identification tests, and their validation MSE
   measured (the others are ranked at their screened point). The refit (``refit``) runs
   a profile line search on the effect parameter (each grid value with the base re-balanced by
   Levenberg-Marquardt steps on the base Jacobian, since the base fit may have absorbed part of
   the effect into its tables) and a joint least-squares polish, from two
   starts: the fitted base, and the data-driven initial guess, which has absorbed nothing (plain
   grid there); the better identification fit wins. 'none' is the base refitted alike; a base whose
   refinement converged on these tests (``tuner.diagnosis.bases.BaseRefinement``) is its own refit. The leading candidate's refit is continued
   (``final_jacobians``) before the decision.
   Score = -ln(MSE_ext / MSE_none) - 0.02 x (extra parameters), pooled over the validation
   tests, against 'none' (the base refitted alike). A cause is named (``decide``) when it scores
   above 0.05 (~7 % held-out MSE reduction for one parameter), its force is above the measured
   noise, its magnitude is physically meaningful (>= half the low end of its typical range, scaled to
   the damper: ``tuner.diagnosis.effect_sizes``), a fitted delay agrees with the residual's, and the 95 % interval of its magnitude excludes zero
   (``effect_intervals``: block sandwich, ``tuner.diagnosis.significance``).
4. Forms weighed with the causes (``search.form_steps.weigh_forms``): when a catalogue cause is named
   and the base leaves a residual above the floor, the forms beyond the catalogue are fitted on the
   base; one that scores above the cause is the first cause. A magnitude at its search bound, or
   whose interval lies wholly above its typical range on this damper, is never named
   (``tuner.diagnosis.rules``). Forward selection (``next_cause``): further causes are added one at a
   time on the same rules against the model of the causes found so far; then the forms on top of
   them when a residual above the floor remains (``forms_on_top``).
5. Unexplained: a final identification RMSE above ``UNEXPLAINED_RATIO`` x the residual floor (the
   force noise and the force the stroke noise makes through the model, ``stroke_noise_force``) is reported as
   a model-form error the catalogue does not explain (cause 'unexplained' when nothing was named).
   With nothing named, the base refit is first continued until its first-order test holds
   (``final_jacobians`` cap); if it still has not converged, the verdict says so and claims no
   form error. The force noise comes from ``tuner.data.noise`` (the cycle-to-cycle scatter of
   periodic tests, else the quiet band of the force's spectrum); when that estimate is not credible
   (filtered data, too few samples) the residual is not compared with the floor at all: no
   'unexplained', no "N x the floor", and the verdict says why (``residual_floor_credible``).
5a. Grid: the final model's force on the grid the identification simulated on against a 4 x finer one
   (``tuner.diagnosis.grid_check``); when it moves by more than half the force noise (a free play in stiff
   contact), the diagnosis on that base runs again on the finer grid (``_on_a_fine_enough_grid``).
6. Output: a ``Diagnosis`` (``tuner.diagnosis.result``), as the fit returns a ``FitResult``: the record
   of ``diagnosis.json`` (cause, causes, selection steps, unexplained, ranking, noise (the estimate used
   and every one made), effect parameters with units, intervals and typical ranges, validation MSE/AME
   before and after per test in the Table 3 definition, evidence, the figures' file names), the final
   model's values and the base model's residual series. ``diagnose`` writes nothing but its checkpoints;
   the job (``tuner.job.write_diagnosis``) writes ``diagnosis.json``, the figures
   (``tuner.results.diagnosis_figures``) and the extended model as a tuned FMU
   (``fmu/<model identifier>_<causes>_tuned.fmu``, e.g. ``DamperLumped_friction_tuned.fmu``). A stage
   that fails raises ``DiagnosisFailed`` with the record of the failure, which the job writes as
   ``diagnosis.json`` (``tuner.job.write_diagnosis_failure``).

Search bounds (``search_bounds``: each effect's rule in its record, ``damper_fmu.effect_catalogue``, the
one source) cover twice the catalogue's typical range, force scales at least 10 % of the measured peak
force and a free play at most the stroke range, so the procedure is not tied to one damper.
"""
from __future__ import annotations

import hashlib
import json
import math
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from damper_fmu.effect_catalogue import ALL_EFFECTS, search_bounds  # noqa: F401

from tuner import strict_json
from tuner.data.reading import RigTest
from tuner.diagnosis.bases import (BASE_MODELS, Base, CoarserGrid, FittedBases, choose_base,  # noqa: F401
                                   identified_bases, progress_plan, why_not_repeated)
from tuner.diagnosis.cost_model import EXTENDED_COST, expected_cost
from tuner.diagnosis.extended_parametrization import ExtendedParametrization  # noqa: F401
from tuner.diagnosis.grid_check import GRID_PART, GRID_REFINEMENT, GridCheck, grid_check
from tuner.diagnosis.refit import MIN_BLOCKS  # noqa: F401
from tuner.diagnosis.result import Diagnosis, DiagnosisFailed, failure_record
from tuner.diagnosis.rules import (ACCEPT_SCORE, PENALTY_PER_PARAMETER, UNEXPLAINED_RATIO, cross_check,  # noqa: F401
                                   decide)
from tuner.diagnosis.search.reference import base_residuals
from tuner.diagnosis.search.run import BaseRun, diagnose_on
from tuner.diagnosis.settings import CANDIDATES, DiagnosisSettings
from tuner.diagnosis.verdict import ACQUISITION_CAUSES, NOTES  # noqa: F401
from tuner.identification.fit import FitResult
from tuner.identification.problem import Problem
from tuner.progress import advance

__all__ = ["Diagnosis", "DiagnosisSettings", "DiagnosisFailed", "diagnose", "decide", "cross_check", "choose_base",
           "FittedBases", "CANDIDATES",
           "BASE_MODELS", "ExtendedParametrization", "search_bounds", "ACQUISITION_CAUSES", "NOTES", "ACCEPT_SCORE"]


def diagnose(identification: list[RigTest], validation: list[RigTest], settings: DiagnosisSettings | None = None, *,
             from_fit: FittedBases | FitResult | None = None, checkpoints: Path | None = None, log=print) -> Diagnosis:
    """Run the diagnosis and return the :class:`tuner.diagnosis.result.Diagnosis` (read-only: the record
    ``diagnosis.json`` holds, the final model's values, the residual series of the figures). Writes nothing
    but its checkpoints, into the folder ``checkpoints`` (resumed when they are there; none kept when it is
    None); ``tuner.job.write_diagnosis`` writes ``diagnosis.json``, the figures and the extended FMU.

    from_fit: an earlier fit, whole: a ``FitResult`` or the ``tuner.diagnosis.bases.FittedBases`` record of one
    (``FittedBases.from_fit``, ``FittedBases.from_records`` of a fit folder's files): the base form it chose by
    held-out MSE (``choose_base``) and its values, how it was chosen (reported), the other fitted base forms, the
    tests it prepared (``tuner.identification.problem``: the same fit rate, abscissae and force limit; built
    from ``settings.data`` when it has none) and how each base's refinement ended on them (a settled base is not
    refitted again as 'none'; its cost per simulation forecasts the time left). Without it the base is
    identified here (``settings.base_model``: 'auto' identifies every one of BASE_MODELS and keeps the one with
    the lowest held-out MSE).

    The base is chosen before any effect is added; when the diagnosis on it leaves a residual above
    the floor (a large effect can make both bare bases fit badly, and then the wrong form may win),
    it is repeated on the other base forms that can plausibly win (bare held-out RMSE within
    ``RACE_RATIO`` x the first's; not at all when the first base's refit did not converge) and the
    final model with the lowest held-out MSE is kept; ``base_choice['not_repeated_on']`` says why not.

    Stages: the base identification (its Firefly state checkpointed every iteration,
    ``diagnosis_base_<kind>.json``), the diagnosis on each base form (checkpointed when finished:
    ``diagnosis_<kind>.json``); the job's export of the extended FMU follows (``Diagnosis.failed``). A stage
    that raises raises ``DiagnosisFailed`` with the record of what was finished (``failed_stage``, the
    error, the ranking so far); called again with the same checkpoints, finished stages are taken from
    them (checkpoints of other data or settings are refused: ValueError)."""
    settings = settings or DiagnosisSettings()
    if not isinstance(settings, DiagnosisSettings):
        raise TypeError(f"diagnose: settings must be a DiagnosisSettings, got {type(settings).__name__}; the "
                        f"diagnosis writes no output folder (it returns a Diagnosis: tuner.job.write_diagnosis "
                        f"writes its files), its checkpoints folder is the keyword 'checkpoints'")
    if not identification or not validation:
        raise ValueError("the diagnosis needs identification AND validation tests (the decision is held-out gain)")
    fitted = FittedBases.from_fit(from_fit) if isinstance(from_fit, FitResult) else from_fit
    scratch = tempfile.TemporaryDirectory(prefix="tuner-diagnosis-") if checkpoints is None else None
    checkpoints = Path(scratch.name if scratch is not None else checkpoints)
    checkpoints.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    problem = _checked_problem(fitted.problem if fitted is not None else None, identification, validation, settings)
    # force noise in the fit band (``tuner.data.noise``: the cycle-to-cycle scatter of periodic tests,
    # else the quiet band of the force's spectrum; the base model's residual is no better a source: its
    # model-form error is broadband at the velocity reversals, measured 10x the noise on lumped-damper
    # data). An effect whose force is below it is not resolved; when the estimate is not credible the
    # residual is not compared with the floor (``diagnose_on``).
    log(f"diagnosis: force measurement noise: {problem.noise.get('text') or f'{problem.noise_n:.3g} N rms'}")
    record = {"stage": "base identification", "finished": [], "partial": None,
              "base_choice": fitted.choice if fitted is not None else None}
    try:
        result = _diagnose_stages(problem, checkpoints, settings, fitted, record, log, t_start)
    except Exception as err:  # recorded, then raised again: a failed stage is never a result
        log(f"diagnosis: FAILED in its stage '{record['stage']}': {type(err).__name__}: {err}")
        settings_block = _settings_record(settings, problem, time.perf_counter() - t_start)
        raise DiagnosisFailed(record["stage"], failure_record(record["stage"], err, record, settings_block),
                              err) from err
    finally:
        if scratch is not None:
            scratch.cleanup()
    log(result.verdict)
    return result


def _checked_problem(problem: Problem | None, identification, validation, settings) -> Problem:
    """The prepared tests: ``problem`` when it was built from these tests at the settings' rate, else
    built here (ValueError for one of other tests or rates)."""
    if problem is None:
        return Problem.build(identification, validation, settings.data)
    if [t.name for t in problem.identification] != [t.name for t in identification] or \
            [t.name for t in problem.validation] != [t.name for t in validation]:
        raise ValueError("diagnose: the problem given was built from other tests")
    asked = settings.data
    if (problem.settings.fit_rate_hz, problem.settings.warmup_s) != (asked.fit_rate_hz, asked.warmup_s):
        raise ValueError(f"diagnose: the problem was prepared at {problem.settings.fit_rate_hz:g} Hz with "
                         f"{problem.settings.warmup_s:g} s warm-up, the settings ask for {asked.fit_rate_hz:g} Hz "
                         f"and {asked.warmup_s:g} s")
    return problem


def _diagnose_stages(problem: Problem, checkpoints: Path, settings: DiagnosisSettings, fitted: FittedBases | None,
                     record: dict, log, t_start: float) -> Diagnosis:
    """The stages of ``diagnose`` after the inputs were checked (``fitted``: the earlier fit's bases, or None:
    identified here); ``record`` follows them (the stage
    running, the stages finished, what the running one has so far) for a failure report. The first base's
    figures go to ``figures/``, a repeat's to ``figures/base_<kind>/``."""
    plan = progress_plan(log, settings, fitted)
    kind, bases, base_choice = identified_bases(problem, checkpoints, settings, fitted, plan)
    record["base_choice"] = base_choice
    record["finished"].append("base identification")
    for k in bases:  # the first base's diagnosis runs; a repeat on another only if the first leaves a residual
        plan.maybe(f"diagnosis on the {k} base", None if k == kind else f"the diagnosis is repeated on the {k} base")
    plan.maybe(GRID_PART, "the final model needs a finer grid")
    forecast_parts(plan, bases, problem, settings, kind)
    runs = {kind: _checkpointed_run(kind, bases[kind], problem, settings, checkpoints, "figures", record,
                                    plan.part(f"diagnosis on the {kind} base"))}
    skipped = _repeats(kind, bases, runs, problem, settings, checkpoints, record, plan)
    _with_the_causes_of_the_others(kind, bases, runs, problem, settings, checkpoints, record, plan)
    if skipped:
        base_choice = {**(base_choice or {}), "not_repeated_on": skipped}
    if len(runs) > 1:
        final = {k: r.run["final_validation_mse"] for k, r in runs.items()}
        first, kind = kind, min(final, key=final.get)
        base_choice = {**(base_choice or {}), "chosen": kind, "first_choice": first,
                       "after_diagnosis": {k: {"causes": r.run["causes"], "validation_mse": final[k]}
                                           for k, r in runs.items()},
                       "by": "held-out MSE of the final models (the first choice left a residual above the floor)"}
        log("diagnosis: final base form " + kind + " (held-out MSE of the final models " + ", ".join(
            f"{k} {math.sqrt(v):.1f} N rms" for k, v in final.items()) + ")")
    # every base's refit on the fit's grid: a lower point than the fit's, on any base, is the job's to adopt
    base_refits = {k: r.run["base_refit"] for k, r in runs.items()}
    runs[kind], grid = _on_a_fine_enough_grid(kind, bases[kind], problem, settings, checkpoints, runs[kind], record,
                                              plan)
    run = runs[kind].run
    result = {k: v for k, v in run.items() if k not in ("after_params", "final_validation_mse", "base_validation_mse")}
    if grid.get("refined"):
        result["verdict"] = f"{result['verdict']}. {grid['text']}"
    result["base_choice"] = base_choice
    result["base_refits"] = base_refits
    result["grid"] = grid
    result["settings"] = _settings_record(settings, problem, time.perf_counter() - t_start)
    return Diagnosis(result, final_values=run["after_params"], stages=record,
                     residuals={r.figures: r.residuals for r in runs.values()})


def _repeats(kind: str, bases: dict, runs: dict, problem: Problem, settings: DiagnosisSettings, checkpoints: Path,
             record: dict, plan) -> dict:
    """The diagnosis repeated on the other base forms when the first (``kind``, ``runs[kind]``) leaves a residual
    above the floor and the other can plausibly win (``why_not_repeated``), each with the causes the first named
    (``named_effects``, ``Base.found_elsewhere``); their runs added to ``runs``, ``bases`` updated. Returns {base:
    why it was not repeated there}."""
    skipped = {}
    for other in [k for k in bases if k != kind]:
        left = runs[kind].run["unexplained"]
        why = "" if left is None else why_not_repeated(kind, other, runs[kind].run, bases[other].values, problem,
                                                      settings)
        if why is not None:
            plan.skip(f"diagnosis on the {other} base")
        if left is None:
            continue
        if why:
            skipped[other] = why
            plan(f"diagnosis: the {kind} base leaves {left['ratio']:.1f} x the residual floor; not repeated on the "
                 f"{other} base: {why}")
            continue
        plan(f"diagnosis: the {kind} base leaves {left['ratio']:.1f} x the residual floor: "
             f"repeated on the {other} base (the base is chosen again by the final models' held-out MSE)")
        plan.maybe(f"diagnosis on the {other} base", None)
        found = named_effects(runs[kind].run, settings)
        if found:
            plan(f"diagnosis: the causes the {kind} base named ({', '.join(found)}) are refitted on the {other} base "
                 f"from their values there too")
        bases[other] = replace(bases[other], found_elsewhere=found)
        runs[other] = _checkpointed_run(other, bases[other], problem, settings, checkpoints, f"figures/base_{other}",
                                        record, plan.part(f"diagnosis on the {other} base"))
    return skipped


def _with_the_causes_of_the_others(kind: str, bases: dict, runs: dict, problem: Problem,
                                   settings: DiagnosisSettings, checkpoints: Path, record: dict, plan) -> None:
    """The reverse of a repeat's ``found_elsewhere``: when the first base (``kind``) would be kept (the lowest
    held-out MSE of the final models) while a repeat named causes the first did not, the diagnosis on the first
    base runs again with those causes refitted from the repeat's values too (checkpointed in
    ``checkpoints/with_others_causes``), and replaces the first's run when its final model validates better: the
    fault is tried on the base the data prefer before the verdict."""
    if len(runs) < 2:
        return
    final = {k: r.run["final_validation_mse"] for k, r in runs.items()}
    if min(final, key=final.get) != kind:
        return
    named_first = set(runs[kind].run["causes"])
    found = {}
    for other in (k for k in runs if k != kind):
        found.update({e: v for e, v in named_effects(runs[other].run, settings).items() if e not in named_first})
    if not found:
        return
    plan(f"diagnosis: the {kind} base validates best but named no {', '.join(found)}, which another base named: "
         f"the diagnosis on the {kind} base runs again with them refitted from the values found there")
    folder = checkpoints / "with_others_causes"
    folder.mkdir(exist_ok=True)
    again = _checkpointed_run(kind, replace(bases[kind], found_elsewhere=found), problem, settings, folder, "figures",
                              record, plan.part(f"diagnosis on the {kind} base"))
    if again.run["final_validation_mse"] < final[kind]:
        bases[kind] = replace(bases[kind], found_elsewhere=found)
        runs[kind] = again
    plan(f"diagnosis: again on the {kind} base: causes {', '.join(again.run['causes']) or 'none'}, held-out "
         f"{math.sqrt(again.run['final_validation_mse']):.1f} N rms against {math.sqrt(final[kind]):.1f} N rms "
         + ("(kept)" if runs[kind] is again else "(the first run stands)"))


def named_effects(run: dict, settings: DiagnosisSettings) -> dict:
    """{effect: its parameters [SI]} of the catalogue causes a diagnosis on one base form named (its ``run``
    record's causes, at its final model's values): what a repeat on another base form refits from them too
    (``Base.found_elsewhere``)."""
    values = run.get("after_params") or {}
    return {c: {n: float(values[n]) for n in ALL_EFFECTS[c].identified if n in values}
            for c in run.get("causes") or [] if c in settings.candidates and c in ALL_EFFECTS}


def forecast_parts(plan, bases: dict, problem: Problem, settings: DiagnosisSettings, first: str) -> None:
    """Each base's diagnosis part of the progress ``plan`` gets its expected seconds (``tuner.diagnosis.
    cost_model``, at the cost per simulation its identification measured; the forms counted), so that the time
    left covers the first base's diagnosis and says what a repeat on another would add until it is known whether
    it runs (a repeat runs only when the first base leaves a residual above the floor: ``Plan.maybe``); the
    diagnosis on a finer grid, the ``first`` base's at ``GRID_REFINEMENT`` x its cost per simulation (said again
    at the cost the grid check measures, when it runs). Nothing when a base's cost per simulation is not known."""
    share = sum(int(s.mask.sum()) for s in problem.sig_val) / sum(int(s.mask.sum()) for s in problem.sig_id)
    seconds = {}
    for kind, base in bases.items():
        rate = base.refinement.seconds_per_evaluation
        if rate is None:
            return
        cost = expected_cost(base.par.dimension, settings, settled=base.settled is not None,
                             forms_run=bool(settings.forms), held_out_share=share)
        seconds[kind] = cost.total * rate * EXTENDED_COST
        plan.part(f"diagnosis on the {kind} base").expect(seconds[kind])
    plan.part(GRID_PART).expect(seconds[first] * GRID_REFINEMENT)


def _on_a_fine_enough_grid(kind: str, base: Base, problem: Problem, settings: DiagnosisSettings, checkpoints: Path,
                           first: BaseRun, record: dict, plan) -> tuple[BaseRun, dict]:
    """(the diagnosis on the ``kind`` base to report, the ``grid`` record of ``diagnosis.json``): ``first``, when its
    final model's force moves by at most ``GRID_ERROR_SHARE`` x the force noise on a grid ``GRID_REFINEMENT`` times
    finer (``tuner.diagnosis.grid_check``), else the diagnosis run again on that grid from the same base values
    (the base refitted there; checkpointed in ``checkpoints/grid_<step in us>us``; ``first``'s final model a start
    for the models of the causes it finds, and its idle series ladders not run again: ``CoarserGrid``), its final
    model checked again.
    Integration error above the noise is a systematic residual the search explains with false or biased causes
    beside a free play in stiff contact; one refinement at most (each costs ``GridCheck.cost_ratio`` x the time)."""
    record["stage"] = "grid check"
    check = grid_check(kind, first.run["after_params"], problem, settings.engine)
    plan(f"diagnosis: grid check: {check.text()}" + (": the diagnosis runs again on the finer grid"
                                                     if check.too_coarse else ""))
    out = {"check": check.to_dict(), "refined": check.too_coarse}
    if not check.too_coarse:
        plan.skip(GRID_PART)
        return first, out
    fine_settings = replace(settings, data=replace(settings.data, sim_step_s=check.finer_step_s))
    finer = problem.on_grid(check.finer_step_s)
    part = plan.part(GRID_PART)
    plan.maybe(GRID_PART, None)
    part.expect(check.cost_ratio * first.seconds)
    folder = checkpoints / f"grid_{1e6 * check.finer_step_s:.0f}us"
    folder.mkdir(exist_ok=True)
    fine = _checkpointed_run(kind, Base(base.par, base.values, coarser=CoarserGrid.of(first.run),
                                                   found_elsewhere=base.found_elsewhere), finer,
                             fine_settings, folder, first.figures, record, part)
    after = grid_check(kind, fine.run["after_params"], finer, settings.engine)
    plan(f"diagnosis: grid check on the finer grid: {after.text()}")
    out.update({"first_grid": {"causes": first.run["causes"], "validation_mse": first.run["final_validation_mse"]},
                "after": after.to_dict(),
                "text": _refined_text(check, after, first.run["causes"])})
    return fine, out


def _refined_text(check: GridCheck, after: GridCheck, first_causes: list[str]) -> str:
    """The verdict's sentence on a diagnosis run again on a finer grid."""
    ms = [f"{1e3 * t:g} ms" for t in (check.step_s, check.finer_step_s, after.finer_step_s)]
    return (f"The diagnosis ran again on a {ms[1]} grid: the model it found on the {ms[0]} grid "
            f"({' + '.join(first_causes) or 'no cause'}) moves by {check.change_n:.3g} N rms on the finer one "
            f"({check.change_n / check.noise_n:.2g} x the force noise)"
            + (f"; the final model still moves by {after.change_n:.3g} N rms on a {ms[2]} grid "
               f"({after.change_n / after.noise_n:.2g} x the noise): small causes beside a stiff contact may be the "
               f"grid's" if after.too_coarse else ""))


def _checkpointed_run(kind: str, base: Base, problem: Problem, settings: DiagnosisSettings, checkpoints: Path,
                      figures: str, record: dict, log) -> BaseRun:
    """The diagnosis on the ``kind`` base (``diagnose_on``; its figures named in the folder ``figures``), or its
    checkpoint from an earlier call on the same data, settings and base values (``diagnosis_<kind>.json`` in
    ``checkpoints``, written when it finishes with its wall time; one of other data or settings: ValueError) with the
    base model's residual series simulated again (the checkpoint holds numbers, not series)."""
    path = checkpoints / f"diagnosis_{kind}.json"
    # the flat record without what may change on resuming; the parametrization, always 'improved', is left out so
    # that checkpoints written before the settings held a DataSettings still match
    key = _digest([problem.digest, kind, {k: v for k, v in settings.to_dict().items()
                                          if k not in ("workers", "parametrization")}])
    base_key = _digest([base.values, base.found_elsewhere] if base.found_elsewhere else base.values)
    if path.exists():
        saved = strict_json.loads(path.read_text())
        if saved.get("key") != key:
            raise ValueError(f"{path} was written with other data or settings; start a new output folder")
        if saved.get("base_key") == base_key:
            log(f"diagnosis: the {kind} base's diagnosis was finished before: taken from {path}")
            record["finished"].append(f"diagnosis on the {kind} base")
            advance(log, 1.0)
            return BaseRun(saved["run"], figures, base_residuals(kind, base.values, problem, settings),
                           float(saved.get("seconds", 0.0)))
        log(f"diagnosis: {path} holds the diagnosis of other {kind} base values (a refit since): diagnosed again")
    record["stage"] = f"diagnosis on the {kind} base"
    record["partial"] = {"base_model": kind}
    t0 = time.perf_counter()
    done = diagnose_on(kind, base, problem, settings, figures, log, record)
    seconds = time.perf_counter() - t0
    tmp = path.with_suffix(".tmp")
    tmp.write_text(strict_json.dumps({"key": key, "base_key": base_key, "run": done.run, "seconds": seconds}))
    tmp.replace(path)
    record["finished"].append(f"diagnosis on the {kind} base")
    record["partial"] = None
    advance(log, 1.0)
    # the same values as a resumed run gets
    return BaseRun(strict_json.loads(path.read_text())["run"], figures, done.residuals, seconds)


def _digest(value) -> str:
    """A SHA-256 of ``value``'s JSON (keys sorted): what a checkpoint was made from."""
    return hashlib.sha256(json.dumps(value, sort_keys=True, default=_json_default).encode()).hexdigest()


def _settings_record(settings: DiagnosisSettings, problem: Problem, elapsed_s: float) -> dict:
    """The settings block of ``diagnosis.json``: the run's settings, the decision rules, the problem."""
    return {**settings.to_dict(),
            "penalty_per_parameter": PENALTY_PER_PARAMETER, "accept_score": ACCEPT_SCORE,
            "unexplained_ratio": UNEXPLAINED_RATIO, "min_blocks": MIN_BLOCKS,
            "problem": {"data_settings": problem.settings.to_dict(), "force_limit_n_used": problem.force_limit_n,
                        "table_abscissae": problem.axes},
            "elapsed_s": elapsed_s}


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, tuple):
        return list(o)
    return str(o)
