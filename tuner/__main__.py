"""Command line of the damper tuner.

    python -m tuner                      identify the lumped, Maxwell and two-chamber models on the
                                         bundled dataset, validate, diagnose, put the tuned FMUs in the
                                         vehicle, report (results/default[-N])
    python -m tuner fit ...              the same on your own data (see --help)
    python -m tuner generate --out DIR   virtual test campaign -> a six-test dataset
    python -m tuner diagnose ...         what the fitted model gets wrong and why (see --help)
    python -m tuner inspect FILES        what the reader understands of rig files (see --help)
    python -m tuner batch MANIFEST       a fleet: one fit per manifest row, local pool or Dask (see --help)
    python -m tuner report DIR           rebuild the report of a fit output folder
    python -m tuner vehicle --fmus F...  the damper FMUs in a vehicle: critical speed, curve, ride (see --help)

Exit status: 0 success, 2 bad input or arguments (message on stderr), 130 interrupted.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from pathlib import Path

from campaign.cli import add_generate_arguments, cmd_generate as generate_command
from damper_fmu.fmu import fast_path_note, native_reason
from damper_fmu.parameters import EFFECT_MODELS, MODEL_KINDS
from tuner import job
from tuner.cli.batch import CONTINUE_HINT, add_parser as add_batch_parser
from tuner.cli.folders import free_folder
from tuner.cli.run import run_handler
from tuner.cli.vehicle import add_parser as add_vehicle_parser
from tuner.data.reading import DEFAULT_DAMPER_CLASS, load_dataset, load_files, read_column_mapping
from tuner.data.summary import format_summary, summarize
from tuner.diagnosis.diagnose import choose_base
from tuner.identification.fit import FitSettings
from tuner.progress import JobProgress
from tuner.results.report import make_report
from tuner.vehicle.compare import VEHICLE_FOLDER

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATASET = ROOT / "data" / "default"
DEFAULT_RESULTS = ROOT / "results"


_OUT = None  # the job's progress display while a job runs (tuner.progress.JobProgress)


def _log(msg: str) -> None:
    if _OUT is not None:
        _OUT(msg)
    else:
        print(msg, flush=True)


def _start_job(args, weights: dict) -> "object":
    """Progress display over the job's stages (``weights``: expected seconds); it is the log."""
    global _OUT
    _OUT = JobProgress(weights, quiet=getattr(args, "quiet", False))
    return _OUT


def _end_job() -> None:
    global _OUT
    if _OUT is not None:
        _OUT.finish()
    _OUT = None


def _end_summary(out: Path, seconds: float, quiet: bool = False) -> dict:
    """Write ``summary.json`` and print the end-of-run summary once, after everything is written:
    verdict, causes, validation AME per test and model, quality gate, where the report and FMUs are."""
    metrics = json.loads((out / "metrics.json").read_text()) if (out / "metrics.json").exists() else {}
    diag = json.loads((out / "diagnosis.json").read_text()) if (out / "diagnosis.json").exists() else {}
    vpath = out / VEHICLE_FOLDER / "vehicle.json"
    vehicle = json.loads(vpath.read_text()) if vpath.exists() else {}
    ame = {}
    for name, t in (metrics.get("tests") or {}).items():
        if t.get("role") == "validation":
            ame[name] = {m: {"ame_n": r["ame"], "ame_pct_of_peak": 100 * r["ame"] / r["peak_measured"]}
                         for m, r in t["models"].items()}
    summary = {
        "verdict": diag.get("verdict"), "cause": diag.get("cause"), "causes": diag.get("causes"),
        "effect_parameters": diag.get("effect_parameters"),
        "quality": {m: {k: q[k] for k in ("describes_data", "worst_ame_pct_of_peak", "worst_test", "gate_pct")}
                    for m, q in (metrics.get("quality") or {}).items()},
        "validation_ame": ame,
        "critical_speed_kmh": {k: (r.get("critical_speed") or {}).get("critical_speed_kmh")
                               for k, r in vehicle.get("results", {}).items()},
        "report": str(out / "report.html") if (out / "report.html").exists() else None,
        "fmus": sorted(str(f) for f in out.rglob("*.fmu")),
        "total_time_s": seconds, "output_folder": str(out),
    }
    tmp = out / "summary.json.tmp"
    tmp.write_text(json.dumps(summary, indent=1, default=str))
    tmp.replace(out / "summary.json")
    lines = ["", "=" * 72, f"done in {seconds / 60:.1f} min: {out}"]
    for m, q in summary["quality"].items():
        lines.append(f"  {m}: {'describes the data' if q['describes_data'] else 'does NOT describe the data'} "
                     f"(worst held-out AME {q['worst_ame_pct_of_peak']:.3g} % of peak, gate {q['gate_pct']:g} %)")
    if ame:
        models = sorted({m for r in ame.values() for m in r})
        lines.append("  validation AME [% of peak]: " + "; ".join(
            f"{n}: " + ", ".join(f"{m} {r[m]['ame_pct_of_peak']:.3g}" for m in models if m in r) for n, r in ame.items()))
    if summary["verdict"]:
        lines.append(f"  diagnosis: {summary['verdict']}")
    if summary["critical_speed_kmh"]:
        lines.append("  vehicle, hunting critical speed [km/h]: " + ", ".join(
            f"{k} {'-' if v is None else format(v, '.0f')}" for k, v in summary["critical_speed_kmh"].items()))
    if summary["report"]:
        lines.append(f"  report: {summary['report']}")
    for f in summary["fmus"]:
        lines.append(f"  FMU: {f}")
    lines.append(f"  summary for scripts: {out / 'summary.json'}")
    print("\n".join(lines), flush=True)
    return summary


