"""Build the damper FMUs (FMI 2.0 co-simulation, FMI 3.0 on request) and validate them with fmpy.

Usage:  python build_fmu.py [--out DIR] [--force] [--python] [--fmi-version 2|3 ...] [lumped maxwell ...]

The command line only: the building is ``damper_fmu.fmu`` (what the flavours are, where the FMUs
go, when they are rebuilt), which the tuner, the tests and the benchmarks import.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from damper_fmu.fmu import FMI_SUFFIX, PY_SLAVES, SLAVES, ensure_fmu, fast_path_note, native_reason, validate


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("kinds", nargs="*", default=list(SLAVES),
                    help=f"FMUs to build, from {sorted(PY_SLAVES)} (default: the four damper models)")
    ap.add_argument("--out", type=Path, default=None, help="output folder (default build/fmu, or $DAMPER_FMU_DIR)")
    ap.add_argument("--force", action="store_true", help="rebuild even if up to date")
    ap.add_argument("--python", action="store_true", help="also build the pythonfmu FMUs (*Py.fmu)")
    ap.add_argument("--fmi-version", type=int, choices=sorted(FMI_SUFFIX), action="append", dest="fmi_versions",
                    help="FMI version of the native FMUs: 2 (default) or 3 (<name>3.fmu); repeat for both")
    args = ap.parse_args(argv)
    bad = [k for k in args.kinds if k not in PY_SLAVES]
    if bad:
        ap.error(f"unknown FMU kind(s) {bad}; choose from {sorted(PY_SLAVES)}")
    note = fast_path_note()
    if note:
        print(note)
    versions = args.fmi_versions or [2]
    if 3 in versions and note:
        ap.error(f"FMI 3.0 FMUs are native only: {native_reason()}")
    status = 0
    for kind in args.kinds:
        if 3 in versions and kind not in SLAVES:
            ap.error(f"no FMI 3.0 FMU of '{kind}' (native models only: {sorted(SLAVES)})")
        jobs = ([("auto", 2)] if 2 in versions else []) + ([("native", 3)] if 3 in versions else [])
        jobs += [("python", 2)] if args.python and kind in SLAVES and not note else []
        for flavour, version in jobs:
            path = ensure_fmu(kind, args.out, flavour, fmi_version=version, force=args.force)
            problems = validate(path)
            print(f"{path}: {'valid' if not problems else 'INVALID'}")
            for p in problems:
                print(f"  - {p}")
                status = 1
    return status


if __name__ == "__main__":
    sys.exit(main())
