"""Force error of the native lumped FMU at co-simulation step sizes (docs/fmus.md; the
table, dated, in docs/measurements.md).

    python benchmarks/cosim_accuracy.py [--duration 1.0] [--tolerance 1e-4]

The master sets the stroke and velocity of each communication point at the start of the step
(``input_interpolation = 0``, as a multibody code does) on sines of 0.5-10 Hz and 1-30 mm; the
reference is scipy's LSODA (rtol 1e-9) on the lumped model's right-hand side driven by the true
continuous stroke (``tuner.identification.reference``). Printed: the largest force error after the first 0.1 s,
in % of the peak force, per frequency/amplitude (rows) and communication step (columns).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from damper_fmu.fmu import ensure_fmu  # noqa: E402
from damper_fmu import EXTRAPOLATE, defaults  # noqa: E402
from tuner.identification.reference import lumped_reference  # noqa: E402
from tuner.identification.runner import FmuRunner  # noqa: E402

STEPS_MS = (0.5, 1.0, 2.0, 5.0, 10.0)
CASES = [(f, a) for f in (0.5, 2.0, 5.0, 10.0) for a in (1e-3, 5e-3, 30e-3)]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=1.0)
    ap.add_argument("--tolerance", type=float, default=None, help="internal_tolerance (default: the FMU's)")
    args = ap.parse_args()
    fmu = ensure_fmu("lumped", flavour="native")
    grid = np.arange(0.0, args.duration + 1e-9, 0.5e-3)
    print(f"largest force error after 0.1 s [% of peak], native lumped FMU, Table 2 parameters, "
          f"{args.duration:g} s sines")
    print(f"{'f [Hz]':>7s} {'A [mm]':>7s} {'peak [kN]':>9s} " + " ".join(f"{h:>7g}ms" for h in STEPS_MS))
    params = {} if args.tolerance is None else {"internal_tolerance": args.tolerance}
    with FmuRunner(fmu, input_mode=EXTRAPOLATE) as r:
        for f, a in CASES:
            w = 2 * np.pi * f
            x, v = (lambda t: a * np.sin(w * t)), (lambda t: a * w * np.cos(w * t))
            ref = lumped_reference(defaults("lumped"), x, v, grid)
            peak = np.abs(ref).max()
            row = []
            for h in STEPS_MS:
                k = int(round(h / 0.5))
                t = grid[::k]
                force = r.run(t, x(t), v(t), params)
                late = t >= 0.1
                row.append(100 * np.abs(force - ref[::k])[late].max() / peak)
            print(f"{f:7g} {a * 1e3:7g} {peak / 1e3:9.1f} " + " ".join(f"{e:9.3f}" for e in row))
    return 0


if __name__ == "__main__":
    sys.exit(main())
