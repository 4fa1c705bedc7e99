"""The vehicle figures' 95 % intervals (tuner.vehicle.propagation), thoroughly.

Part 1 (``--maxwell-draws``): the linear Maxwell FMU with a given covariance of (ln k_s, ln c)
(tests/vehicle_interval_cases.py), many draws: every draw's time-domain critical speed against the
eigenvalue critical speed at its parameters, and the interval against the delta method on the eigenvalue
critical speed (finite-differenced), with the stated Monte-Carlo error; per number of draws a row.

Part 2 (``--from FOLDER``): a fit output folder's tuned FMUs (``python -m tuner`` leaves one); the intervals
with ``--draws`` draws, written to FOLDER/vehicle/intervals.json (replacing the job's), the stop reason, the
search's own scatter, and what a draw costs (wall and processor time).

    python benchmarks/vehicle_intervals.py [--maxwell-draws 24,96] [--from results/default --draws 24]
                                           [--scheduler pool:2]
"""
from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # vehicle_interval_cases: test support

from tuner.identification.parameter_draws import draw_parameter_sets  # noqa: E402
from tuner.metrics import Z95  # noqa: E402
from tuner.vehicle.hunting import eigen_critical_speed  # noqa: E402
from tuner.vehicle.propagation import PropagationSettings, propagate  # noqa: E402
from vehicle_interval_cases import KS, C, cov_log, eigen_gradient, maxwell_folder  # noqa: E402


def maxwell_row(n: int, scheduler: str | None, seed: int) -> str:
    """One table row: n draws of the Maxwell case against the eigenvalues and the delta method (km/h)."""
    with tempfile.TemporaryDirectory() as tmp:
        params = maxwell_folder(Path(tmp))
        s = PropagationSettings(draws=n, batch=n, v_min_ms=250 / 3.6, v_max_ms=550 / 3.6, half_width_ms=20 / 3.6,
                                seed=seed)
        t0 = time.perf_counter()
        res = propagate(tmp, s, scheduler=scheduler, log=lambda m: None)["results"]["DamperMaxwell_tuned"]
        wall = time.perf_counter() - t0
    cs = res["critical_speed"]
    draws = draw_parameter_sets("maxwell", params["maxwell"], n, seed)
    td = np.array([o["critical_speed"] for o in sorted(res["outcomes"], key=lambda o: o["index"]) if o["index"] >= 0])
    eig = np.array([eigen_critical_speed(p["k_s"], p["c"], tol=1e-3) for p in draws.sets])
    v0, grad = eigen_critical_speed(KS, C, tol=1e-3), eigen_gradient()
    sd = math.sqrt(grad @ cov_log() @ grad)
    k = 3.6
    return (f"| {n} | {cs['method']} | {cs['nominal'] * k:.2f} / {v0 * k:.2f} | {cs['low'] * k:.1f}-{cs['high'] * k:.1f} "
            f"| {(v0 - Z95 * sd) * k:.1f}-{(v0 + Z95 * sd) * k:.1f} | {cs['mc_error'] * k if cs['mc_error'] else math.nan:.2f} "
            f"| {np.max(np.abs(td - eig)) * k:.3f} | {np.std(td, ddof=1) / sd:.3f} | {wall:.0f} |")


def folder_rows(folder: Path, n: int, scheduler: str | None, seed: int) -> list[str]:
    """One row per tuned FMU of the fit folder."""
    t0 = time.perf_counter()
    data = propagate(folder, PropagationSettings(draws=n, seed=seed), scheduler=scheduler, log=print)
    wall = time.perf_counter() - t0
    rows = []
    for label, r in data["results"].items():
        cs, pf = r["critical_speed"], r["peak_curve_force"]
        outs = [o for o in r["outcomes"] if o["error"] is None]
        scatter = r["search_scatter_ms"]
        rows.append(f"| {label} | {r['critical_speed_text']} | +-{(cs['mc_error'] or math.nan) * 3.6:.2f} | "
                    f"{'-' if scatter is None else format(scatter * 3.6, '.2f')} | {r['peak_curve_force_text']} | "
                    f"+-{(pf['mc_error'] or math.nan) * 1e-3:.3f} | {cs['draws']} | "
                    f"{np.mean([o['runs'] for o in outs]):.1f} | {np.mean([o['cpu_time_s'] for o in outs]):.2f} | "
                    f"{np.mean([o['wall_time_s'] for o in outs]):.2f} |")
    rows.append(f"(all FMUs: {wall:.0f} s wall on {data['where']})")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--maxwell-draws", default="24,96", help="comma-separated numbers of draws ('' to skip)")
    ap.add_argument("--from", dest="folder", type=Path, default=None, help="a fit output folder (part 2)")
    ap.add_argument("--draws", type=int, default=PropagationSettings().draws)
    ap.add_argument("--scheduler", default=None, help="pool:N, local:N, a Dask address; default this process")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    if args.maxwell_draws:
        print("| draws | interval | nominal / eigenvalues [km/h] | 95 % [km/h] | delta method [km/h] | Monte-Carlo "
              "[km/h] | max draw - eigenvalues [km/h] | sd / delta sd | wall [s] |")
        print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
        for n in (int(v) for v in args.maxwell_draws.split(",")):
            print(maxwell_row(n, args.scheduler, args.seed), flush=True)
    if args.folder is not None:
        if not (args.folder / "parameters.json").is_file():
            sys.exit(f"--from {args.folder}: no parameters.json (not a fit output folder)")
        print("| FMU | critical speed | Monte-Carlo [km/h] | search scatter [km/h] | curve peak force | "
              "Monte-Carlo [kN] | draws | kick runs per draw | processor s per draw | wall s per draw |")
        print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
        for row in folder_rows(args.folder, args.draws, args.scheduler, args.seed):
            print(row, flush=True)


if __name__ == "__main__":
    main()
