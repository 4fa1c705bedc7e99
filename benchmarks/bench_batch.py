"""Fleet batch speed-up: the same batch on 1 worker and on 2 workers, side by side in one run.

    python benchmarks/bench_batch.py [--rows 4] [--t-end 6] [--population 10] [--iterations 10]
                                     [--polish 10] [--executor pool|local] [--keep DIR]

Generates ``--rows`` small virtual-rig datasets (lumped-model damper, ``--t-end`` s manoeuvres,
one dataset seed per row), writes a fleet manifest and runs ``tuner.fleet.batch.run_batch`` on it twice
into fresh folders: with 1 worker, then with 2 (``--executor pool``: the local process pool,
default; ``local``: a Dask LocalCluster). Prints both wall times, the speed-up (target >= 1.7 on a
2-core machine), the load average around each run (the machine may be shared) and whether both
runs identified the same parameters (they must: seeds come from the manifest).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from campaign.generate import CampaignPlan, generate_dataset  # noqa: E402
from tuner.fleet.batch import BatchOptions, run_batch  # noqa: E402

ID_FILES = ("id1_straight_250", "id2_curve_R400_72", "id3_switch_R190_43")
VAL_FILES = ("val1_straight_250", "val2_curve_R6000_306")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rows", type=int, default=4, help="dampers in the fleet (default %(default)s)")
    ap.add_argument("--t-end", type=float, default=6.0, help="duration of each manoeuvre [s]")
    ap.add_argument("--population", type=int, default=10)
    ap.add_argument("--iterations", type=int, default=10)
    ap.add_argument("--polish", type=int, default=10, help="refinement cap in Jacobians")
    ap.add_argument("--executor", choices=("pool", "local"), default="pool",
                    help="pool: local process pool (default); local: Dask LocalCluster")
    ap.add_argument("--keep", type=Path, default=None, help="keep datasets and results in this folder")
    a = ap.parse_args(argv)
    base = a.keep or Path(tempfile.mkdtemp(prefix="bench_batch_"))
    base.mkdir(parents=True, exist_ok=True)
    try:
        t0 = time.perf_counter()
        lines = ["damper_id,type,identification,validation,seed"]
        for k in range(a.rows):
            name = f"D{k + 1:02d}"
            generate_dataset(base / "data" / name, seed=100 + k, damper="lumped", plan=CampaignPlan(t_end=a.t_end),
                             overwrite=True, log=lambda m: None)
            ident = ";".join(f"data/{name}/{f}.csv" for f in ID_FILES)
            valid = ";".join(f"data/{name}/{f}.csv" for f in VAL_FILES)
            lines.append(f"{name},A,{ident},{valid},0")
        manifest = base / "fleet.csv"
        manifest.write_text("\n".join(lines) + "\n")
        print(f"{a.rows} datasets generated in {time.perf_counter() - t0:.0f} s; batch: population {a.population}, "
              f"iterations {a.iterations}, polish cap {a.polish}, models lumped+maxwell, executor {a.executor}",
              flush=True)
        settings = {"population": a.population, "iterations": a.iterations, "polish_jacobians": a.polish}
        wall, params = {}, {}
        for n in (1, 2):
            out = base / f"out_{n}"
            shutil.rmtree(out, ignore_errors=True)
            load0 = os.getloadavg()[0]
            t = time.perf_counter()
            res = run_batch(manifest, out, options=BatchOptions(scheduler=f"{a.executor}:{n}", settings=settings,
                                                                progress=False), log=lambda m: None)
            wall[n] = time.perf_counter() - t
            bad = [r["id"] for r in res["rows"] if r["status"] != "done"]
            if bad:
                raise SystemExit(f"rows not done with {n} worker(s): {bad}; see {out}")
            row_s = [r["record"]["elapsed_s"] for r in res["rows"]]
            params[n] = {r["id"]: json.loads((out / r["id"] / "parameters.json").read_text()) for r in res["rows"]}
            print(f"{n} worker{'s' if n > 1 else ' '}: wall {wall[n]:6.1f} s  (rows {min(row_s):.1f}-{max(row_s):.1f} s "
                  f"each, sum {sum(row_s):.1f} s; load average {load0:.2f} -> {os.getloadavg()[0]:.2f})", flush=True)
        same = params[1] == params[2]
        print(f"\nspeed-up 2 workers over 1: {wall[1] / wall[2]:.2f}x (target >= 1.7x on 2 cores); "
              f"identical parameters on 1 and 2 workers: {'yes' if same else 'NO'}")
        return 0 if same else 1
    finally:
        if a.keep is None:
            shutil.rmtree(base, ignore_errors=True)


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    sys.exit(code)
