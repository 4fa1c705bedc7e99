"""``python -m tuner vehicle --fmus PATH [PATH ...]``: the vehicle with each damper FMU, side by side.

Runs the scenarios of :mod:`tuner.vehicle.compare` (hunting critical speed, a curve entry, a straight track
with irregularities) with four copies of each FMU as the vehicle's yaw dampers, prints critical speed,
peak and RMS yaw damper force, carbody lateral acceleration and bogie yaw per FMU, and writes
``vehicle.json`` and one figure per scenario into ``--out`` (default ``results/vehicle``, or the first
free ``results/vehicle-N``).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from tuner.cli.folders import free_folder
from tuner.progress import JobProgress
from tuner.vehicle.compare import SCENARIO_NAMES, compare_fmus, format_table

__all__ = ["add_parser", "cmd_vehicle"]

ROOT = Path(__file__).resolve().parents[2]


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the ``vehicle`` sub-command on an argparse subparsers object (func=cmd_vehicle)."""
    p = subparsers.add_parser("vehicle", help="the damper FMUs in a vehicle: critical speed, curve, ride",
                              description=__doc__.split("\n\n")[0])
    p.add_argument("--fmus", nargs="+", type=Path, required=True, metavar="PATH",
                   help="damper FMUs (inputs stroke [m], stroke_velocity [m/s], output force [N]), e.g. "
                        "results/default/fmu/*.fmu")
    p.add_argument("--out", type=Path, default=None, help="output folder (default results/vehicle[-N])")
    p.add_argument("--scenarios", nargs="+", choices=SCENARIO_NAMES, default=list(SCENARIO_NAMES))
    p.add_argument("--step", type=float, default=1e-3, help="communication step [s] (default 0.001)")
    p.add_argument("--seed", type=int, default=0, help="master seed of the track irregularities (default 0)")
    p.add_argument("--v-min", type=float, default=100.0, help="critical speed search from [km/h] (default 100)")
    p.add_argument("--v-max", type=float, default=1000.0, help="... up to [km/h] (default 1000)")
    p.add_argument("--tol", type=float, default=1.0, help="critical speed tolerance [km/h] (default 1)")
    p.add_argument("--kick", type=float, default=3.0, help="lateral kick of wheelsets and bogies [mm] (default 3)")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.set_defaults(func=cmd_vehicle)
    return p


def cmd_vehicle(args) -> int:
    if not (0 < args.v_min < args.v_max) or not args.tol > 0 or not args.kick > 0 or not 0 < args.step <= 0.01:
        raise ValueError("need 0 < --v-min < --v-max, --tol > 0, --kick > 0 and 0 < --step <= 0.01")
    for f in args.fmus:
        if not f.is_file():
            raise FileNotFoundError(f"damper FMU not found: {f}")
    out = args.out if args.out is not None else free_folder(ROOT / "results" / "vehicle")
    weights = {f"{Path(f).stem}: {s}": (6.0 if s == "critical_speed" else 1.0) for f in args.fmus for s in args.scenarios}
    log = JobProgress(weights, quiet=args.quiet)
    try:
        data = compare_fmus(args.fmus, out, scenarios=args.scenarios, step=args.step, seed=args.seed,
                            v_min=args.v_min / 3.6, v_max=args.v_max / 3.6, tol=args.tol / 3.6,
                            kick=args.kick * 1e-3, log=log)
    finally:
        log.finish()
    print(format_table(data), flush=True)
    print(f"written: {out / 'vehicle.json'} and one figure per scenario in {out}", flush=True)
    return 0
