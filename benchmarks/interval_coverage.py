"""Coverage of the identified parameters' 95 % intervals (tuner.identification.intervals) over many seeds.

For each seed, rig tests of a lumped damper of known parameters (tests/interval_cases.py: Table 2's
tables, masses M_P 12, M_O 9, M_C 14 kg; white load-cell noise; a new stroke and noise realisation per
seed) are fitted by the local refinement from the truth, and every parameter's interval is checked
against the truth. Prints per parameter group: how many (seed, parameter) pairs, the share flagged
determined, the share whose interval covers the truth (of those with a finite interval; a 95 % interval
should cover about 95 %), the median |z| = |estimate - truth| / std (0.67 for a correct standard error),
the median representation shift against the standard error (tuner.identification.intervals: the
bias of the identification's 1 ms steps and stroke resampling, in the interval's half-width
Z95 sqrt(std^2 + shift^2)), the median width against the bound range, and how many had no finite interval.

The truth's force is integrated finely (``--truth fine``: the model itself) or as the identification
engine integrates (``--truth identification``: what the fit can represent exactly), and the tuner
differentiates the stroke (as for a rig without a velocity channel) or reads the exact velocity
(``--velocity measured``). ``--truth exact``: the fit sees the identification's own simulated force at
the truth plus the same resampled noise (data it represents exactly: the intervals' statistics alone).

    python benchmarks/interval_coverage.py [--seeds 20] [--noise 25] [--durations 10,10] [--kind multisine]
                                           [--truth fine|identification|exact] [--velocity differentiated|measured]
                                           [--slow-amp 0.015] [--fit-rate 200]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # interval_cases: test support

from interval_cases import KINDS, TRUTH_STEPS, fitted, rig_tests, truth  # noqa: E402

GROUPS = ("M_P", "M_O", "M_C", "k_B, c_B", "Fc reached", "Fc extrapolated", "Fk reached", "Fk extrapolated")


def group(p) -> str:
    """The group of a ``ParameterInterval``."""
    if p.name in ("M_P", "M_O", "M_C"):
        return p.name
    if p.name in ("k_B", "c_B"):
        return "k_B, c_B"
    return f"{p.name[:2]} {'extrapolated' if p.extrapolated else 'reached'}"


def rows_of(seed: int, a) -> list[dict]:
    """One row per identified parameter of one seed's fit."""
    known = truth()
    steps = "fine" if a.truth == "exact" else a.truth
    tests = rig_tests(known, a.kind, seed, a.durations, a.noise, a.slow_amp, steps, a.velocity == "measured")
    clean = (rig_tests(known, a.kind, seed, a.durations, 0.0, a.slow_amp, steps, a.velocity == "measured")
             if a.truth == "exact" else None)
    _, par, _, iv, _ = fitted(known, tests, fit_rate_hz=a.fit_rate, noise_free=clean)
    exact = par.to_params(par.from_params(known))
    out = []
    for p in iv.parameters:
        finite = p.low is not None
        out.append({"group": group(p), "determined": p.determined, "finite": finite,
                    "covered": finite and p.low <= exact[p.name] <= p.high,
                    "z": abs(p.value - exact[p.name]) / p.std if finite and p.std else np.nan,
                    "shift": abs(p.systematic) / p.std if finite and p.std and p.systematic is not None else np.nan,
                    "width": p.width_fraction if finite else np.nan})
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--noise", type=float, default=25.0, help="load-cell noise rms [N]")
    ap.add_argument("--durations", default="10,10", help="identification test lengths [s], comma-separated")
    ap.add_argument("--kind", choices=KINDS, default="multisine")
    ap.add_argument("--slow-amp", type=float, default=0.015, help="slow stroke amplitude [m]")
    ap.add_argument("--truth", choices=(*TRUTH_STEPS, "exact"), default="fine")
    ap.add_argument("--fit-rate", type=float, default=200.0)
    ap.add_argument("--velocity", choices=("differentiated", "measured"), default="differentiated",
                    help="the tuner differentiates the stroke, or reads the exact velocity as the rig's channel")
    a = ap.parse_args(argv)
    a.durations = tuple(float(d) for d in a.durations.split(","))
    t0 = time.perf_counter()
    rows = [r for seed in range(a.seeds) for r in rows_of(seed, a)]
    print(f"95 % intervals against the truth: {a.seeds} seeds, {a.kind} strokes {a.durations} s, {a.noise:g} N noise, "
          f"truth integrated '{a.truth}', velocity {a.velocity}, fit rate {a.fit_rate:g} Hz")
    print(f"{'group':16s} {'pairs':>5s} {'determ.':>7s} {'covers':>7s} {'cov|det':>7s} {'med|z|':>6s} "
          f"{'med|s|/sd':>9s} {'med width':>9s} {'no interval':>11s}")
    for g in GROUPS:
        sel = [r for r in rows if r["group"] == g]
        if not sel:
            continue
        fin = [r for r in sel if r["finite"]]
        det = [r for r in fin if r["determined"]]
        share = (lambda xs: f"{100 * np.mean([r['covered'] for r in xs]):6.1f}%" if xs else "     - ")
        z = np.nanmedian([r["z"] for r in fin]) if fin else np.nan
        w = np.nanmedian([r["width"] for r in fin]) if fin else np.nan
        sh = np.nanmedian([r["shift"] for r in fin]) if fin else np.nan
        print(f"{g:16s} {len(sel):5d} {100 * np.mean([r['determined'] for r in sel]):6.1f}% {share(fin)} {share(det)} "
              f"{z:6.2f} {sh:9.2f} {100 * w:8.3g}% {len(sel) - len(fin):11d}")
    print(f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