def _tidy_checkpoints(out: Path, keep: bool) -> None:
    """After a successful run the checkpoints (what --resume continues from) are removed unless kept."""
    ck = out / "checkpoints"
    if ck.is_dir() and not keep:
        shutil.rmtree(ck)


def _prepare_out(out: Path, resume: bool, force: bool) -> Path:
    if out.exists() and any(out.iterdir()):
        if resume:
            if not (out / "checkpoints").is_dir():
                raise ValueError(f"--resume: {out} holds no checkpoints of an earlier run")
            return out
        if not force:
            raise FileExistsError(f"output folder {out} exists and is not empty: use --resume to continue "
                                  f"that run, --force to move it aside, or another --out")
        backup = free_folder(Path(f"{out}.old"))
        out.rename(backup)
        _log(f"moved the existing {out} to {backup}")
    elif resume:
        raise ValueError(f"--resume: {out} does not exist or is empty")
    out.mkdir(parents=True, exist_ok=True)
    return out


def _add_data_options(g) -> None:
    """Options saying how to read rig files (all default to None: the file's own declaration, else SI)."""
    g.add_argument("--time-col", default=None, metavar="COL",
                   help="time column: header, header without its unit, or 1-based position (default 'time'); "
                        "'none' with --rate when the file has no time column. Seconds, milliseconds "
                        "(--time-unit ms) or date/ISO timestamps")
    g.add_argument("--stroke-col", default=None, metavar="COL", help="stroke column (default 'stroke')")
    g.add_argument("--force-col", default=None, metavar="COL", help="force column (default 'force')")
    g.add_argument("--velocity-col", default=None, metavar="COL",
                   help="the rig's measured stroke velocity, used instead of differentiating the stroke")
    g.add_argument("--temperature-col", default=None, metavar="COL",
                   help="column holding the oil temperature (default: a column named 'temperature', if any)")
    g.add_argument("--test-col", default=None, metavar="COL",
                   help="test-id column: a file holding several tests is split by its values")
    g.add_argument("--time-unit", default=None, choices=["s", "ms"])
    g.add_argument("--stroke-unit", default=None, choices=["m", "cm", "mm", "um"],
                   help="unit of the stroke (default: as the header or units row declares, else m)")
    g.add_argument("--force-unit", default=None, choices=["N", "daN", "kN"],
                   help="unit of the force (default: as the header or units row declares, else N)")
    g.add_argument("--velocity-unit", default=None, choices=["m/s", "cm/s", "mm/s", "um/s"])
    g.add_argument("--temperature-unit", default=None, choices=["degC", "K"])
    g.add_argument("--stroke-sign", type=int, default=None, choices=[1, -1],
                   help="-1 if the rig writes compression as positive stroke (ours: extension positive)")
    g.add_argument("--force-sign", type=int, default=None, choices=[1, -1],
                   help="-1 if the rig writes compression as positive force (ours: tension positive)")
    g.add_argument("--rate", type=float, default=None, metavar="HZ", help="sample rate of files without time")
    g.add_argument("--t-start", type=float, default=None, metavar="S",
                   help="use the test from this time [s from its first sample]")
    g.add_argument("--t-end", type=float, default=None, metavar="S", help="... up to this time [s]")
    g.add_argument("--columns", type=Path, default=None, metavar="FILE",
                   help="column mapping file (TOML or JSON) for campaigns with many files: the options above "
                        "as keys (time_col, stroke_unit, force_sign ...), for every file and per file name")
    g.add_argument("--accept-implausible", action="store_true",
                   help="read data that fails the physical plausibility checks (units) as declared")
    g.add_argument("--damper-class", default=None, choices=["yaw", "primary", "secondary", "any"],
                   help="the kind of railway damper tested (default yaw): a test whose apparent damping is "
                        "outside that class's range is read with a warning (a force in kN read as N)")


