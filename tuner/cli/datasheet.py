"""``python -m tuner datasheet --fmus FMU... --out DIR``: the damper's datasheet from its FMUs.

Each FMU is driven through fmpy by sine strokes, as a co-simulation master drives it (``tuner.datasheet``): the
force-velocity characteristic (the force at the peak velocities of settled sines, extension and compression) and
the dynamic characteristic (K', K'', |K*|, loss angle, equivalent Maxwell k and c, harmonic distortion, per
frequency and amplitude). Written into ``--out`` (default ``results/datasheet[-N]``): ``datasheet.json``, per FMU
``<FMU>_force_velocity.csv`` (with the series stiffness) and ``<FMU>_maxwell.csv``, and the figures. ``--out`` a fit
output folder: into its ``datasheet/`` sub-folder, and its report is rebuilt with the section "Datasheet".

``--tests FILE...``: rig tests; those that are sine tests give measured points (the same quantities from the
measured force at each test's frequency and amplitude), each beside every FMU's point there with its error.
``--nominal CSV --nominal-tolerance PCT``: a supplier's nominal characteristic; every force-velocity point, simulated
and measured, is marked inside or outside its band.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from campaign.cli import float_list
from tuner.cli.folders import DEFAULT_RESULTS, free_folder
from tuner.cli.options import add_data_options, column_options
from tuner.cli.vehicle import is_fit_folder
from tuner.datasheet.characteristic import (DEFAULT_AMPLITUDES, DEFAULT_FREQUENCIES, DEFAULT_FV_AMPLITUDE,
                                            DEFAULT_PEAK_VELOCITIES, DatasheetSettings)
from tuner.datasheet.sheet import (DATASHEET_FILE, DATASHEET_FOLDER, format_datasheet_table, make_datasheet,
                                   write_datasheet)
from tuner.datasheet.nominal import read_nominal
from tuner.datasheet.sine_runs import SineSettings
from tuner.data.reading import load_files
from tuner.results.datasheet_figures import draw_datasheet_figures
from tuner.results.report import make_report

__all__ = ["add_parser", "cmd_datasheet", "datasheet_settings", "read_tests"]


def _numbers(values) -> str:
    return ",".join(f"{v:g}" for v in values)


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the ``datasheet`` sub-command on an argparse subparsers object (func=cmd_datasheet)."""
    p = subparsers.add_parser("datasheet", help="the damper's datasheet (force-velocity, dynamic stiffness) from FMUs",
                              description=__doc__.split("\n\n")[0])
    p.add_argument("--fmus", nargs="+", type=Path, required=True, metavar="FMU",
                   help="damper FMUs (inputs stroke [m], stroke_velocity [m/s], output force [N]), e.g. "
                        "results/default/fmu/*_tuned.fmu")
    p.add_argument("--out", type=Path, default=None,
                   help="output folder (default results/datasheet[-N]); a fit output folder: its datasheet/ "
                        "sub-folder, and its report is rebuilt")
    p.add_argument("--velocities", type=float_list, default=list(DEFAULT_PEAK_VELOCITIES), metavar="V,V,...",
                   help=f"peak velocities of the force-velocity sines [m/s], each in extension and compression "
                        f"(default {_numbers(DEFAULT_PEAK_VELOCITIES)})")
    p.add_argument("--fv-amplitude", type=float, default=DEFAULT_FV_AMPLITUDE * 1e3, metavar="MM",
                   help=f"stroke amplitude of the force-velocity sines [mm] (default {DEFAULT_FV_AMPLITUDE * 1e3:g})")
    p.add_argument("--frequencies", type=float_list, default=list(DEFAULT_FREQUENCIES), metavar="F,F,...",
                   help=f"frequencies of the dynamic characteristic [Hz] (default {_numbers(DEFAULT_FREQUENCIES)})")
    p.add_argument("--amplitudes", type=float_list, default=[a * 1e3 for a in DEFAULT_AMPLITUDES], metavar="MM,...",
                   help=f"stroke amplitudes of the dynamic characteristic [mm] "
                        f"(default {_numbers(a * 1e3 for a in DEFAULT_AMPLITUDES)})")
    p.add_argument("--max-step", type=float, default=SineSettings().max_step_s * 1e3, metavar="MS",
                   help="largest communication step [ms] (default 1; at least 200 steps per period)")
    p.add_argument("--tests", nargs="+", type=Path, default=[], metavar="FILE",
                   help="rig test files: the sine tests among them give measured points beside the FMUs' (read with "
                        "the data options below, e.g. --columns docs/real-data/mr-sine.toml)")
    p.add_argument("--nominal", type=Path, default=None, metavar="CSV",
                   help="a nominal force-velocity characteristic (header row; velocity and force columns with their "
                        "units, e.g. 'velocity [m/s],force [kN]'; compression negative): every simulated and measured "
                        "point is marked inside or outside its band")
    p.add_argument("--nominal-tolerance", type=float, default=None, metavar="PCT",
                   help="--nominal: the band's half width [%% of the nominal force] (or a 'tolerance' column in "
                        "the CSV)")
    p.add_argument("--no-report", action="store_true", help="--out a fit output folder: do not rebuild its report")
    p.add_argument("--quiet", action="store_true", help="print only the table")
    add_data_options(p.add_argument_group("data (how --tests are read)"))
    p.set_defaults(func=cmd_datasheet)
    return p


def datasheet_settings(args) -> DatasheetSettings:
    """The settings of the command's options (SI units; ValueError naming the option that cannot be used)."""
    if not 0 < args.max_step <= 10:
        raise ValueError(f"--max-step must be in (0, 10] ms, got {args.max_step:g}")
    settings = DatasheetSettings(peak_velocities_m_s=tuple(args.velocities), fv_amplitude_m=args.fv_amplitude * 1e-3,
                                 frequencies_hz=tuple(args.frequencies),
                                 amplitudes_m=tuple(a * 1e-3 for a in args.amplitudes),
                                 sine=SineSettings(max_step_s=args.max_step * 1e-3))
    settings.check()
    return settings


def read_tests(args) -> list:
    """The rig tests of ``--tests``, each read with its options (``--columns`` and the data options)."""
    common, per_file = column_options(args)
    return [t for p in args.tests for t in load_files([p], "identification", per_file.get(Path(p).name, common))]


def cmd_datasheet(args) -> int:
    settings = datasheet_settings(args)
    if args.nominal_tolerance is not None and args.nominal is None:
        raise ValueError("--nominal-tolerance needs --nominal CSV")
    nominal = read_nominal(args.nominal, args.nominal_tolerance) if args.nominal is not None else None
    tests = read_tests(args)
    out = args.out if args.out is not None else free_folder(DEFAULT_RESULTS / "datasheet")
    run = out if is_fit_folder(out) else None
    if run is not None:
        out = run / DATASHEET_FOLDER
    log = (lambda line: None) if args.quiet else (lambda line: print(line, flush=True))
    sheet = make_datasheet(args.fmus, settings, tests=tests, nominal=nominal, log=log)
    write_datasheet(sheet, out)
    rebuild = run is not None and not args.no_report
    if not rebuild:  # a fit folder's report draws them
        draw_datasheet_figures(sheet.to_dict(), out)
    print(format_datasheet_table(sheet.to_dict()), flush=True)
    print(f"written: {out / DATASHEET_FILE}, the CSV tables and figures in {out} ({sheet.seconds:.1f} s of sines)",
          flush=True)
    if rebuild:
        print(f"report with the datasheet section: {make_report(run)}", flush=True)
    return 0
