"""``python -m tuner design --from results/RUN``: the rig tests that would pin down what the identification
tests leave open.

Ranks candidate rig tests (sines, small-amplitude high-frequency sines, sweeps, steps within the rig's
stroke, velocity and force limits, and the identification tests run again) by how much they are expected
to shrink the 95 % intervals of the parameters each fitted model leaves not determined
(``tuner.identification.rig_test_design``), and writes the best as a dataset ready for the rig (one CSV per
test, ``damper-rig-dataset/1``; the force column holds the fitted model's prediction) with ``design.json``
(every candidate's expected gain) into ``--out`` (default ``RUN/design``; then the run's report is rebuilt
with the section "The tests that would pin down the rest").
"""
from __future__ import annotations

import argparse
from pathlib import Path

from tuner import strict_json
from tuner.identification.rig_test_design import DESIGN_FOLDER, RigLimits, design_from_folder
from tuner.progress import JobProgress
from tuner.results.report import make_report

__all__ = ["add_parser", "cmd_design"]


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the ``design`` sub-command on an argparse subparsers object (func=cmd_design)."""
    p = subparsers.add_parser("design", help="the rig tests that would pin down the parameters not determined",
                              description=__doc__.split("\n\n")[0])
    p.add_argument("--from", dest="folder", type=Path, required=True, metavar="RUN",
                   help="output folder of a fit (parameters.json with intervals, metrics.json, simulations.npz)")
    p.add_argument("--out", type=Path, default=None, help="output folder (default RUN/design)")
    p.add_argument("--top", type=int, default=3, help="tests written per model (default 3)")
    p.add_argument("--duration", type=float, default=10.0, help="length of each candidate test [s] (default 10)")
    p.add_argument("--rate", type=float, default=1000.0, help="sample rate of the stroke files [Hz] (default 1000)")
    p.add_argument("--models", default=None, help="comma-separated models to design for (default: every fitted one)")
    p.add_argument("--stroke-limit", type=float, default=None, metavar="MM",
                   help="the rig's largest |stroke| [mm] (default: what the identification tests reached)")
    p.add_argument("--velocity-limit", type=float, default=None, metavar="MM_S",
                   help="the rig's largest |stroke velocity| [mm/s] (default: the identification tests')")
    p.add_argument("--force-limit", type=float, default=None, metavar="N",
                   help="the rig's largest |force| [N] (default: the identification tests')")
    p.add_argument("--quiet", action="store_true", help="no progress display")
    p.add_argument("--no-report", action="store_true", help="do not rebuild RUN/report.html with the design's section")
    p.set_defaults(func=cmd_design)
    return p


def cmd_design(args) -> int:
    if args.top < 1 or not args.duration > 2.0 or not args.rate >= 50.0:
        raise ValueError("need --top >= 1, --duration > 2 s (the first second eases in) and --rate >= 50 Hz")
    given = [args.stroke_limit, args.velocity_limit, args.force_limit]
    limits = None
    if any(v is not None for v in given):
        if any(v is None for v in given):
            raise ValueError("give all three rig limits (--stroke-limit, --velocity-limit, --force-limit) or none")
        limits = RigLimits(args.stroke_limit * 1e-3, args.velocity_limit * 1e-3, args.force_limit)
        limits.check()
    models = [m.strip() for m in args.models.split(",")] if args.models else None
    pj = args.folder / "parameters.json"
    if not pj.is_file():
        raise FileNotFoundError(f"--from {args.folder}: no parameters.json (not a fit output folder)")
    fitted = [m for m in strict_json.loads(pj.read_text()) if not models or m in models]
    log = JobProgress({f"design {m}": 1.0 for m in fitted} or {"design": 1.0}, quiet=args.quiet)
    try:
        data = design_from_folder(args.folder, args.out, limits=limits, top=args.top, duration=args.duration,
                                  rate=args.rate, models=models, log=log)
    finally:
        log.finish()
    out = args.out or args.folder / DESIGN_FOLDER
    for model, d in data["models"].items():
        print(f"{model}: not determined {', '.join(d['targets'])}; best tests: {', '.join(d['written'])}")
    print(f"written: {out} (stroke files and manifest.json, design.json)", flush=True)
    if (not args.no_report and Path(out).resolve() == (args.folder / DESIGN_FOLDER).resolve()
            and (args.folder / "report.html").exists()):
        print(f"report with the design section: {make_report(args.folder)}", flush=True)
    return 0
