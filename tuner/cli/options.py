"""The command line's data and fit options, and the one mapping of them to settings (``fit_settings``),
to the reader's options (``column_options``: ``ReadOptions`` records) and to tests read (``load_tests``)."""
from __future__ import annotations

import argparse
import math
from pathlib import Path

from campaign.cli import float_list  # the one argparse type for number lists
from tuner.cli.log import log
from tuner.data.read_options import COLUMN_OPTIONS, DEFAULT_DAMPER_CLASS, ReadOptions, read_column_mapping
from tuner.data import units
from tuner.data.programme import split_selection
from tuner.data.reading import load_dataset, load_files
from tuner.data.summary import filter_warning, summarize, summary_text
from tuner.executors import parse_scheduler
from tuner.identification.fit import FitSettings
from tuner.identification.problem import DataSettings
from tuner.vehicle.propagation import INTERVALS_FOR, PropagationSettings

__all__ = ["add_data_options", "add_fit_options", "column_options", "fit_settings", "load_tests", "fit_rate_and_band",
           "vehicle_scheduler", "DATA_OPTIONS"]


def add_data_options(g) -> None:
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
    g.add_argument("--stroke-unit", default=None, choices=list(units.STROKE),
                   help="unit of the stroke (default: as the header or units row declares, else m); in and ft "
                        "exactly (0.0254 m/in)")
    g.add_argument("--force-unit", default=None, choices=list(units.FORCE),
                   help="unit of the force (default: as the header or units row declares, else N); lbf and kip "
                        "exactly (4.4482216152605 N/lbf)")
    g.add_argument("--velocity-unit", default=None, choices=list(units.VELOCITY))
    g.add_argument("--temperature-unit", default=None, choices=["degC", "K"])
    g.add_argument("--stroke-sign", type=int, default=None, choices=[1, -1],
                   help="-1 if the rig writes compression as positive stroke (ours: extension positive)")
    g.add_argument("--force-sign", type=int, default=None, choices=[1, -1],
                   help="-1 if the rig writes compression as positive force (ours: tension positive)")
    g.add_argument("--rate", type=float, default=None, metavar="HZ", help="sample rate of files without time")
    g.add_argument("--t-start", type=float, default=None, metavar="S",
                   help="use the test from this time [s from its first sample]")
    g.add_argument("--t-end", type=float, default=None, metavar="S", help="... up to this time [s]")
    g.add_argument("--header-line", type=int, default=None, metavar="N",
                   help="1-based line number of the column names (default: detected, after any preamble of "
                        "metadata lines such as a data logger's 'Sampling Rate:  1000')")
    g.add_argument("--date-order", default=None, choices=["mdy", "dmy"],
                   help="day-month order of date-time stamps with the year last: mdy (05/25/2022) or dmy "
                        "(25.05.2022); default: from the data, refused when every stamp fits both and it matters")
    g.add_argument("--stroke-scale", type=float, default=None, metavar="K",
                   help="calibration: stroke = K x raw + B in the unit of --stroke-unit (K > 0; 10 for a 10 mm/V "
                        "transducer with --stroke-unit mm); the unit the column declares is then the raw one")
    g.add_argument("--stroke-offset", type=float, default=None, metavar="B",
                   help="calibration offset B [--stroke-unit] (default 0)")
    g.add_argument("--force-scale", type=float, default=None, metavar="K",
                   help="calibration: force = K x raw + B in the unit of --force-unit (K > 0; 980.665 for a "
                        "980.665 N/V load cell with --force-unit N)")
    g.add_argument("--force-offset", type=float, default=None, metavar="B",
                   help="calibration offset B [--force-unit] (default 0)")
    g.add_argument("--velocity-scale", type=float, default=None, metavar="K",
                   help="calibration of --velocity-col: velocity = K x raw + B in the unit of --velocity-unit")
    g.add_argument("--velocity-offset", type=float, default=None, metavar="B",
                   help="calibration offset B [--velocity-unit] (default 0)")
    g.add_argument("--force-zero", type=float, default=None, metavar="S",
                   help="tare: remove the mean force over the first S seconds of each test (the damper at rest: "
                        "refused if the stroke moves more than 5 %% of its range meanwhile)")
    g.add_argument("--prefilter", default=None, metavar="SPEC",
                   help="the filter the lab applied to its channels before writing the file, applied to the "
                        "simulated force before every comparison: 'moving-average:T' (T in s, causal), "
                        "'butterworth:N:FC' (order, cut-off in Hz, causal), either with ':zero-phase', or 'none' "
                        "(default); per file in a --columns file (key prefilter)")
    g.add_argument("--programme", action="store_true",
                   help="a test programme in one file (a stepped sine): cut each file into one test per step of "
                        "frequency or amplitude (transitions and settling cycles left out); FILE@SEL reads some "
                        "steps of one file: FILE@2, FILE@1,3, FILE@1Hz, FILE@10mm, FILE@1Hz:10mm (--columns key "
                        "programme = true)")
    g.add_argument("--columns", type=Path, default=None, metavar="FILE",
                   help="column mapping file (TOML or JSON) for campaigns with many files: the options above "
                        "as keys (time_col, stroke_unit, force_sign, header_line, force_scale ...), for every file "
                        "and per file name")
    g.add_argument("--accept-implausible", action="store_true",
                   help="read data that fails the physical plausibility checks (units) as declared")
    g.add_argument("--damper-class", default=None, choices=["yaw", "primary", "secondary", "any"],
                   help="the kind of railway damper tested (default yaw): a test whose apparent damping is "
                        "outside that class's range is read with a warning (a force in kN read as N)")


