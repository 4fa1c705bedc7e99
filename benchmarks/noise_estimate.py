"""Force-noise estimates against the truth over many seeds and test shapes.

For each shape of ``tests/noise_cases.py`` (a random lumped damper through the rig's sensor chain,
5-50 N of load-cell noise; sine strokes at 500 Hz and 2 kHz, the same at 200 Hz low-pass filtered at
20 Hz, random multisine strokes at 500 Hz and at 200 Hz filtered, a sine through a 10-bit ADC, a random
drive replayed twice in one test at 500 Hz, at 200 Hz filtered, and starting between samples) and
seed, every estimator of ``tuner.data.noise`` and the spectral median the tuner used before
(``tuner.metrics.noise_std``, scaled to the fit band alike) is compared with the true noise in the
fit band (the noise alone through the tuner's resampler to ``--fit-rate``). Prints per shape and
method: how many estimates were available and credible, and the estimate / truth ratio (median, min,
max over the available ones; for the chosen estimate also over the credible ones).

    python benchmarks/noise_estimate.py [--seeds 20] [--fit-rate 200]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # noise_cases: test support

from noise_cases import SHAPES, noise_case  # noqa: E402
from tuner.data.noise import force_noise, in_band  # noqa: E402
from tuner.metrics import noise_std  # noqa: E402

METHODS = ("cycle_scatter", "repeats", "quiet_band", "resolution", "spectral (before)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--fit-rate", type=float, default=200.0)
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    print(f"estimate / truth of the force noise in the {a.fit_rate / 2:g} Hz fit band, {a.seeds} seeds per shape")
    print(f"{'shape':20s} {'method':18s} {'avail':>5s} {'cred':>5s} {'median':>7s} {'min':>7s} {'max':>7s}")
    for shape in SHAPES:
        rows = {m: [] for m in (*METHODS, "chosen")}
        for seed in range(a.seeds):
            test, truth = noise_case(shape, seed, fit_rate_hz=a.fit_rate)
            r = force_noise(test, a.fit_rate)
            for m in METHODS[:4]:
                e = r["all"][m]
                if e["available"]:
                    rows[m].append((e["in_band_n"] / truth["in_band_n"], e["credible"]))
            spectral = in_band(noise_std(test.force, test.sample_rate), test.sample_rate, a.fit_rate)
            rows["spectral (before)"].append((spectral / truth["in_band_n"], True))
            rows["chosen"].append((r["in_band_n"] / truth["in_band_n"], r["credible"]))
        for m, vals in rows.items():
            if m == "spectral (before)":
                cred = "-"
            else:
                cred = str(sum(c for _, c in vals))
            x = np.array([v for v, _ in vals])
            stats = (f"{np.median(x):7.3f} {x.min():7.3f} {x.max():7.3f}" if x.size
                     else f"{'-':>7s} {'-':>7s} {'-':>7s}")
            print(f"{shape:20s} {m:18s} {len(vals):5d} {cred:>5s} {stats}")
            if m == "chosen" and 0 < sum(c for _, c in vals) < len(vals):
                xc = np.array([v for v, c in vals if c])
                print(f"{shape:20s} {'chosen, credible':18s} {xc.size:5d} {xc.size:5d} "
                      f"{np.median(xc):7.3f} {xc.min():7.3f} {xc.max():7.3f}")
        print()
    print(f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
