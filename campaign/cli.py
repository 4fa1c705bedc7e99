"""Command line of the virtual test campaign: ``python -m campaign generate --out DIR`` (also reachable as
``python -m tuner generate``): the six manoeuvres of the paper's Table 1 replayed on the virtual rig ->
a dataset folder in the ``damper_dataset`` format.

Exit status: 0 success, 2 bad input or arguments (message on stderr), 130 interrupted.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from campaign.effects import parse_effect
from campaign.generate import CampaignPlan, generate_dataset

__all__ = ["add_generate_arguments", "cmd_generate", "main", "float_list"]


def float_list(text: str) -> list[float]:
    """argparse type: comma-separated numbers ('1,2.5,3')."""
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None


def add_generate_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``generate`` (one definition for ``python -m campaign`` and ``python -m tuner``)."""
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--effect", action="append", metavar="NAME[=VALUE]",
                   help="switch on a hidden effect (repeatable), e.g. friction=150")
    p.add_argument("--seed", type=int, default=2023)
    p.add_argument("--sample-rate", type=float, default=1000.0, help="rig sample rate [Hz]")
    p.add_argument("--damper", choices=("twin-tube", "lumped"), default="twin-tube",
                   help="damper on the rig: the physical twin-tube (default) or one whose hydraulics are "
                        "the lumped model with the paper's Table 2 (no model-form error)")
    p.add_argument("--t-end", type=float, default=None, help="shorter manoeuvres: duration [s] of each")
    p.add_argument("--oil-temperatures", type=float_list, default=None, metavar="T1,T2,...",
                   help="oil temperature [degC] the damper is conditioned to before each test, one per "
                        "scenario in order (default 20 degC for all)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing dataset folder")


def cmd_generate(args, log=print) -> int:
    """Write the dataset that ``args`` (``add_generate_arguments``) describe; 0 on success."""
    effects = dict(parse_effect(spec) for spec in args.effect or [])
    plan = CampaignPlan(t_end=args.t_end, sample_rate=args.sample_rate, oil_temperatures=args.oil_temperatures)
    out = generate_dataset(args.out, seed=args.seed, effects=effects, damper=args.damper, plan=plan,
                           overwrite=args.overwrite, log=log)
    log(f"dataset written to {out}")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m campaign", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    add_generate_arguments(sub.add_parser("generate", help="virtual test campaign -> dataset folder"))
    args = ap.parse_args(sys.argv[1:] if argv is None else list(argv))
    try:
        return cmd_generate(args)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except (ValueError, FileExistsError, FileNotFoundError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