#: the reader's options (``ReadOptions`` fields) that have an option of the same name (``--time-col`` ...):
#: those of a mapping file but ``rate_hz`` (``--rate``) and ``check_plausible`` (``--accept-implausible``)
DATA_OPTIONS = tuple(k for k in COLUMN_OPTIONS if k not in ("rate_hz", "check_plausible", "programme"))


def column_options(args) -> tuple[ReadOptions, dict[str, ReadOptions]]:
    """The reader's options (``ReadOptions``) from the ``--columns`` mapping file and the command line: (those
    of every file, file name -> that file's own). Each is the defaults, then the mapping file's ``[columns]``,
    then its entry for the file, then the command line's options given: the command line wins."""
    common, per_file = read_column_mapping(args.columns) if args.columns else ({}, {})
    given = {k: getattr(args, k) for k in DATA_OPTIONS if getattr(args, k) is not None}
    if given.get("time_col", "").lower() == "none":
        given["time_col"] = None
    if args.rate is not None:
        given["rate_hz"] = args.rate
    if args.accept_implausible:
        given["check_plausible"] = False
    if getattr(args, "programme", False):
        given["programme"] = True
    every = ReadOptions().merged(common)
    return every.merged(given), {name: every.merged(opts).merged(given) for name, opts in per_file.items()}


def add_fit_options(ap: argparse.ArgumentParser) -> None:
    d = FitSettings()
    g = ap.add_argument_group("data")
    g.add_argument("--dataset", type=Path, help="dataset folder with manifest.json (roles from the manifest)")
    g.add_argument("--identification", nargs="+", type=Path, default=[], metavar="FILE",
                   help="identification test files (delimited text, MTS 793 export, .mat, Parquet; FILE@SEL: "
                        "steps of a test programme, see --programme)")
    g.add_argument("--validation", nargs="+", type=Path, default=[], metavar="FILE",
                   help="validation test files (held out; FILE@SEL as for --identification)")
    add_data_options(g)
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
    g.add_argument("--parametrization", default=d.data.parametrization, choices=["improved", "paper"])
    g.add_argument("--init", default=d.init, choices=["seeded", "random"],
                   help="seeded: data-driven guess and preset in the first population (default)")
    g.add_argument("--fit-rate", type=float, default=d.data.fit_rate_hz, help="resample to this rate [Hz]")
    g.add_argument("--warmup", type=float, default=d.data.warmup_s, help="seconds skipped at each test start")
    g.add_argument("--sim-step", type=float, default=1e3 * d.data.sim_step_s, metavar="MS",
                   help="grid and fixed sub-step [ms] the model is simulated on while fitting (default %(default)g); "
                        "0.25 or 0.1 where a free play closes on stiff silent blocks (2-5 x the time): 1 ms integrates "
                        "that impact to tens of newtons, which biases small causes beside it")
    g.add_argument("--diff-band", type=float, default=d.data.diff_band_hz, metavar="HZ",
                   help="band up to which the stroke differentiator is accurate to 0.5 %% (default: per test, where "
                        "99 %% of the stroke velocity's power lies, 20 Hz at least; ignored with --velocity-col)")
    g.add_argument("--force-limit", type=float, default=None,
                   help="Fc,O ordinate limit [N] (default: 1.5 x peak measured force)")
    g.add_argument("--damping-abscissae", type=float_list, default=None, metavar="V1,...,V14",
                   help="the 14 rates [mm/s] of the Fc,O table, increasing (default: Table 2's, stretched to the "
                        "data's peak velocity when it exceeds 150 mm/s)")
    g.add_argument("--elastic-abscissae", type=float_list, default=None, metavar="X1,...,X10",
                   help="the 10 elongations [mm] of the Fk,O table, increasing (default: Table 2's, stretched when "
                        "the peak force would elongate the reference spring beyond 3 mm)")
    g.add_argument("--no-stop", action="store_true", help="disable the search's stopping rules (the paper's stagnation test and the data-resolution "
                        "stop): the whole --iterations budget")
    g.add_argument("--no-diagnose", action="store_true",
                   help="skip the diagnosis that follows the fit (it needs validation tests)")
    g.add_argument("--vehicle", action="store_true",
                   help="yaw dampers: run the tuned FMUs as the yaw dampers of the campaign's vehicle (critical "
                        "speed, curve entry, straight track; about 25 s; with --vehicle-draws their 95 %% intervals, about a "
                        "minute more) and add the section to the report "
                        "(on in the default run)")
    g.add_argument("--no-datasheet", action="store_true",
                   help="skip the datasheet of the tuned FMUs (force-velocity and dynamic stiffness from sine strokes, "
                        "about 1 s per FMU)")
    g.add_argument("--vehicle-draws", type=int, default=PropagationSettings().draws, metavar="N",
                   help="with --vehicle: 95 %% intervals of the critical speed and the curve's peak damper force "
                        "from up to N parameter sets per tuned FMU drawn from the fitted covariance, fewer once "
                        "the Monte-Carlo error is below 2 km/h and 1 %% (default %(default)s; 0: no intervals)")
    g.add_argument("--vehicle-intervals", choices=INTERVALS_FOR, default=INTERVALS_FOR[0],
                   help="with --vehicle-draws: the intervals for the recommended model's FMU only (default) or for "
                        "every tuned FMU (about 25 s more in the default run)")
    g.add_argument("--vehicle-scheduler", default=None, metavar="SPEC",
                   help="where the draws run: pool:N (local processes), local:N (Dask LocalCluster), a Dask "
                        "scheduler address tcp://HOST:PORT, or 'here' (this process); default a pool of "
                        "--workers processes")
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
    g.add_argument("--no-figures", action="store_true",
                   help="the report without the fit's figures (tables and verdicts; about 5 s less on the bundled "
                        "data); python -m tuner report OUT draws them")
    g.add_argument("--quiet", action="store_true", help="no progress and no log lines; only the final summary")


