"""``python -m tuner fit`` (the main job: ``tuner.job.run``) and ``python -m tuner diagnose``."""
from __future__ import annotations

import sys
import time
from pathlib import Path

from damper_fmu.fmu import fast_path_note, native_reason
from damper_fmu.parameters import EFFECT_MODELS, MODEL_KINDS
from tuner import job
from tuner.cli.folders import DEFAULT_DATASET, DEFAULT_RESULTS, free_folder, prepare_out, tidy_checkpoints
from tuner.cli.log import end_job, job_log, log, progress, start_job
from tuner.cli.options import add_fit_options, fit_settings, load_tests, vehicle_scheduler
from tuner.cli.summary import end_summary, print_table3
from tuner.diagnosis.bases import FittedBases
from tuner.diagnosis.diagnose import DiagnosisFailed
from tuner import strict_json
from tuner.worker_processes import pool_context

__all__ = ["add_parsers", "cmd_fit", "cmd_diagnose", "check_engine", "start_workers_early"]


def add_parsers(sub) -> None:
    """Register ``fit`` and ``diagnose`` on an argparse subparsers object."""
    p_fit = sub.add_parser("fit", help="identify, validate and report on your data")
    add_fit_options(p_fit)
    p_fit.set_defaults(func=cmd_fit)
    p_diag = sub.add_parser("diagnose", help="what the fitted model gets wrong, the cause, the gain")
    add_fit_options(p_diag)
    p_diag.add_argument("--from", dest="from_fit", type=Path, help="output folder of an earlier fit (its "
                        "best-validated lumped or two-chamber model is the base; otherwise both are identified "
                        "here and the better one on held-out data is kept)")
    p_diag.set_defaults(func=cmd_diagnose)


def check_engine(args) -> None:
    """Say once when the fast (native) path is off, and refuse ``--engine native`` without it."""
    if args.engine == "native" and native_reason():
        raise ValueError(f"--engine native needs the C kernel: {native_reason()}; use --engine fmu or inprocess")
    note = fast_path_note()
    if note:
        log(note)


#: seconds each stage of the bundled job takes on a 2-core machine (python -m tuner, 2026-11-28, after the
#: two-chamber kernel's pattern solve; the report's figures in the workers 2026-11-29: docs/measurements.md):
#: what the progress display plans before a stage says its own time (``expect``) and scales by how the finished
#: stages went against it. A base form's fit is 6 s when it races one fitted before it (``fit_order``) and
#: ``FIRST_BASE_EXTRA_S`` more when it is the first (every refinement restart: 26-29 s), whichever that is
#: (``JobProgress``'s ``first_of``); the vehicle intervals stop after the first round of 8 draws when the
#: Monte-Carlo errors are small (10 s per drawn FMU).
FIT_S = {"lumped": 6.0, "twochamber": 6.0, "maxwell": 3.0, "maxwell_table": 8.0}
FIRST_BASE_EXTRA_S = 22.0
STAGE_S = {"validate and export": 3.0, "diagnosis": 26.0, "report": 5.5, "report without figures": 0.5}
VEHICLE_S_PER_FMU = 2.0
DATASHEET_S_PER_FMU = 1.0
DRAW_S, FIRST_ROUND_DRAWS = 1.25, 8


def first_base_fit(args, models: tuple[str, ...]) -> tuple[tuple[str, ...], float]:
    """(the base forms' fit stages, the extra seconds [s] of the first of them to run): ``JobProgress``'s
    ``first_of``, scaled by the Firefly budget as ``planned_seconds``."""
    budget = args.population * args.iterations / (20 * 150)
    return tuple(f"fit {m}" for m in models if m in EFFECT_MODELS), FIRST_BASE_EXTRA_S * budget


def planned_seconds(args, models: tuple[str, ...]) -> dict[str, float]:
    """The job's stages and their planned seconds [s] (``FIT_S``, ``STAGE_S``): the fits scaled by the Firefly
    budget against the default one (20 fireflies, 150 iterations), the stages this command runs only; the first
    base form's extra in ``first_base_fit``."""
    budget = args.population * args.iterations / (20 * 150)
    weights = {f"fit {m}": FIT_S[m] * budget for m in models}
    report = STAGE_S["report without figures" if getattr(args, "no_figures", False) else "report"]
    weights.update({"validate and export": STAGE_S["validate and export"], "report": report})
    if getattr(args, "vehicle", False):
        weights["vehicle"] = VEHICLE_S_PER_FMU * len(models)
        if args.vehicle_draws > 0:
            drawn = len(models) if args.vehicle_intervals == "all" else 1
            weights["vehicle intervals"] = DRAW_S * min(args.vehicle_draws, FIRST_ROUND_DRAWS) * drawn
    if not args.no_diagnose and any(m in EFFECT_MODELS for m in models):
        weights["diagnosis"] = STAGE_S["diagnosis"]
    if not getattr(args, "no_datasheet", False):
        weights["datasheet"] = DATASHEET_S_PER_FMU * len(models)
    return weights