_DATA_OPTIONS = ("time_col", "stroke_col", "force_col", "velocity_col", "temperature_col", "test_col", "time_unit",
                 "stroke_unit", "force_unit", "velocity_unit", "temperature_unit", "stroke_sign", "force_sign",
                 "t_start", "t_end", "damper_class")


def _column_options(args) -> tuple[dict, dict]:
    """(options for every file, file name -> its own options) from the mapping file and the command line;
    the command line wins."""
    common, per_file = read_column_mapping(args.columns) if args.columns else ({}, {})
    given = {k: getattr(args, k) for k in _DATA_OPTIONS if getattr(args, k) is not None}
    if given.get("time_col", "").lower() == "none":
        given["time_col"] = None
    if args.rate is not None:
        given["rate_hz"] = args.rate
    if args.accept_implausible:
        given["check_plausible"] = False
    return {**common, **given}, {name: {**opts, **given} for name, opts in per_file.items()}


def _add_fit_options(ap: argparse.ArgumentParser) -> None:
    d = FitSettings()
    g = ap.add_argument_group("data")
    g.add_argument("--dataset", type=Path, help="dataset folder with manifest.json (roles from the manifest)")
    g.add_argument("--identification", nargs="+", type=Path, default=[], metavar="FILE",
                   help="identification test files (CSV/Parquet)")
    g.add_argument("--validation", nargs="+", type=Path, default=[], metavar="FILE",
                   help="validation test files (held out)")
    _add_data_options(g)
    g = ap.add_argument_group("identification")
    g.add_argument("--models", default=",".join(d.models),
                   help="comma-separated from lumped, maxwell, maxwell_table, twochamber (the twin-tube form; "
                        "default: %(default)s)")
    g.add_argument("--population", type=int, default=d.population, help="fireflies (default %(default)s)")
    g.add_argument("--iterations", type=int, default=d.iterations, help="max iterations (default %(default)s)")
    g.add_argument("--workers", type=int, default=d.workers, help="worker processes (default %(default)s)")
    g.add_argument("--seed", type=int, default=d.seed)
    g.add_argument("--engine", default=d.engine, choices=["fmu", "native", "inprocess"],
                   help="fmu: the built FMU through fmpy (default; the native FMU where a C compiler is "
                        "found); native: the same C kernel called once per test, without FMI (faster, "
                        "equal results); inprocess: the Python reference (slow)")
    g.add_argument("--parametrization", default=d.parametrization, choices=["improved", "paper"])
    g.add_argument("--init", default=d.init, choices=["seeded", "random"],
                   help="seeded: data-driven guess and preset in the first population (default)")
    g.add_argument("--fit-rate", type=float, default=d.fit_rate_hz, help="resample to this rate [Hz]")
    g.add_argument("--warmup", type=float, default=d.warmup_s, help="seconds skipped at each test start")
    g.add_argument("--diff-band", type=float, default=d.diff_band_hz, metavar="HZ",
                   help="band up to which the stroke differentiator is accurate to 0.5 %% (default: per test, where "
                        "99 %% of the stroke velocity's power lies, 20 Hz at least; ignored with --velocity-col)")
    g.add_argument("--force-limit", type=float, default=None,
                   help="Fc,O ordinate limit [N] (default: 1.5 x peak measured force)")
    g.add_argument("--damping-abscissae", type=_float_list, default=None, metavar="V1,...,V14",
                   help="the 14 rates [mm/s] of the Fc,O table, increasing (default: Table 2's, stretched to the "
                        "data's peak velocity when it exceeds 150 mm/s)")
    g.add_argument("--elastic-abscissae", type=_float_list, default=None, metavar="X1,...,X10",
                   help="the 10 elongations [mm] of the Fk,O table, increasing (default: Table 2's, stretched when "
                        "the peak force would elongate the reference spring beyond 3 mm)")
    g.add_argument("--no-stop", action="store_true", help="disable the paper's stagnation stopping rule")
    g.add_argument("--no-diagnose", action="store_true",
                   help="skip the diagnosis that follows the fit (it needs validation tests)")
    g.add_argument("--vehicle", action="store_true",
                   help="yaw dampers: run the tuned FMUs as the yaw dampers of the campaign's vehicle (critical "
                        "speed, curve entry, straight track; about 25 s) and add the section to the report "
                        "(on in the default run)")
    g.add_argument("--polish", type=int, default=d.polish_jacobians, metavar="N",
                   help="local least-squares refinement after Firefly until converged, at most N Jacobians "
                        "(default %(default)s, a safety cap; 0 = the paper's Firefly result as is)")
    g = ap.add_argument_group("output")
    g.add_argument("--out", type=Path, help="output folder (default results/<dataset name>[-N])")
    g.add_argument("--resume", action="store_true", help="continue an interrupted run in --out")
    g.add_argument("--force", action="store_true", help="move an existing --out aside (never deleted)")
    g.add_argument("--keep-checkpoints", action="store_true",
                   help="keep out/checkpoints after a successful run (by default they are removed: they only "
                        "serve --resume after an interruption)")
    g.add_argument("--quiet", action="store_true", help="no progress and no log lines; only the final summary")


