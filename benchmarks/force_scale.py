"""Every damper FMU on a damper scaled from 1 N to 1 MN peak force (issue 63); the fit of a scaled damper (issue 74).

    python benchmarks/force_scale.py [--peaks 1,18,1e3,25e3,1e5,1e6] [--duration 0.4] [--no-python]
    python benchmarks/force_scale.py --fit [--factors 1,1e-3,10] [--population 8] [--iterations 10] [--polish 20]

Each model's preset (the lumped and two-chamber ones with a seal friction and the thermal drift on,
``tests/force_scale_cases.py``) is scaled consistently to each peak force: every parameter whose unit carries
a kilogram times s, so the force under the same stroke is s times the preset's (a physics identity). Each FMU
(native FMI 2.0 and 3.0, pythonfmu FMI 2.0) runs a 5 Hz, 3 mm sine through ``fmpy.simulate_fmu``; printed per
FMU and peak: the largest |F_s / s - F_1| in units of the preset run's peak force, or the error the FMU
stopped with. Then the issue's damper, the two-chamber preset with a 1000 x smaller table and the stiffest mount
(k_M = 1e11 N/m), at fixed 1 ms steps as the tuner runs it, on the sine about 0 and about 20 mm.

``--fit``: the bundled damper (data/default/) scaled consistently by each factor (its force times the factor,
``tests/force_scale_cases.scaled_tests``) fitted by each base form with the given budget (``FitSettings``, one
worker): per form and factor the worst held-out AME [% of peak], its ratio to the first factor's (full scale,
1) and the parameters on a bound (within 0.1 % of the range, in log space where the search is) that the
full-scale fit leaves free. Every bound and fixed constant follows the damper's scale
(``tuner.identification.damper_scale``), so the ratios are those of one problem in another unit of force.
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
                               scaled, scaled_tests, sine_signals)
from damper_fmu.parameters import MODEL_PARAMETERS  # noqa: E402
from tuner.data.reading import load_dataset  # noqa: E402
from tuner.identification.fit import FitSettings, fit  # noqa: E402

FIT_MODELS = ("lumped", "maxwell", "twochamber")
#: a parameter within this share of its search range from a bound is on it
ON_BOUND = 1e-3

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


def on_bounds(model: str, entry: dict) -> set[str]:
    """The identified parameters of ``model`` (no table ordinate) within ``ON_BOUND`` of their search range from a
    bound in the fit's ``entry`` (``FitResult.params[model]``: values and bounds, SI)."""
    log_scale = {p.name: p.log_scale for p in MODEL_PARAMETERS[model]}
    out = set()
    for name, (lo, hi) in entry["bounds"].items():
        if name.startswith(("Fc_", "Fk_")):
            continue
        v = entry["values"][name]
        if log_scale[name] and lo > 0:
            v, lo, hi = np.log(v), np.log(lo), np.log(hi)
        if min(v - lo, hi - v) <= ON_BOUND * (hi - lo):
            out.add(name)
    return out


def fit_table(factors, population: int, iterations: int, polish: int) -> None:
    """The bundled damper scaled by each of ``factors`` fitted by each base form (module docstring)."""
    tests = load_dataset(ROOT / "data" / "default")
    settings = FitSettings(models=FIT_MODELS, population=population, iterations=iterations, polish_jacobians=polish,
                           workers=1)
    print(f"the bundled damper scaled by {', '.join(f'{s:g}' for s in factors)}: FitSettings(population={population}, "
          f"iterations={iterations}, polish_jacobians={polish}, workers=1)")
    print("| form | factor | worst held-out AME [% of peak] | / full scale | on a bound the full-scale fit leaves free "
          "| on a bound at full scale | fit [s] |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    first = {}
    for s in factors:
        scaled_set = scaled_tests(tests, s)
        t0 = time.perf_counter()
        result = fit([t for t in scaled_set if t.role == "identification"],
                     [t for t in scaled_set if t.role == "validation"], settings, log=lambda line: None)
        elapsed = time.perf_counter() - t0
        for model in FIT_MODELS:
            ame = result.metrics["quality"][model]["worst_ame_pct_of_peak"]
            bound = on_bounds(model, result.params[model])
            base_ame, base_bound = first.setdefault(model, (ame, bound))
            new, kept = (", ".join(sorted(b)) or "-" for b in (bound - base_bound, bound & base_bound))
            print(f"| {model} | {s:g} | {ame:.4g} | {ame / base_ame:.3f} | {new} | {kept} | {elapsed:.0f} |", flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--peaks", default="1,18,1e3,25e3,1e5,1e6", help="peak forces [N], comma-separated")
    ap.add_argument("--duration", type=float, default=0.4, help="stroke duration [s]")
    ap.add_argument("--no-python", action="store_true", help="native FMUs only")
    ap.add_argument("--fit", action="store_true", help="fit the bundled damper scaled by --factors instead")
    ap.add_argument("--factors", default="1,1e-3,10", help="force factors, the first the reference (comma-separated)")
    ap.add_argument("--population", type=int, default=8, help="Firefly population (--fit)")
    ap.add_argument("--iterations", type=int, default=10, help="Firefly iterations (--fit)")
    ap.add_argument("--polish", type=int, default=20, help="local refinement's Jacobians at most (--fit)")
    args = ap.parse_args()
    if args.fit:
        fit_table([float(s) for s in args.factors.split(",")], args.population, args.iterations, args.polish)
        return 0
    flavours = FLAVOURS[:2] if args.no_python else FLAVOURS
    scale_table([float(p) for p in args.peaks.split(",")], args.duration, flavours)
    stiff_mount_table(args.duration, flavours)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
