"""Every damper FMU on a damper scaled from 1 N to 100 kN peak force (issue 63).

    python benchmarks/force_scale.py [--peaks 1,18,1e3,25e3,1e5] [--duration 0.4] [--no-python]

Each model's preset (the lumped and two-chamber ones with a seal friction and the thermal drift on,
``tests/force_scale_cases.py``) is scaled consistently to each peak force: every parameter whose unit carries
a kilogram times s, so the force under the same stroke is s times the preset's (a physics identity). Each FMU
(native FMI 2.0 and 3.0, pythonfmu FMI 2.0) runs a 5 Hz, 3 mm sine through ``fmpy.simulate_fmu``; printed per
FMU and peak: the largest |F_s / s - F_1| in units of the preset run's peak force, or the error the FMU
stopped with. Then the issue's damper, the two-chamber preset with a 1000 x smaller table and the stiffest mount
(k_M = 1e11 N/m), at fixed 1 ms steps as the tuner runs it, on the sine about 0 and about 20 mm.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))  # force_scale_cases: test support

from damper_fmu import defaults  # noqa: E402
from damper_fmu.fmu import ensure_fmu  # noqa: E402
from force_scale_cases import (KINDS, SMALL_STIFF_MOUNT, base_parameters, factor_for_peak, run_fmu,  # noqa: E402
                               scaled, sine_signals)

FLAVOURS = (("native FMI 2.0", "native", 2), ("native FMI 3.0", "native", 3), ("pythonfmu FMI 2.0", "python", 2))


def _cell(path, kind, signals, params, factor, ref) -> str:
    try:
        f = run_fmu(path, kind, signals, params)
    except Exception as exc:  # the FMU's error, shown in the table
        return f"error: {str(exc).splitlines()[0][:60]}"
    return f"{np.abs(f / factor - ref).max() / np.abs(ref).max():.1e}"


def scale_table(peaks, duration, flavours) -> None:
    print("largest |F_s / s - F_1| / peak |F_1| (F_1: the preset's run) per FMU and peak force [N]")
    print("| FMU | " + " | ".join(f"{p:g} N" for p in peaks) + " |")
    print("| --- |" + " --- |" * len(peaks))
    for label, flavour, version in flavours:
        for kind in KINDS:
            path = ensure_fmu(kind, flavour=flavour, fmi_version=version)
            base, signals = base_parameters(kind), sine_signals(kind, duration)
            ref = run_fmu(path, kind, signals, base)
            cells = []
            for peak in peaks:
                s = factor_for_peak(kind, base, peak)
                cells.append(_cell(path, kind, signals, scaled(kind, base, s), s, ref))
            print(f"| {kind}, {label} | " + " | ".join(cells) + " |", flush=True)


def stiff_mount_table(duration: float, flavours) -> None:
    print("\nthe issue's damper (two-chamber preset, table 1000 x smaller, k_M = 1e11 N/m), fixed 1 ms steps:"
          " peak force or error, seconds")
    for label, flavour, version in flavours:
        path = ensure_fmu("twochamber", flavour=flavour, fmi_version=version)
        for offset in (0.0, 0.02):
            t0 = time.perf_counter()
            try:
                signals = sine_signals("twochamber", duration, offset=offset)
                f = run_fmu(path, "twochamber", signals, {**defaults("twochamber"), **SMALL_STIFF_MOUNT},
                            {"internal_tolerance": 0.0})
                out = f"peak {np.abs(f).max():.4g} N"
            except Exception as exc:
                out = f"error: {str(exc).splitlines()[0][:150]}"
            print(f"  {label}, stroke about {offset * 1e3:g} mm: {out} ({time.perf_counter() - t0:.2f} s)", flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--peaks", default="1,18,1e3,25e3,1e5", help="peak forces [N], comma-separated")
    ap.add_argument("--duration", type=float, default=0.4, help="stroke duration [s]")
    ap.add_argument("--no-python", action="store_true", help="native FMUs only")
    args = ap.parse_args()
    flavours = FLAVOURS[:2] if args.no_python else FLAVOURS
    scale_table([float(p) for p in args.peaks.split(",")], args.duration, flavours)
    stiff_mount_table(args.duration, flavours)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
