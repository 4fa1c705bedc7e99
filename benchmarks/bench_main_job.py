"""Timings that hold: wall time of the README's main job (`python -m tuner`) and of the test suite,
with the date, the machine and its load noted, as docs/measurements.md states them.

    python benchmarks/bench_main_job.py [--tests] [--tests-args "-m 'not slow'"]

Run it in a fresh virtual environment from a clean clone (the README's two commands) so that the
FMU builds are part of the figure. Prints one block; nothing is asserted on the times. Exits 1
when the main job or the suite failed.
"""
from __future__ import annotations

import argparse
import datetime
import os
import platform
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _machine() -> str:
    cpu = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{platform.node()}: {os.cpu_count()} cores {cpu}, Python {platform.python_version()}, {platform.system()}"


def _timed(cmd, cwd) -> tuple[float, int, tuple, tuple, str]:
    before = os.getloadavg()
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    return time.perf_counter() - t0, proc.returncode, before, os.getloadavg(), proc.stdout[-1500:] + proc.stderr[-1500:]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tests", action="store_true", help="also time the test suite")
    ap.add_argument("--tests-args", default="", help="extra pytest arguments, e.g. \"-m 'not slow'\"")
    args = ap.parse_args()
    print(f"{datetime.datetime.now().isoformat(timespec='minutes')}  {_machine()}")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "main"
        wall, rc, lb, la, tail = _timed([sys.executable, "-m", "tuner", "fit", "--dataset", str(ROOT / "data" / "default"),
                                         "--out", str(out)], ROOT)
        print(f"main job: {wall:.0f} s, exit {rc}, load average before {lb[0]:.2f}, after {la[0]:.2f}")
        failed = rc != 0
        if rc:
            print(tail)
    if args.tests:
        wall, rc, lb, la, tail = _timed([sys.executable, "-m", "pytest", "-q", *shlex.split(args.tests_args)], ROOT)
        summary = [ln for ln in tail.splitlines() if " passed" in ln or " failed" in ln]
        print(f"test suite: {wall / 60:.1f} min, exit {rc}, load average before {lb[0]:.2f}, after {la[0]:.2f}; "
              f"{summary[-1].strip() if summary else ''}")
        failed = failed or rc != 0
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
