"""``python -m tuner vehicle --fmus PATH [PATH ...]``: the vehicle with each damper FMU, side by side.

Runs the scenarios of :mod:`tuner.vehicle.compare` (hunting critical speed, a curve entry, a straight track
with irregularities) with four copies of each FMU as the vehicle's yaw dampers, prints critical speed,
peak and RMS yaw damper force, carbody lateral acceleration and bogie yaw per FMU, and writes
``vehicle.json`` and one figure per scenario into ``--out`` (default ``results/vehicle``, or the first
free ``results/vehicle-N``).

With ``--nonlinear``: hunting with nonlinear wheel-rail contact instead (:mod:`tuner.vehicle.limit_cycles`):
per FMU and equivalent conicity the linear and nonlinear critical speeds, the bifurcation diagrams
(``hunting_bifurcation.png``), the critical speed against conicity (``critical_speed_conicity.png``) and
``hunting_nonlinear.json``.

With ``--cooperrider``: the FMUs as the yaw dampers of DTU's Cooperrider car on S1002/UIC60 contact instead
(:mod:`tuner.vehicle.cooperrider_hunting`): the linear critical speed per FMU beside the car's own dashpots,
``cooperrider.json``. The car's parameters and contact table are the DTU simulator DYTSI's published input,
read at run time and not part of the project (``--cooperrider-input``, default
``$DYTSI_REFERENCE`` or ``../shared/reference/dytsi`` beside the repository).

``--out`` a fit output folder (``results/RUN``, with its parameters.json and metrics.json): the files go to its
``vehicle/`` sub-folder and its report is rebuilt with them in the section "In the vehicle" (``--no-report``:
not rebuilt).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from campaign.cooperrider_params import STRAIGHT_INPUT, reference_input
from tuner.cli.folders import DEFAULT_RESULTS, free_folder
from tuner.cli.summary import update_cooperrider_summary
from tuner.progress import JobProgress
from campaign.bifurcation import RampSettings
from tuner.results.report import make_report
from tuner.vehicle.compare import SCENARIO_NAMES, VEHICLE_FOLDER, ScenarioOptions, compare_fmus, format_table
from tuner.vehicle.cooperrider_hunting import (COOPERRIDER_FILE, CooperriderSearch, cooperrider_study,
                                               format_cooperrider_table)
from tuner.vehicle.limit_cycles import (CONICITY_FIGURE, DEFAULT_CONICITIES, DIAGRAM_FIGURE, STUDY_FILE, HuntingStudy,
                                        format_study_table, hunting_study)

__all__ = ["add_parser", "cmd_vehicle", "is_fit_folder"]


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the ``vehicle`` sub-command on an argparse subparsers object (func=cmd_vehicle)."""
    p = subparsers.add_parser("vehicle", help="the damper FMUs in a vehicle: critical speed, curve, ride",
                              description=__doc__.split("\n\n")[0])
    p.add_argument("--fmus", nargs="+", type=Path, required=True, metavar="PATH",
                   help="damper FMUs (inputs stroke [m], stroke_velocity [m/s], output force [N]), e.g. "
                        "results/default/fmu/*.fmu")
    p.add_argument("--out", type=Path, default=None,
                   help="output folder (default results/vehicle[-N]); a fit output folder: its vehicle/ sub-folder, "
                        "and its report is rebuilt")
    p.add_argument("--no-report", action="store_true", help="--out a fit output folder: do not rebuild its report")
    p.add_argument("--scenarios", nargs="+", choices=SCENARIO_NAMES, default=list(SCENARIO_NAMES))
    p.add_argument("--step", type=float, default=None,
                   help="communication step [s] (default 0.001; --cooperrider 0.0005)")
    p.add_argument("--seed", type=int, default=0, help="master seed of the track irregularities (default 0)")
    p.add_argument("--v-min", type=float, default=None,
                   help="critical speed search from [km/h] (default 100; --cooperrider 108)")
    p.add_argument("--v-max", type=float, default=None, help="... up to [km/h] (default 1000; --cooperrider 900)")
    p.add_argument("--tol", type=float, default=1.0, help="critical speed tolerance [km/h] (default 1)")
    p.add_argument("--kick", type=float, default=3.0, help="lateral kick of wheelsets and bogies [mm] (default 3)")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.add_argument("--nonlinear", action="store_true",
                   help="hunting with nonlinear contact (saturating creep, flange) instead of the scenarios: "
                        "bifurcation diagrams, linear and nonlinear critical speed against conicity")
    p.add_argument("--conicities", nargs="+", type=float, default=list(DEFAULT_CONICITIES), metavar="LAMBDA",
                   help="--nonlinear: equivalent conicities of the sweep (default 0.05 0.15 0.25 0.35 0.45)")
    p.add_argument("--diagram-conicity", type=float, default=0.25,
                   help="--nonlinear: conicity of the bifurcation diagrams (default 0.25)")
    p.add_argument("--dv", type=float, default=20.0, help="--nonlinear: speed step of the ramp-down [km/h] (default 20)")
    p.add_argument("--workers", type=int, default=2, help="--nonlinear: processes (default 2)")
    p.add_argument("--cooperrider", action="store_true",
                   help="the FMUs as the yaw dampers of DTU's Cooperrider car on S1002/UIC60 contact instead: linear "
                        "critical speed per FMU beside the car's own dashpots (about 5-7 min per FMU; --cycle-time 0: 1-2 min)")
    p.add_argument("--cooperrider-input", type=Path, default=None, metavar="XML",
                   help=f"--cooperrider: the DTU simulator DYTSI's input file with the car (default {STRAIGHT_INPUT} "
                        "in $DYTSI_REFERENCE or ../shared/reference/dytsi beside the repository)")
    p.add_argument("--cycle-time", type=float, default=CooperriderSearch().cycle_time, metavar="S",
                   help="--cooperrider: run time [s] at 1.05 x each critical speed for the limit cycle's amplitude "
                        "(default 120; 0: no cycle)")
    p.add_argument("--contact-table", type=Path, default=None, metavar="RSGEO",
                   help="--cooperrider: the contact table (default: the RSGEO file the input file names)")
    p.set_defaults(func=cmd_vehicle)
    return p