def _load(args, file_role: str | None = "identification"):
    """(identification tests, validation tests, name) from --dataset or the files; ``file_role``: the
    role of --identification files (None for ``inspect``, which only reads them)."""
    common, per_file = _column_options(args)

    def read(paths, role):
        return [t for p in paths for t in load_files([p], role, **{**common, **per_file.get(Path(p).name, {})})]

    if args.dataset and (args.identification or args.validation):
        raise ValueError("give either --dataset or --identification/--validation files, not both")
    if args.dataset:
        tests = load_dataset(args.dataset, check_plausible=not args.accept_implausible,
                             damper_class=args.damper_class or DEFAULT_DAMPER_CLASS)
        ident = [t for t in tests if t.role == "identification"]
        valid = [t for t in tests if t.role == "validation"]
        name = args.dataset.resolve().name
    else:
        if not args.identification:
            raise ValueError("no data: give --dataset DIR or --identification FILE ...")
        ident = read(args.identification, file_role)
        valid = read(args.validation, "validation")
        name = "fit"
    if not ident:
        raise ValueError("the data holds no identification test")
    rate, band = _fit_rate_and_band(args)
    if not getattr(args, "json", False):  # inspect --json: the JSON alone on stdout
        _log("data as read:")
        for t in ident + valid:
            _log(format_summary(t, rate, band))
    names = [t.name for t in ident + valid]
    if len(set(names)) != len(names):
        raise ValueError(f"test names must be unique, got {names}")
    return ident, valid, name


def _fit_rate_and_band(args) -> tuple[float, float | None]:
    """Fit rate [Hz] and differentiator band [Hz] (None: from the data) the command will use."""
    return getattr(args, "fit_rate", None) or FitSettings().fit_rate_hz, getattr(args, "diff_band", None)


def cmd_inspect(args) -> int:
    if args.files and args.dataset:
        raise ValueError("give either --dataset or FILES, not both")
    if not args.files and not args.dataset:
        args.dataset = DEFAULT_DATASET
    args.identification, args.validation = list(args.files), []
    ident, valid, _ = _load(args, file_role=None)
    if args.json:
        rate, band = _fit_rate_and_band(args)
        print(json.dumps([summarize(t, rate, band) for t in ident + valid], indent=1))
    return 0


def _check_engine(args) -> None:
    """Say once when the fast (native) path is off, and refuse ``--engine native`` without it."""
    if args.engine == "native" and native_reason():
        raise ValueError(f"--engine native needs the C kernel: {native_reason()}; use --engine fmu or inprocess")
    note = fast_path_note()
    if note:
        _log(note)


