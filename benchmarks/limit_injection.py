"""Do the diagnosis's detection limits hold where the base absorbs the effect? An injection check on a physical damper.

    python benchmarks/limit_injection.py --case friction --seed-offset 2 [--scales 1,2,4] [--jacobians 10]

Runs ``blind_physical.py``'s run of the case and seed (the physical twin-tube damper, the fault hidden, the diagnosis
blind) and, at the detection-limit stage of each base diagnosed, checks every limit whose effect the base absorbs for
at least ``rules.CONFOUNDED_SHARE`` of its force on the identification tests (the linear estimate of
``tuner.diagnosis.detection`` is least sure there): the catalogue effect's force at ``scale`` x the stated limit
(the base refit with it minus without it, on the identification and the held-out tests) is added to the measured
force, the base is refined on those injected data from its refit (``polish``, at most ``--jacobians``), and printed:
the share of the injected identification SSE a refit of the effect could win back (the screen refits from 2 %:
``tuner.diagnosis.screen.SCREEN_SHARE``), the held-out score it would reach (``rules.score`` of the base refit's MSE
against the refined base's on the injected data; named above ``rules.ACCEPT_SCORE``) and the effect's force against the noise. Where the check names what
the linear limit says it names, the limit holds for an effect that arises on the identified base; a fault present
when the base was identified can still be absorbed more completely (docs/benchmarks.md, friction seed 3224).
Forces in N, magnitudes in the effect parameter's SI unit.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchmarks.blind_physical as bp  # noqa: E402
import tuner.diagnosis.search.run as search_run  # noqa: E402
from tuner.diagnosis.rules import ACCEPT_SCORE, CONFOUNDED_SHARE, score  # noqa: E402
from tuner.diagnosis.screen import SCREEN_SHARE  # noqa: E402
from tuner.identification.polish import polish  # noqa: E402


class Injected:
    """An engine whose measured force carries ``add`` [N] more (a residual vector per sample): residuals + add."""

    def __init__(self, engine, add: np.ndarray):
        self.engine, self.add, self.n_samples, self.tests = engine, add, engine.n_samples, engine.tests

    def residuals_batch(self, points):
        return [None if r is None else r + self.add for r in self.engine.residuals_batch(points)]


@dataclass(frozen=True)
class InjectionCheck:
    """One injected magnitude: the refinement's Jacobians, the share [0-1] of the injected identification SSE the
    effect could win back, the held-out score, the effect's force [N rms] on the identification tests."""

    magnitude: float
    jacobians: int
    screen_share: float
    score: float
    force_n: float

    def named(self, noise_n: float) -> bool:
        """Whether the diagnosis's rules would refit and name it: screened in, scored, its force above the noise."""
        return self.screen_share >= SCREEN_SHARE and self.score > ACCEPT_SCORE and self.force_n >= noise_n


def injection_check(s, name: str, magnitude: float, jacobians: int) -> InjectionCheck:
    """The check of ``name`` at ``magnitude`` on the search state ``s`` (its engines, base refit ``z_none``)."""
    base = s.par.to_params(s.z_none)
    (r_id0, on_id), (r_val0, on_val) = (eng.residuals_batch([base, {**base, name: magnitude}]) for eng in (s.eid, s.ev))
    d_id, d_val = r_id0 - on_id, r_val0 - on_val  # the effect's force [N] (residual: measured - simulated)
    injected = Injected(s.eid, d_id)
    pol = polish(injected, s.par, s.z_none, max_jacobians=jacobians, log=lambda m: None)
    point = s.par.to_params(pol.z)
    r_id, r_val = injected.residuals_batch([point])[0], s.ev.residuals_batch([point])[0] + d_val
    sse, sse0 = float(r_id @ r_id), float(r_id0 @ r_id0)
    mse, mse0 = float(r_val @ r_val) / len(r_val), float(r_val0 @ r_val0) / len(r_val0)
    # the effect refitted would take the held-out MSE back to the base refit's: its score against the refined base
    return InjectionCheck(magnitude, pol.jacobians, (sse - sse0) / sse, score(mse0, mse, 1),
                          math.sqrt(float(d_id @ d_id) / len(d_id)))


def checking(scales: list[float], jacobians: int):
    """The diagnosis's detection stage with the checks after it (``search.run.detection`` wrapped)."""
    plain = search_run.detection

    def detection(s, candidates):
        limits = plain(s, candidates)
        for effect, lim in limits.items():
            if lim.get("absorbed_share", 0.0) < CONFOUNDED_SHARE or not math.isfinite(lim["limit"]):
                continue
            for scale in scales:
                t0 = time.perf_counter()
                c = injection_check(s, lim["parameter"], scale * lim["limit"], jacobians)
                print(f"{s.kind:10s} {effect:13s} {lim['parameter']} = {c.magnitude:.4g} ({scale:g} x the limit, "
                      f"{100 * lim['absorbed_share']:.0f} % absorbed): {c.jacobians} Jacobians, screen "
                      f"{100 * c.screen_share:.2f} %, score {c.score:+.3f}, force {c.force_n:.1f} N (noise "
                      f"{s.noise:.1f} N): {'named' if c.named(s.noise) else 'NOT named'} "
                      f"[{time.perf_counter() - t0:.0f} s]", flush=True)
        return limits

    return detection


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default="friction", choices=bp.SINGLES)
    ap.add_argument("--seed-offset", type=int, default=0, help="the case's k-th seed (blind_physical.py's)")
    ap.add_argument("--scales", default="1,2,4", help="multiples of each stated limit injected")
    ap.add_argument("--jacobians", type=int, default=10, help="the base's refinement on the injected data, at most")
    ap.add_argument("--out", type=Path, default=Path("results/limit_injection"))
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    search_run.detection = checking([float(x) for x in a.scales.split(",")], a.jacobians)
    seed = bp.case_seed(a.case, a.seed_offset)
    case = {"case": a.case, "seed": seed, **bp.acquisition_draw(seed), "workers": 2, "hidden": {}, "durations": None,
            "log_dir": str(a.out), "sim_step_s": bp.DEFAULT_STEP}
    row = bp.run_case(case)
    print(f"{a.case} seed {seed}: hidden {row['hidden']}; named {row['causes'] or 'nothing'}; said absorbed "
          f"{row['confounded'] or 'nothing'}; the diagnosis's log: {a.out}/{a.case}-{seed}.log")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