def start_workers_early(args) -> None:
    """With worker processes (``--workers``): start their fork server now (``tuner.worker_processes``), so that it
    imports the simulation modules (about 2 s) while this process reads and prepares the data."""
    if args.workers:
        pool_context()


def cmd_fit(args) -> int:
    check_engine(args)
    start_workers_early(args)

    models = tuple(m.strip() for m in args.models.split(",") if m.strip())
    bad = [m for m in models if m not in MODEL_KINDS]
    if bad or not models:
        raise ValueError(f"unknown model(s) {bad}; choose from {', '.join(MODEL_KINDS)}")
    for opt in ("population", "iterations"):
        if getattr(args, opt) < 1:
            raise ValueError(f"--{opt} must be >= 1")
    if args.population < 2:
        raise ValueError("--population must be >= 2")
    vehicle_scheduler(args)  # --vehicle-draws and --vehicle-scheduler checked before anything runs
    t0 = time.perf_counter()
    start_job(args, planned_seconds(args, models), first_base_fit(args, models))
    failed = None
    try:
        out = _fit_job(args, models)
    except DiagnosisFailed as err:  # the fit and its FMUs are written: the summary says there is no verdict
        failed, out = err, err.path.parent
    finally:
        end_job()
    return _end(out, args, t0, failed)


def _end(out: Path, args, t0: float, failed: DiagnosisFailed | None) -> int:
    """The end of a command: checkpoints tidied (kept after a failed diagnosis, for --resume), the end summary
    (also after a failed diagnosis: no recommendation, how to continue), the failure raised on."""
    if failed is None:
        tidy_checkpoints(out, args.keep_checkpoints)
    end_summary(out, time.perf_counter() - t0)
    if failed is not None:
        raise failed
    return 0


def _fit_job(args, models) -> Path:
    ident, valid, name = load_tests(args)
    out = args.out or free_folder(DEFAULT_RESULTS / name)
    out = prepare_out(out, args.resume, args.force)
    settings = fit_settings(args, models)
    provenance = {"dataset": str(args.dataset) if args.dataset else None,
                  "files": {t.name: str(t.source) for t in ident + valid},
                  "command": " ".join(sys.argv)}
    log(f"output folder: {out}")
    diagnosis = not args.no_diagnose and job.wants_diagnosis(settings, valid)
    if not diagnosis and progress() is not None:
        progress().weights.pop("diagnosis", None)
    options = job.JobOptions(diagnose_after=diagnosis, vehicle=args.vehicle, vehicle_draws=args.vehicle_draws,
                             vehicle_scheduler=vehicle_scheduler(args), vehicle_intervals=args.vehicle_intervals,
                             provenance=provenance, figures=not args.no_figures, datasheet=not args.no_datasheet)
    result = job.run(ident, valid, out, settings, options=options, log=job_log())  # the display when a job runs
    print_table3(result.fit.metrics)
    return out


def _fitted_bases(folder: Path) -> FittedBases:
    """The bases of the fit in ``folder`` for a diagnosis after it (its ``parameters.json`` and ``metrics.json``)."""
    return FittedBases.from_records(strict_json.loads((folder / "parameters.json").read_text()),
                                    strict_json.loads((folder / "metrics.json").read_text()))


def cmd_diagnose(args) -> int:
    check_engine(args)
    start_workers_early(args)
    if not args.dataset and not args.identification:
        args.dataset = DEFAULT_DATASET  # by default the bundled dataset
    ident, valid, name = load_tests(args)
    if not valid:
        raise ValueError("the diagnosis needs validation tests: its decision is the held-out gain")
    fitted = None
    if args.from_fit:
        pj = args.from_fit / "parameters.json"
        if not pj.exists() or not (args.from_fit / "metrics.json").exists():
            raise ValueError(f"--from {args.from_fit}: no parameters.json and metrics.json (not a fit output folder)")
        try:
            fitted = _fitted_bases(args.from_fit)
        except ValueError as err:
            raise ValueError(f"--from {args.from_fit}: {err}") from None
    out = prepare_out(args.out or free_folder(DEFAULT_RESULTS / f"{name}-diagnosis"), args.resume, args.force)
    if fitted is not None and args.from_fit.resolve() != out.resolve():
        for f in ("parameters.json", "metrics.json", "simulations.npz",
                  *[f"history_{m}.json" for m in MODEL_KINDS]):
            if (args.from_fit / f).exists():
                (out / f).write_bytes((args.from_fit / f).read_bytes())
    log(f"output folder: {out}")
    t0 = time.perf_counter()
    start_job(args, {"diagnosis": 70.0 if fitted is not None else 130.0, "report": 5.0})
    failed = None
    try:  # the diagnosis states the verdict once
        job.run_diagnosis(ident, valid, out, job.diagnosis_settings(fit_settings(args)), from_fit=fitted,
                          figures=not args.no_figures, log=job_log())
    except DiagnosisFailed as err:
        failed = err
    finally:
        end_job()
    return _end(out, args, t0, failed)
