"""Hunting of the nonlinear car (campaign.vehicle_nonlinear) with its built-in Maxwell yaw dampers: the
bifurcation diagram by ramp-down and the linear and nonlinear critical speeds against equivalent conicity.

    python benchmarks/hunting_bifurcation.py [--conicities 0.05 0.15 0.25 0.35 0.45] [--dv 20] [--tol 2]
                                             [--v-max 1200] [--v-min 100] [--linear-dashpot] [--unstable]

Prints, per conicity, the linear critical speed (eigenvalues of campaign.vehicle), the fold of the
large limit cycle's branch, the nonlinear critical speed (the lower of the two), the cycle amplitude of
the leading wheelset at the fold, the plateaus run and the wall time on this machine. ``--unstable``:
also the branch through the fold by shooting (campaign.periodic_orbits), from the lowest stable cycle of
the ramp about 8 km/h above the fold down in amplitude steps of 0.2 mm: amplitude against speed, the unstable part between the fold
and the linear critical speed.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from campaign.bifurcation import RampSettings, builtin_runner, conicity_sweep  # noqa: E402
from campaign.periodic_orbits import continue_in_amplitude, orbit_guess, solve_orbit, vehicle_shooting_problem  # noqa: E402
from campaign.vehicle import VehicleParams, critical_speed  # noqa: E402
from campaign.vehicle_nonlinear import LEADING_WHEELSET, NonlinearVehicle, kick_state  # noqa: E402


def unstable_branch(params, diagram, step: float = 0.2e-3, above: float = 8.0 / 3.6) -> list:
    """The branch through the stable cycle of ``diagram`` nearest ``above`` [m/s] over the fold (at the fold
    itself a step in amplitude has no good predictor) continued down in amplitude by shooting."""
    stable = [c for c in diagram.cycles if c.exists]
    low = min(stable, key=lambda c: abs(c.speed - diagram.fold_speed - above))
    run = NonlinearVehicle(params, low.speed).simulate(low.state, 1.0)
    guess = orbit_guess(run.t, run.states, low.speed, LEADING_WHEELSET)
    prob = vehicle_shooting_problem(params, None, np.max(np.abs(run.states), axis=0))
    start = solve_orbit(prob, guess.amplitude, guess)
    amps = np.arange(start.amplitude - step, 0.5 * step, -step)
    return [start] + continue_in_amplitude(prob, start, amps, stability=False,
                                           log=lambda line: print(line, flush=True))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--conicities", nargs="+", type=float, default=[0.05, 0.15, 0.25, 0.35, 0.45])
    ap.add_argument("--dv", type=float, default=20.0, help="speed step [km/h]")
    ap.add_argument("--tol", type=float, default=2.0, help="fold bisection tolerance [km/h]")
    ap.add_argument("--v-max", type=float, default=1200.0, help="highest speed [km/h]")
    ap.add_argument("--v-min", type=float, default=100.0, help="lowest speed [km/h]")
    ap.add_argument("--linear-dashpot", action="store_true", help="yaw damper without blow-off")
    ap.add_argument("--unstable", action="store_true", help="also the branch through the fold by shooting")
    args = ap.parse_args()
    base = VehicleParams()
    if args.linear_dashpot:
        base = dataclasses.replace(base, yaw_blowoff_velocity=math.inf)
    v_max, v_min = args.v_max / 3.6, args.v_min / 3.6

    def params(lam):
        return dataclasses.replace(base, conicity=lam)

    settings = RampSettings(dv=args.dv / 3.6, tol=args.tol / 3.6)
    rows = []
    for lam in args.conicities:
        t0 = time.perf_counter()
        (pt,) = conicity_sweep([lam], lambda c: builtin_runner(params(c)),
                               lambda c: critical_speed(params(c), v_max=v_max, dv=2.0, tol=0.05),
                               kick_state(settings.kick), v_max=v_max, v_min=v_min, settings=settings)
        d = pt.diagram
        v, a = d.branch()
        rows.append((lam, d.linear_critical_speed, d.fold_speed, d.nonlinear_critical_speed,
                     a[0] if a.size else math.nan, len(d.cycles), sum(c.duration for c in d.cycles),
                     time.perf_counter() - t0))
        print(f"conicity {lam}: done in {rows[-1][-1]:.0f} s", flush=True)
        if args.unstable and d.cycle_reached:
            t0 = time.perf_counter()
            orbits = unstable_branch(params(lam), d)
            print(f"\nconicity {lam}: branch by shooting ({time.perf_counter() - t0:.0f} s)\n"
                  "| amplitude [mm] | speed [km/h] | period [s] | closure residual |\n| --- | --- | --- | --- |")
            for o in orbits:
                print(f"| {o.amplitude * 1e3:.2f} | {o.speed * 3.6:.1f} | {o.period:.4f} | {o.residual:.1e} |")
    print("\n| conicity | linear [km/h] | fold [km/h] | nonlinear [km/h] | amplitude at fold [mm] | plateaus "
          "| simulated [s] | wall [s] |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for lam, vl, vf, vn, a, n, sim, wall in rows:
        f = (lambda x: "> v_max" if math.isinf(x) else f"{x * 3.6:.1f}")
        print(f"| {lam:.2f} | {f(vl)} | {f(vf)} | {f(vn)} | {a * 1e3:.2f} | {n} | {sim:.0f} | {wall:.0f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