def cmd_fit(args) -> int:
    _check_engine(args)

    models = tuple(m.strip() for m in args.models.split(",") if m.strip())
    bad = [m for m in models if m not in MODEL_KINDS]
    if bad or not models:
        raise ValueError(f"unknown model(s) {bad}; choose from {', '.join(MODEL_KINDS)}")
    for opt in ("population", "iterations"):
        if getattr(args, opt) < 1:
            raise ValueError(f"--{opt} must be >= 1")
    if args.population < 2:
        raise ValueError("--population must be >= 2")
    t0 = time.perf_counter()
    budget = args.population * args.iterations / (20 * 150)  # relative to the default run's
    weights = {f"fit {m}": {"lumped": 60.0, "maxwell": 8.0, "maxwell_table": 30.0, "twochamber": 60.0}[m] * budget
               for m in models}
    weights.update({"validate and export": 12.0, "report": 8.0})
    if getattr(args, "vehicle", False):
        weights["vehicle"] = 8.0 * len(models)
    if not args.no_diagnose and any(m in EFFECT_MODELS for m in models):
        weights["diagnosis"] = 70.0
    _start_job(args, weights)
    try:
        out = _fit_job(args, models)
    finally:
        _end_job()
    _tidy_checkpoints(out, args.keep_checkpoints)
    _end_summary(out, time.perf_counter() - t0)
    return 0


def fit_settings(args, models: tuple | None = None) -> "object":
    """The one mapping of the command line's options to ``FitSettings`` (SI units: the abscissae are
    given in mm and mm/s); ``models``: the checked --models (default the settings' own)."""
    return FitSettings(models=models or FitSettings().models, fit_rate_hz=args.fit_rate, warmup_s=args.warmup,
                       population=args.population, iterations=args.iterations, workers=args.workers,
                       seed=args.seed, engine=args.engine, parametrization=args.parametrization,
                       init=args.init, force_limit_n=args.force_limit,
                       stop_tol=None if args.no_stop else 1e-3, polish_jacobians=args.polish,
                       diff_band_hz=args.diff_band,
                       damping_abscissae_m_s=None if args.damping_abscissae is None else
                       tuple(1e-3 * v for v in args.damping_abscissae),
                       elastic_abscissae_m=None if args.elastic_abscissae is None else
                       tuple(1e-3 * x for x in args.elastic_abscissae))


def _fit_job(args, models) -> Path:
    ident, valid, name = _load(args)
    out = args.out or free_folder(DEFAULT_RESULTS / name)
    out = _prepare_out(out, args.resume, args.force)
    settings = fit_settings(args, models)
    provenance = {"dataset": str(args.dataset) if args.dataset else None,
                  "files": {t.name: str(t.source) for t in ident + valid},
                  "command": " ".join(sys.argv)}
    _log(f"output folder: {out}")
    diagnosis = not args.no_diagnose and job.wants_diagnosis(settings, valid)
    if not diagnosis and _OUT is not None:
        _OUT.weights.pop("diagnosis", None)
    result = job.run(ident, valid, out, settings, diagnose_after=diagnosis, vehicle=args.vehicle,
                     provenance=provenance, log=_OUT or _log)  # the progress display when a job runs
    _print_summary(result.fit.metrics)
    return out


def _fitted_base(folder: Path) -> tuple:
    """(base parameters, kind, how it was chosen, the other fitted bases) for a diagnosis after the fit
    in ``folder``."""
    kind, values, choice, others = choose_base(json.loads((folder / "parameters.json").read_text()),
                                               json.loads((folder / "metrics.json").read_text()))
    return values, kind, choice, others


