"""The tuner's job, in one place: prepare -> fit -> export -> choose the base -> diagnose -> vehicle -> datasheet
-> report.

``run`` is what ``python -m tuner fit`` and every row of ``python -m tuner batch`` do; ``run_diagnosis``
what ``python -m tuner diagnose`` does. The stages hand their results on in memory (the prepared
``Problem``, the ``FitResult``, the ``Diagnosis``); the fit and the diagnosis write nothing but their
checkpoints, the job writes their files; each output file is written once (metrics.json a second time with
the full-rate check, which runs after the results are safe on disk and the diagnosis, at the final point):

    parameters.json, metrics.json, history_<model>.json, simulations.npz   the fit (FitResult.write); metrics.json's
                                                                            "warnings": the reading's, each once
                                                                            (``reading_warnings``)
    fmu/<Model>_tuned.fmu                                                   the tuned FMUs (export_fmus)
    diagnosis.json, figures/ (diag_residual_*), fmu/<Model>_<causes>_tuned.fmu
                                                                            the diagnosis (write_diagnosis; a
                                                                            failed one: write_diagnosis_failure)
    vehicle/vehicle.json, vehicle/<scenario>.png                            the vehicle (``vehicle=True``)
    vehicle/intervals.json                                                  its 95 % intervals (``vehicle_draws``)
    datasheet/datasheet.json, datasheet/*.csv                               every tuned FMU's datasheet (``datasheet``)
    time_budget.json                                                        each stage's and section's seconds
                                                                            and share of the run up to the
                                                                            report (``tuner.time_budget``; the
                                                                            log's last lines add the report's)
    report.html, figures/                                                   the report (last)
    checkpoints/                                                            what --resume continues from

Settings: one ``FitSettings``; the diagnosis's are derived from it (``diagnosis_settings``), so a
setting given on the command line reaches the fit and the diagnosis alike.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack
from dataclasses import dataclass, replace
from pathlib import Path

from damper_fmu.fmu import SLAVES, build
from damper_fmu.parameters import EFFECT_MODELS, MODEL_PARAMETERS
from tuner.data.reading import RigTest, reading_warnings
from tuner import strict_json
from tuner.diagnosis.bases import FittedBases, diagnosis_forecast
from tuner.datasheet.characteristic import DatasheetSettings
from tuner.datasheet.sheet import DATASHEET_FOLDER, Datasheet, make_datasheet, write_datasheet
from tuner.diagnosis.diagnose import Diagnosis, DiagnosisFailed, DiagnosisSettings, diagnose
from tuner.executors import FleetExecutor
from tuner.identification.best_point import continue_fit, lower_points
from tuner.identification.fit import FitResult, FitSettings, fit, full_rate_checks
from tuner.identification.intervals import ModelIntervals
from tuner.identification.problem import Problem
from tuner.identification.runner import SimulationError
from tuner.progress import SubStages, forecast, stage
from tuner.results.diagnosis_figures import diagnosis_figures
from tuner.results.diagnosis_report import make_diagnosis_report
from tuner.results.recommendation import recommend
from tuner.results.report import make_report
from tuner.time_budget import TimeBudget, section
from tuner.vehicle.compare import SCENARIO_NAMES, VEHICLE_FOLDER, ScenarioOptions, compare_fmus
from tuner.vehicle.propagation import INTERVALS_FOR, PropagationSettings, propagate

__all__ = ["JobOptions", "JobResult", "run", "run_diagnosis", "diagnosis_settings", "export_fmus", "wants_diagnosis",
           "write_diagnosis", "write_diagnosis_failure", "export_extended_fmu", "vehicle_consequences", "job_datasheet"]

#: the diagnosis's stage that the job runs: the extended model's export (a failure is recorded as the diagnosis's)
EXPORT_STAGE = "export of the extended FMU"


@dataclass(frozen=True)
class JobOptions:
    """What ``run`` does beside the fit (the command line's options of the job). ``diagnose_after``: diagnose the
    best-validated base form after the fit (when ``wants_diagnosis``); ``vehicle``: the tuned FMUs as the yaw
    dampers of the campaign's vehicle (``vehicle_consequences``), with 95 % intervals from up to ``vehicle_draws``
    parameter sets per FMU (0: none) run on ``vehicle_scheduler`` (None: in this process), for the recommended
    model's FMU or ``vehicle_intervals`` 'all'; ``provenance``: what the fit records of where its data came from
    (``metrics.json``); ``figures``: False writes the fit's report without its figures (``make_report``; the
    diagnosis's residual figures are drawn still); ``datasheet``: every tuned FMU's datasheet (``job_datasheet``)."""

    diagnose_after: bool = True
    vehicle: bool = False
    vehicle_draws: int = 0
    vehicle_scheduler: str | None = None
    vehicle_intervals: str = "recommended"
    provenance: dict | None = None
    figures: bool = True
    datasheet: bool = True


@dataclass
class JobResult:
    """What ``run`` produced: the output folder, the fit, the diagnosis (None when not run), the
    exported FMUs (the tuned models and the diagnosis's extended one) and the report's path."""

    out: Path
    fit: FitResult
    diagnosis: Diagnosis | None
    fmus: list
    report: Path


def diagnosis_settings(settings: FitSettings) -> DiagnosisSettings:
    """The diagnosis's settings after a fit with ``settings``: the same problem definition (fit rate,
    warm-up, differentiator band, abscissae, force limit, spring reference; the parametrization is
    the diagnosis's own, 'improved'), engine, workers and seed."""
    return DiagnosisSettings(data=replace(settings.data, parametrization="improved"),
                             workers=settings.workers, engine=settings.engine, seed=settings.seed)


def wants_diagnosis(settings: FitSettings, validation: list[RigTest]) -> bool:
    """A diagnosis can follow the fit: validation tests (its decision is the held-out gain) and a
    fitted base form (one of the models that carry the effect catalogue)."""
    return bool(validation) and any(m in EFFECT_MODELS for m in settings.models)


def export_fmus(result: FitResult, out: Path) -> list[Path]:
    """``out/fmu/<Model>_tuned.fmu`` for every fitted model: the identified values as start values, and in
    each identified parameter's description how well the identification tests determine it (its 95 %
    range and flags, ``tuner.identification.intervals``). The builds run side by side (each links its model's
    cached object, 0.05-0.1 s; the first of a model on a machine compiles it, about 1 s)."""
    jobs = []
    for model, p in result.params.items():
        names = {q.name for q in MODEL_PARAMETERS[model]}
        notes = ModelIntervals.from_dict(model, p["intervals"]).descriptions() if p.get("intervals") else {
            n: f"determined range unknown ({p.get('intervals_note', 'no intervals')})" for n in p["bounds"]}
        jobs.append(dict(kind=model, out=Path(out) / "fmu", start_values={k: v for k, v in p["values"].items()
                                                                       if k in names},
                         filename=f"{SLAVES[model]}_tuned.fmu", parameter_notes=notes))
    with ThreadPoolExecutor(max_workers=max(1, len(jobs))) as pool:
        return [f.result() for f in [pool.submit(build, **job) for job in jobs]]


def run(identification: list[RigTest], validation: list[RigTest], out: Path, settings: FitSettings, *,
        options: JobOptions = JobOptions(), log=print) -> JobResult:
    """The whole job into the existing folder ``out`` (checkpoints there are resumed): the fit with ``settings``,
    then what ``options`` asks (``JobOptions``: the diagnosis, the vehicle, the report's figures);
    log: a callable taking one line (or a ``tuner.progress.JobProgress``, whose stages it advances)."""
    out = Path(out)
    log = log if isinstance(log, TimeBudget) else TimeBudget(log)
    diagnose_after, figures = options.diagnose_after, options.figures
    problem = Problem.build(identification, validation, settings.data)  # prepared once, for every stage
    if diagnose_after and wants_diagnosis(settings, validation) and hasattr(log, "forecast"):
        # the progress display prices the diagnosis from the start
        ahead = diagnosis_forecast(problem, diagnosis_settings(settings),
                                   [m for m in settings.models if m in EFFECT_MODELS])
        forecast(log, "diagnosis", ahead.seconds, (ahead.forms_s, "the diagnosis tries the forms"))
    result = fit(identification, validation, settings, checkpoints=out / "checkpoints", provenance=options.provenance,
                 problem=problem, log=log)
    result.metrics["warnings"] = reading_warnings([*identification, *validation])  # for the summary and report
    result.write(out)
    section(log, "export of the tuned FMUs")
    log("exporting tuned FMUs ...")
    export_fmus(result, out)
    diagnosis = None
    if diagnose_after and wants_diagnosis(settings, validation):
        try:
            diagnosis = _diagnose(identification, validation, out, diagnosis_settings(settings),
                                  FittedBases.from_fit(result), log)
        except DiagnosisFailed:
            _full_rate(result, out, settings, log)
            make_report(out, figures=figures)  # the fit's report with the failure said: the fit and its FMUs are safe
            raise
        _at_the_best_point(result, diagnosis, out, settings, log)
    _full_rate(result, out, settings, log)  # once, at the final point
    if options.vehicle:
        vehicle_consequences(sorted((out / "fmu").glob("*_tuned.fmu")), out, settings.seed, log,
                             draws=options.vehicle_draws, scheduler=options.vehicle_scheduler,
                             intervals_for=options.vehicle_intervals)
    if options.datasheet:
        job_datasheet(sorted((out / "fmu").glob("*_tuned.fmu")), [*identification, *validation], out, log)
    report = _report(out, log, figures=figures, workers=settings.workers)
    return JobResult(out=out, fit=result, diagnosis=diagnosis, fmus=sorted((out / "fmu").glob("*.fmu")),
                     report=report)


def _at_the_best_point(result: FitResult, diagnosis: Diagnosis, out: Path, settings: FitSettings, log) -> None:
    """Where the diagnosis's base refit ended more than one standard error below the fit of a model
    (``tuner.identification.best_point``), that model's fit is continued from there and the fit's files and the tuned
    FMUs are written again at the final point (the log and ``history_<model>.json``'s ``best_point`` say which stage
    found it; the full-rate check follows, ``_full_rate``); nothing when every fit was its minimum."""
    lower = lower_points(diagnosis.get("base_refits") or {}, result.params)
    if not lower:
        return
    for point in lower:
        continue_fit(result, point, settings, log)
    result.write(out)
    section(log, "export of the tuned FMUs at the best point")
    export_fmus(result, out)


def _full_rate(result: FitResult, out: Path, settings: FitSettings, log) -> None:
    """The full-rate check of every fitted model at its final values into ``metrics.json`` (after the results are
    written: a failure here, an exception, never a number, loses nothing)."""
    section(log, "full-rate check")
    result.metrics["full_rate"] = full_rate_checks([*result.problem.identification, *result.problem.validation],
                                                   result.params, settings, log)
    result.write_metrics(out)


def run_diagnosis(identification: list[RigTest], validation: list[RigTest], out: Path,
                  settings: DiagnosisSettings, *, from_fit: FittedBases | None = None, figures: bool = True,
                  log=print) -> Diagnosis:
    """A diagnosis on its own into ``out`` (the bases from an earlier fit, ``from_fit``, or identified here; its
    files by ``write_diagnosis``), then the report: the full one when ``out`` holds that fit's files (``figures``: False
    without the fit's figures), the diagnosis alone otherwise."""
    out = Path(out)
    log = log if isinstance(log, TimeBudget) else TimeBudget(log)
    try:
        result = _diagnose(identification, validation, out, settings, from_fit, log)
    finally:  # a failed diagnosis gets its report too: what was finished, the failing stage, --resume
        if (out / "diagnosis.json").exists():
            if (out / "parameters.json").exists():
                _report(out, log, figures=figures, workers=settings.workers)
            else:
                stage(log, "report")
                make_diagnosis_report(out)
                log(log.text())
    return result


def _report(out: Path, log: TimeBudget, *, figures: bool, workers: int) -> Path:
    """The report of the folder ``out`` (``make_report``), after ``time_budget.json`` (the run's stages up to the
    report, which the report shows); the whole budget, the report's time too, is the log's last lines."""
    stage(log, "report")
    (out / "time_budget.json").write_text(strict_json.dumps(log.record(), indent=1))
    report = make_report(out, figures=figures, workers=workers)
    log(log.text())
    return report


def _diagnose(identification, validation, out, settings: DiagnosisSettings, from_fit: FittedBases | None,
              log) -> Diagnosis:
    """The diagnosis into ``out`` (its checkpoints in ``out/checkpoints``; the bases from the earlier fit
    ``from_fit``, or identified), then its files (``write_diagnosis``); a failed stage's record is written
    (``write_diagnosis_failure``) before ``DiagnosisFailed`` goes on."""
    stage(log, "diagnosis")
    log(f"\ndiagnosis: refitting the {from_fit.kind if from_fit else 'base'} model extended by each candidate "
        f"effect ...")
    try:
        diagnosis = diagnose(identification, validation, settings, from_fit=from_fit,
                             checkpoints=Path(out) / "checkpoints", log=log)
    except DiagnosisFailed as failed:
        write_diagnosis_failure(failed, out)
        raise
    write_diagnosis(diagnosis, out, log, workers=settings.workers)
    return diagnosis


def write_diagnosis(diagnosis: Diagnosis, out: Path, log=print, workers: int = 0) -> list[Path]:
    """The files of ``diagnosis`` into the output folder ``out``: the residual figures its record lists
    (``tuner.results.diagnosis_figures``, drawn in ``workers`` processes when >= 2), the extended model as a
    tuned FMU when a cause was named (``export_extended_fmu``) and ``diagnosis.json`` (the record, strict JSON).
    Returns the paths written.
    The export is the diagnosis's last stage: when it raises, ``diagnosis.json`` holds that failure
    (``write_diagnosis_failure``) and ``DiagnosisFailed`` is raised."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = diagnosis_figures(diagnosis, out, workers)
    if diagnosis.causes:
        try:
            paths.append(export_extended_fmu(diagnosis, out))
        except Exception as err:  # recorded as the diagnosis's failed stage: --resume exports again
            log(f"diagnosis: FAILED in its stage '{EXPORT_STAGE}': {type(err).__name__}: {err}")
            failed = diagnosis.failed(EXPORT_STAGE, err)
            write_diagnosis_failure(failed, out)
            raise failed from err
        log(f"extended model exported: {paths[-1]}")
    path = out / "diagnosis.json"
    path.write_text(strict_json.dumps(diagnosis.to_dict(), indent=2))
    return [*paths, path]


def export_extended_fmu(diagnosis: Diagnosis, out: Path) -> Path:
    """``out/fmu/<Model>_<causes>_tuned.fmu``: the base model of ``diagnosis`` extended by the causes it named,
    its final values as start values (e.g. ``DamperLumped_friction_tuned.fmu``); ValueError without a cause."""
    kind, causes = diagnosis.base_model, diagnosis.causes
    if not causes:
        raise ValueError("export_extended_fmu: the diagnosis named no cause, so there is no extended model "
                         "(the base model's FMU is the fit's, export_fmus)")
    return build(kind, Path(out) / "fmu", start_values=diagnosis.final_values,
                 filename=f"{SLAVES[kind]}_{'_'.join(causes)}_tuned.fmu")


def write_diagnosis_failure(failed: DiagnosisFailed, out: Path) -> Path:
    """``out/diagnosis.json`` of a diagnosis that failed (``failed.record``: no verdict, the failing stage, the
    error, what was finished); an earlier diagnosis.json is kept as ``diagnosis.previous.json`` (nothing is
    lost). Sets ``failed.path``, which its message names."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "diagnosis.json"
    if path.exists():
        path.replace(out / "diagnosis.previous.json")
    path.write_text(strict_json.dumps(failed.record, indent=2))
    failed.path = path
    return path


def interval_models(out: Path, intervals_for: str, log=print) -> tuple[str, ...] | None:
    """The models whose FMUs get vehicle intervals: None for 'all'; for 'recommended', the model the folder's
    recommendation names (``tuner.results.recommendation``; its base FMU: an extension's own parameters are not
    drawn), none when it names none. A model that fails the quality gate has no interval worth drawing: its
    covariance bounds its parameters, not its error (the default run's Maxwell FMU: 334-889 km/h)."""
    if intervals_for not in INTERVALS_FOR:
        raise ValueError(f"--vehicle-intervals must be one of {', '.join(INTERVALS_FOR)}, got {intervals_for!r}")
    if intervals_for == "all":
        return None
    rec = recommend(out)
    if rec.model is None:
        log("vehicle intervals: not computed, no model is recommended (--vehicle-intervals all draws every FMU)")
        return ()
    log(f"vehicle intervals: for the recommended {rec.model} FMU" + (f" (its base: the parameters of "
        f"{', '.join(rec.causes)} are not drawn)" if rec.causes else "") + "; --vehicle-intervals all draws every FMU")
    return (rec.model,)


def vehicle_consequences(fmus: list[Path], out: Path, seed: int = 0, log=print, *, draws: int = 0,
                         scheduler: str | None = None, intervals_for: str = "recommended") -> dict:
    """What the damper model changes at vehicle level: each FMU of ``fmus`` as the four yaw dampers of the
    campaign's vehicle in every scenario of ``tuner.vehicle.compare`` (hunting critical speed, curve
    entry, straight track with irregularities), into ``out / VEHICLE_FOLDER`` (the report's vehicle
    section). ``seed``: the irregularities' master seed and the draws'. ``draws`` > 0: the 95 % intervals of
    the critical speed and the curve's peak damper force from up to that many parameter sets per tuned FMU
    (``tuner.vehicle.propagation``), run on ``scheduler`` (None: in this process), for the FMUs of
    ``intervals_for``: 'recommended' (``interval_models``) or 'all'."""
    stage(log, "vehicle")
    log(f"vehicle: {len(fmus)} tuned FMUs as the yaw dampers, scenarios {', '.join(SCENARIO_NAMES)} ...")
    models = interval_models(out, intervals_for, log) if draws > 0 else ()
    with ExitStack() as open_executor:
        executor = FleetExecutor(scheduler) if scheduler else None
        try:  # the FMUs side by side on the draws' workers, started once for both
            executor = open_executor.enter_context(executor) if executor is not None else None
        except (ValueError, OSError, RuntimeError) as err:  # e.g. no Dask cluster there: the scenarios still run
            log(f"vehicle: {executor.description} not started ({err}): the scenarios run in this process, "
                f"no intervals")
            executor, models = None, ()
        data = compare_fmus(fmus, Path(out) / VEHICLE_FOLDER, options=ScenarioOptions(seed=seed), executor=executor,
                            log=SubStages(log, len(fmus) * len(SCENARIO_NAMES)))
        if models is None or models:
            stage(log, "vehicle intervals")
            try:
                propagate(out, PropagationSettings(draws=draws, seed=seed, irregularity_seed=seed, models=models),
                          executor=executor, log=log)
            except (ValueError, OSError, RuntimeError) as err:  # e.g. the Dask cluster went away: the rest stands
                log(f"vehicle intervals not computed: {err}")
    return data


def job_datasheet(fmus: list[Path], tests: list[RigTest], out: Path, log=print) -> Datasheet | None:
    """The datasheet of the tuned FMUs ``fmus`` (``tuner.datasheet``, default settings) into ``out / DATASHEET_FOLDER``
    (its figures are the report's). ``tests``: the rig tests, whose sine tests give the measured points. A failure
    (an FMU that refuses a sine) is logged and leaves the datasheet out: the fit, its FMUs and the rest stand."""
    stage(log, "datasheet")
    log(f"datasheet: {len(fmus)} tuned FMUs driven by sine strokes ...")
    try:
        sheet = make_datasheet(fmus, DatasheetSettings(), tests=tests, log=log)
        write_datasheet(sheet, Path(out) / DATASHEET_FOLDER)
    except (SimulationError, ValueError, OSError) as err:
        log(f"datasheet not written: {err}")
        return None
    log(f"datasheet: {sheet.seconds:.1f} s of sines, written to {Path(out) / DATASHEET_FOLDER}")
    return sheet