def cmd_vehicle(args) -> int:
    _speed_defaults(args)
    if not (0 < args.v_min < args.v_max) or not args.tol > 0 or not args.kick > 0 or not 0 < args.step <= 0.01:
        raise ValueError("need 0 < --v-min < --v-max, --tol > 0, --kick > 0 and 0 < --step <= 0.01")
    for f in args.fmus:
        if not f.is_file():
            raise FileNotFoundError(f"damper FMU not found: {f}")
    out = args.out if args.out is not None else free_folder(DEFAULT_RESULTS / "vehicle")
    run = out if is_fit_folder(out) else None
    if run is not None:
        out = run / VEHICLE_FOLDER
    if args.nonlinear and args.cooperrider:
        raise ValueError("choose one of --nonlinear and --cooperrider")
    code = (_nonlinear(args, out) if args.nonlinear else _cooperrider(args, out) if args.cooperrider
            else _scenarios(args, out))
    if run is not None and args.cooperrider and update_cooperrider_summary(run):
        print(f"critical speeds on the Cooperrider car in {run / 'summary.json'} ('cooperrider')", flush=True)
    if run is not None and not args.no_report:
        print(f"report with the vehicle section: {make_report(run)}", flush=True)
    return code


def _speed_defaults(args) -> None:
    """--step, --v-min and --v-max not given: the defaults of the chosen study (module docstring)."""
    coop = getattr(args, "cooperrider", False)
    search = CooperriderSearch()
    if args.step is None:
        args.step = search.step if coop else 1e-3
    if args.v_min is None:
        args.v_min = search.v_min * 3.6 if coop else 100.0
    if args.v_max is None:
        args.v_max = search.v_max * 3.6 if coop else 1000.0


def is_fit_folder(folder: Path) -> bool:
    """``folder`` is a fit output folder (its report reads parameters.json and metrics.json)."""
    return (Path(folder) / "parameters.json").is_file() and (Path(folder) / "metrics.json").is_file()


def _scenarios(args, out: Path) -> int:
    weights = {f"{Path(f).stem}: {s}": (6.0 if s == "critical_speed" else 1.0) for f in args.fmus for s in args.scenarios}
    log = JobProgress(weights, quiet=args.quiet)
    try:
        data = compare_fmus(args.fmus, out, options=ScenarioOptions(
            scenarios=tuple(args.scenarios), step=args.step, seed=args.seed, v_min=args.v_min / 3.6,
            v_max=args.v_max / 3.6, tol=args.tol / 3.6, kick=args.kick * 1e-3), log=log)
    finally:
        log.finish()
    print(format_table(data), flush=True)
    print(f"written: {out / 'vehicle.json'} and one figure per scenario in {out}", flush=True)
    return 0


def _nonlinear(args, out: Path) -> int:
    if not (args.dv > 0 and args.workers >= 1):
        raise ValueError("need --dv > 0 and --workers >= 1")
    study = HuntingStudy(conicities=tuple(args.conicities), diagram_conicity=args.diagram_conicity,
                         v_min=args.v_min / 3.6, v_max=args.v_max / 3.6, tol=args.tol / 3.6,
                         ramp=RampSettings(dv=args.dv / 3.6, tol=args.tol / 3.6), step=args.step,
                         workers=args.workers)
    log = (lambda line: None) if args.quiet else (lambda line: print(line, flush=True))
    data = hunting_study(args.fmus, out, study, log=log)
    print(format_study_table(data), flush=True)
    print(f"written: {out / STUDY_FILE}, {out / DIAGRAM_FIGURE} and {out / CONICITY_FIGURE}", flush=True)
    return 0


def _cooperrider(args, out: Path) -> int:
    xml = args.cooperrider_input if args.cooperrider_input is not None else reference_input()
    if not xml.is_file():
        raise FileNotFoundError(
            f"Cooperrider car: the DTU simulator DYTSI's input file {xml} is not there. It is not part of the project; "
            f"give its path with --cooperrider-input (the {STRAIGHT_INPUT} of a DYTSI copy) or set DYTSI_REFERENCE "
            "to the dytsi/ folder of the reference engines")
    if args.contact_table is not None and not args.contact_table.is_file():
        raise FileNotFoundError(f"Cooperrider car: contact table {args.contact_table} (--contact-table) not found")
    search = CooperriderSearch(v_min=args.v_min / 3.6, v_max=args.v_max / 3.6, step=args.step,
                               cycle_time=args.cycle_time)
    log = (lambda line: None) if args.quiet else (lambda line: print(line, flush=True))
    data = cooperrider_study(args.fmus, out, xml, search, table_path=args.contact_table, log=log)
    print(format_cooperrider_table(data), flush=True)
    print(f"written: {out / COOPERRIDER_FILE}", flush=True)
    return 0
