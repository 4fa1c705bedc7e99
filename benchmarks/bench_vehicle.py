"""Speed of the vehicle co-simulation with four yaw damper FMUs (tuner.vehicle), measured side by side.

    python benchmarks/bench_vehicle.py [--fmus PATH ...] [--t-end 20]

For each damper FMU (default: the native Maxwell, lumped and two-chamber FMUs at their presets):
a ``--t-end`` s run on the straight track with irregularities at 300 km/h (1 ms communication step)
with the master loop in C and in Python, and one hunting critical-speed search (100-1000 km/h, 1 km/h);
and, as the yardstick, the same run of the built-in vehicle (campaign.vehicle, Maxwell dampers in its
equations, 0.5 ms steps). Wall times on this machine; ratios from the same run.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from campaign.vehicle import VehicleParams  # noqa: E402
from damper_fmu.fmu import ensure_fmu  # noqa: E402
from tuner.vehicle.compare import _irregularity, scenario_runs  # noqa: E402
from tuner.vehicle.cosim import VehicleCosim, master_loop, reference_run  # noqa: E402
from tuner.vehicle.hunting import critical_speed_time_domain  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fmus", nargs="*", type=Path, default=None)
    ap.add_argument("--t-end", type=float, default=20.0)
    ap.add_argument("--no-search", action="store_true", help="skip the critical speed searches")
    args = ap.parse_args()

    fmus = args.fmus or [ensure_fmu(k) for k in ("maxwell", "lumped", "twochamber")]
    sc = scenario_runs()["straight_irregular"]
    sc = dataclasses.replace(sc, duration_s=args.t_end)
    params = VehicleParams()
    track, irr = sc.track(), _irregularity(sc, 0, params)
    print(f"{time.strftime('%Y-%m-%d %H:%M')}  load average {os.getloadavg()[0]:.1f}  "
          f"C master loop: {'yes' if master_loop() is not None else 'no (no compiler)'}")
    t0 = time.perf_counter()
    reference_run(params, sc.speed, track, irr, args.t_end)
    t_ref = time.perf_counter() - t0
    print(f"built-in vehicle (campaign.vehicle, 0.5 ms): {args.t_end:g} s run in {t_ref:.2f} s")
    for f in fmus:
        times = {}
        for c_loop in (True, False):
            with VehicleCosim(f, c_loop=c_loop) as co:
                co.run(sc.speed, track, irr, 0.01)  # discretisation cached, FMUs warm
                t0 = time.perf_counter()
                co.run(sc.speed, track, irr, args.t_end)
                times[c_loop] = time.perf_counter() - t0
        line = (f"{Path(f).name}: {args.t_end:g} s run with 4 FMU dampers: C loop {times[True]:.2f} s "
                f"(x{t_ref / times[True]:.2f} the built-in vehicle's speed), Python loop {times[False]:.2f} s "
                f"(C x{times[False] / times[True]:.1f} faster)")
        if not args.no_search:
            with VehicleCosim(f) as co:
                t0 = time.perf_counter()
                res = critical_speed_time_domain(co, 100 / 3.6, 1000 / 3.6)
                t_s = time.perf_counter() - t0
            vc = f"{res.speed_kmh:.1f} km/h" if res.speed < 1e9 else "stable to 1000 km/h"
            line += f"; critical speed search {t_s:.1f} s ({len(res.runs)} kick runs of 8 s): {vc}"
        print(line, flush=True)
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    os._exit(code)
