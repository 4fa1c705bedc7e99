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
    python -m tuner design --from RUN    the rig tests that would pin down the parameters not determined
    python -m tuner datasheet --fmus F... the damper's datasheet: force-velocity and dynamic stiffness (see --help)

Exit status: 0 success, 2 bad input or arguments (message on stderr), 130 interrupted.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from campaign.cli import add_generate_arguments, cmd_generate as generate_command
from tuner.cli import batch as batch_command, fit as fit_commands, inspect as inspect_command
from tuner.cli import datasheet as datasheet_command, design as design_command, vehicle as vehicle_command
from tuner.cli.folders import DEFAULT_DATASET
from tuner.cli.log import log
from tuner.cli.run import run_handler
from tuner.results.report import make_report

#: how to continue an interrupted fit or diagnosis
RESUME_HINT = "run again with --resume and the same --out to continue"


def cmd_generate(args) -> int:
    """The campaign's own command (``python -m campaign generate``), with the tuner's log."""
    return generate_command(args, log=log)


def cmd_report(args) -> int:
    log(f"report: {make_report(args.folder)}")
    return 0


def parser() -> argparse.ArgumentParser:
    """The command line: every sub-command's options come from its module in ``tuner.cli``."""
    ap = argparse.ArgumentParser(prog="python -m tuner", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="command")
    fit_commands.add_parsers(sub)
    p_gen = sub.add_parser("generate", help="virtual test campaign -> dataset folder (python -m campaign generate)")
    add_generate_arguments(p_gen)
    p_gen.set_defaults(func=cmd_generate)
    inspect_command.add_parser(sub)
    p_rep = sub.add_parser("report", help="rebuild the report of a fit output folder")
    p_rep.add_argument("folder", type=Path)
    p_rep.set_defaults(func=cmd_report)
    batch_command.add_parser(sub)
    vehicle_command.add_parser(sub)
    design_command.add_parser(sub)
    datasheet_command.add_parser(sub)
    return ap


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    ap = parser()
    if not argv:
        argv = ["fit", "--dataset", str(DEFAULT_DATASET), "--vehicle"]
    args = ap.parse_args(argv)
    if args.command is None:
        ap.print_help()
        return 2
    hint = batch_command.CONTINUE_HINT if args.command == "batch" else RESUME_HINT
    return run_handler(args.func, args, hint)


if __name__ == "__main__":
    sys.exit(main())