def cmd_diagnose(args) -> int:
    _check_engine(args)
    if not args.dataset and not args.identification:
        args.dataset = DEFAULT_DATASET  # by default the bundled dataset
    ident, valid, name = _load(args)
    if not valid:
        raise ValueError("the diagnosis needs validation tests: its decision is the held-out gain")
    base, base_kind, base_choice, others = None, None, None, None
    if args.from_fit:
        pj = args.from_fit / "parameters.json"
        if not pj.exists() or not (args.from_fit / "metrics.json").exists():
            raise ValueError(f"--from {args.from_fit}: no parameters.json and metrics.json (not a fit output folder)")
        try:
            base, base_kind, base_choice, others = _fitted_base(args.from_fit)
        except ValueError as err:
            raise ValueError(f"--from {args.from_fit}: {err}") from None
    out = args.out or free_folder(DEFAULT_RESULTS / f"{name}-diagnosis")
    if out.exists() and any(out.iterdir()):
        raise FileExistsError(f"output folder {out} exists and is not empty: choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    if base is not None and args.from_fit.resolve() != out.resolve():
        for f in ("parameters.json", "metrics.json", "simulations.npz",
                  *[f"history_{m}.json" for m in MODEL_KINDS]):
            if (args.from_fit / f).exists():
                (out / f).write_bytes((args.from_fit / f).read_bytes())
    _log(f"output folder: {out}")
    t0 = time.perf_counter()
    _start_job(args, {"diagnosis": 70.0 if base is not None else 130.0, "report": 5.0})
    try:
        # it states the verdict once
        job.run_diagnosis(ident, valid, out, job.diagnosis_settings(fit_settings(args)), base_params=base,
                          base_model=base_kind, base_choice=base_choice, other_bases=others, log=_OUT or _log)
    finally:
        _end_job()
    _tidy_checkpoints(out, args.keep_checkpoints)
    _end_summary(out, time.perf_counter() - t0)
    return 0


def _print_summary(metrics: dict) -> None:
    t3 = metrics.get("table3") or {}
    if not t3:
        return
    _log("\nTable 3 (validation)           MSE Maxwell   MSE lumped    var.    AME Maxwell  AME lumped   var.  AME/peak")
    for name, r in t3.items():
        _log(f"  {name:28s} {r['mse_maxwell']:11.3e} {r['mse_lumped']:11.3e} {r['mse_variation_pct']:7.1f}% "
             f"{r['ame_maxwell']:10.0f} N {r['ame_lumped']:9.0f} N {r['ame_variation_pct']:6.1f}% "
             f"{r['ame_lumped_pct_of_peak']:6.2f}%")


def _float_list(text: str) -> list[float]:
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None


def cmd_generate(args) -> int:
    """The campaign's own command (``python -m campaign generate``), with the tuner's log."""
    return generate_command(args, log=_log)


def cmd_report(args) -> int:
    _log(f"report: {make_report(args.folder)}")
    return 0


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    ap = argparse.ArgumentParser(prog="python -m tuner", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="command")
    p_fit = sub.add_parser("fit", help="identify, validate and report on your data")
    _add_fit_options(p_fit)
    p_gen = sub.add_parser("generate", help="virtual test campaign -> dataset folder (python -m campaign generate)")
    add_generate_arguments(p_gen)
    p_diag = sub.add_parser("diagnose", help="what the fitted model gets wrong, the cause, the gain")
    _add_fit_options(p_diag)
    p_diag.add_argument("--from", dest="from_fit", type=Path, help="output folder of an earlier fit (its "
                        "best-validated lumped or two-chamber model is the base; otherwise both are identified "
                        "here and the better one on held-out data is kept)")
    p_ins = sub.add_parser("inspect", help="what the reader understands of rig files (columns, units, ranges)")
    p_ins.add_argument("files", nargs="*", type=Path, metavar="FILE", help="rig test files (CSV/TSV/Parquet)")
    p_ins.add_argument("--dataset", type=Path, help="a dataset folder with manifest.json instead of files")
    p_ins.add_argument("--json", action="store_true", help="also print the figures as JSON (SI units)")
    _add_data_options(p_ins.add_argument_group("data"))
    p_rep = sub.add_parser("report", help="rebuild the report of a fit output folder")
    p_rep.add_argument("folder", type=Path)
    add_batch_parser(sub)
    add_vehicle_parser(sub)
    if not argv:
        argv = ["fit", "--dataset", str(DEFAULT_DATASET), "--vehicle"]
    args = ap.parse_args(argv)
    if args.command is None:
        ap.print_help()
        return 2
    handler = {"fit": cmd_fit, "generate": cmd_generate, "report": cmd_report, "diagnose": cmd_diagnose,
               "inspect": cmd_inspect}.get(args.command) or args.func
    hint = CONTINUE_HINT if args.command == "batch" else "run again with --resume and the same --out to continue"
    return run_handler(handler, args, hint)

if __name__ == "__main__":
    code = main()
    # leave without interpreter teardown: every FMU has been freed explicitly, and native FMU
    # libraries have been seen to corrupt the heap when collected during finalisation
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
