"""``python -m tuner batch MANIFEST``: fleet batch identification (also ``python -m tuner.cli.batch``);
the manifest format, executors and resume rules are in ``tuner.fleet``.

Exit status: 0 every row done, 1 some rows failed (see the summary), 2 bad manifest or options,
130 interrupted (rerun the same command to continue).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tuner.cli.folders import DEFAULT_RESULTS
from tuner.cli.run import run_handler
from tuner.fleet.batch import BatchOptions, run_batch
from tuner.fleet.manifest import convert_cell
from tuner.identification.fit import FitSettings
from tuner.results.fleet_summary import OUTLIER_K, OUTLIER_TOLERANCE

__all__ = ["add_parser", "cmd_batch", "main", "CONTINUE_HINT"]

#: how to continue an interrupted batch (finished rows are never redone)
CONTINUE_HINT = "run the same command again to continue (finished rows are kept)"


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the ``batch`` sub-command on an argparse subparsers object (func=cmd_batch)."""
    p = subparsers.add_parser("batch", help="identify a fleet: one fit per manifest row, fleet summary",
                              description=__doc__.split("\n\n")[0])
    _add_arguments(p)
    p.set_defaults(func=cmd_batch)
    return p


def _add_arguments(p: argparse.ArgumentParser) -> None:
    d = FitSettings()
    p.add_argument("manifest", type=Path, help="fleet manifest (CSV or TOML), one row per damper test session")
    p.add_argument("--out", type=Path, default=None,
                   help="results folder (default results/<manifest name>); rerunning continues it")
    p.add_argument("--scheduler", default=None, metavar="SPEC",
                   help="pool (default: local process pool of os.cpu_count() processes), pool:N, local:N (Dask "
                        "LocalCluster of N workers) or a Dask scheduler address tcp://HOST:PORT")
    p.add_argument("--diagnose", action="store_true", help="run the diagnosis after each fit (rows may say "
                   "diagnose = true/false)")
    p.add_argument("--no-row-figures", action="store_true",
                   help="each row's report without its figures (about 7 s less a row); python -m tuner report "
                        "OUT/ROW draws them")
    g = p.add_argument_group("fit settings where the manifest leaves them open")
    g.add_argument("--models", default=None, help=f"e.g. lumped,maxwell (default {','.join(d.models)})")
    g.add_argument("--population", type=int, default=None, help=f"fireflies (default {d.population})")
    g.add_argument("--iterations", type=int, default=None, help=f"max iterations (default {d.iterations})")
    g.add_argument("--polish", type=int, default=None, help=f"refinement cap in Jacobians (default {d.polish_jacobians})")
    g.add_argument("--seed", type=int, default=None, help=f"seed of every row without its own (default {d.seed})")
    g.add_argument("--engine", default=None, choices=["fmu", "native", "inprocess"])
    g.add_argument("--fit-rate", type=float, default=None, help=f"[Hz] (default {d.data.fit_rate_hz:g})")
    g.add_argument("--warmup", type=float, default=None, help=f"[s] (default {d.data.warmup_s:g})")
    g.add_argument("--row-workers", type=int, default=0,
                   help="evaluation processes inside each row (default 0: in the row's process)")
    g = p.add_argument_group("fleet summary")
    g.add_argument("--outlier-k", type=float, default=OUTLIER_K, help="k of the median +- k x 1.4826 MAD rule "
                   "(default %(default)s)")
    g.add_argument("--outlier-tolerance", type=float, default=OUTLIER_TOLERANCE,
                   help="smallest band as a fraction of |median| (default %(default)s)")


def cmd_batch(args) -> int:
    """Run the batch of ``args`` (the ``batch`` sub-command); 0 all done, 1 some rows failed."""
    settings = {}
    if args.models is not None:
        settings["models"] = convert_cell(args.models, "models", "--models", "models")
    for opt, name in (("population", "population"), ("iterations", "iterations"), ("polish", "polish_jacobians"),
                      ("seed", "seed"), ("engine", "engine"), ("fit_rate", "fit_rate_hz"), ("warmup", "warmup_s")):
        v = getattr(args, opt)
        if v is not None:
            settings[name] = v
    manifest = Path(args.manifest)
    out = args.out or DEFAULT_RESULTS / manifest.stem
    if args.outlier_k <= 0 or args.outlier_tolerance < 0:
        raise ValueError("--outlier-k must be > 0 and --outlier-tolerance >= 0")
    res = run_batch(manifest, out, options=BatchOptions(
        scheduler=args.scheduler, settings=settings, diagnose=args.diagnose, row_workers=args.row_workers,
        outlier_k=args.outlier_k, outlier_tolerance=args.outlier_tolerance, figures=not args.no_row_figures))
    failed = [r for r in res["rows"] if r["status"] == "failed"]
    for r in failed:
        print(f"failed: {r['id']}: {r['error']}", file=sys.stderr)
    return 1 if failed else 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tuner batch", description=__doc__.split("\n\n")[0])
    _add_arguments(ap)
    args = ap.parse_args(sys.argv[1:] if argv is None else list(argv))
    return run_handler(cmd_batch, args, CONTINUE_HINT)


if __name__ == "__main__":
    sys.exit(main())
