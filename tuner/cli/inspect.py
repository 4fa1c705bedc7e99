"""``python -m tuner inspect FILES``: what the reader understands of rig files."""
from __future__ import annotations

import json
from pathlib import Path

from tuner.cli.folders import DEFAULT_DATASET
from tuner.cli.options import add_data_options, fit_rate_and_band, load_tests
from tuner.data.summary import summarize

__all__ = ["add_parser", "cmd_inspect"]


def add_parser(sub) -> None:
    """Register ``inspect`` on an argparse subparsers object."""
    p = sub.add_parser("inspect", help="what the reader understands of rig files (columns, units, ranges)")
    p.add_argument("files", nargs="*", type=Path, metavar="FILE",
                   help="rig test files (delimited text, MTS 793 export, .mat, Parquet; FILE@SEL: steps of a test "
                        "programme)")
    p.add_argument("--dataset", type=Path, help="a dataset folder with manifest.json instead of files")
    p.add_argument("--json", action="store_true", help="also print the figures as JSON (SI units)")
    add_data_options(p.add_argument_group("data"))
    p.set_defaults(func=cmd_inspect)


def cmd_inspect(args) -> int:
    if args.files and args.dataset:
        raise ValueError("give either --dataset or FILES, not both")
    if not args.files and not args.dataset:
        args.dataset = DEFAULT_DATASET
    args.identification, args.validation = list(args.files), []
    ident, valid, _ = load_tests(args, file_role=None)
    if args.json:
        rate, band = fit_rate_and_band(args)
        print(json.dumps([summarize(t, rate, band) for t in ident + valid], indent=1))
    return 0