def positive_step(ms: float) -> float:
    """``--sim-step`` [ms] as seconds; a clear error for a step that is not a positive number."""
    if not (ms > 0.0 and math.isfinite(ms)):
        raise SystemExit(f"--sim-step {ms:g}: the simulation step must be a positive number of milliseconds, "
                         "e.g. --sim-step 0.25")
    return 1e-3 * ms


def fit_settings(args, models: tuple | None = None) -> "object":
    """The one mapping of the command line's options to ``FitSettings`` (SI units: the abscissae are
    given in mm and mm/s); ``models``: the checked --models (default the settings' own)."""
    data = DataSettings(fit_rate_hz=args.fit_rate, warmup_s=args.warmup, diff_band_hz=args.diff_band,
                        damping_abscissae_m_s=None if args.damping_abscissae is None else
                        tuple(1e-3 * v for v in args.damping_abscissae),
                        elastic_abscissae_m=None if args.elastic_abscissae is None else
                        tuple(1e-3 * x for x in args.elastic_abscissae),
                        force_limit_n=args.force_limit, parametrization=args.parametrization,
                        sim_step_s=positive_step(args.sim_step))
    return FitSettings(models=models or FitSettings().models, data=data,
                       population=args.population, iterations=args.iterations, workers=args.workers,
                       seed=args.seed, engine=args.engine, init=args.init,
                       stop_tol=None if args.no_stop else 1e-3, polish_jacobians=args.polish)


def vehicle_scheduler(args) -> str | None:
    """Where the vehicle's draws run (``tuner.executors.parse_scheduler``'s spec, None: in this process)
    from --vehicle-scheduler and --workers; ValueError naming the option for a bad value."""
    if getattr(args, "vehicle_draws", 0) < 0 or getattr(args, "vehicle_draws", 0) == 1:
        raise ValueError(f"--vehicle-draws must be 0 (no intervals) or at least 2, got {args.vehicle_draws}")
    spec = getattr(args, "vehicle_scheduler", None)
    if spec == "here":
        return None
    if spec is None:
        return f"pool:{args.workers}" if args.workers > 1 else None
    try:
        parse_scheduler(spec)
    except ValueError as err:
        raise ValueError(str(err).replace("--scheduler", "--vehicle-scheduler")) from None
    return spec


def load_tests(args, file_role: str | None = "identification"):
    """(identification tests, validation tests, name) from --dataset or the files; ``file_role``: the
    role of --identification files (None for ``inspect``, which only reads them)."""
    common, per_file = column_options(args)

    def read(paths, role):
        out = []
        for p in paths:
            file, steps = (str(p), None) if Path(p).exists() else split_selection(str(p))
            opts = per_file.get(Path(file).name, common)
            out += load_files([Path(file)], role, opts if steps is None else opts.merged(steps=steps))
        return out

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
    rate, band = fit_rate_and_band(args)
    if not getattr(args, "json", False):  # inspect --json: the JSON alone on stdout
        log("data as read:")
        for t in ident + valid:
            s = summarize(t, rate, band)
            log(summary_text(s))
            note = filter_warning(s)
            if note:  # a warning of the reading, kept with the reader's own: the job's end repeats them
                t.metadata["warnings"] = [*t.metadata.get("warnings", []), note]
    names = [t.name for t in ident + valid]
    if len(set(names)) != len(names):
        raise ValueError(f"test names must be unique, got {names}")
    return ident, valid, name


def fit_rate_and_band(args) -> tuple[float, float | None]:
    """Fit rate [Hz] and differentiator band [Hz] (None: from the data) the command will use."""
    return getattr(args, "fit_rate", None) or DataSettings().fit_rate_hz, getattr(args, "diff_band", None)
