"""Long rig tests: wall time of `python -m tuner fit` (lumped + Maxwell, validation, diagnosis,
report) on a 100 s test at 300 Hz and on a 30 s test at 5 kHz (issue 13's target: <= 5 min each
on 2 cores), and whether the result depends on the rate the data was written at.

Data: the lumped model (Table 2 preset) under random multi-sine strokes with 20 N of load-cell
noise (campaign.synthetic), one identification test of the stated length and a held-out test of
a third of it. Prints one table; nothing is asserted.

    python benchmarks/bench_long_tests.py [--cases 300x100,5000x30] [--workers 2]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> int:
    from campaign.synthetic import write_model_dataset
    from damper_fmu import defaults

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", default="300x100,5000x30", help="RATExSECONDS, comma-separated")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for case in args.cases.split(","):
            rate, seconds = (float(v) for v in case.split("x"))
            data = write_model_dataset(Path(tmp) / f"d{case}", "lumped", defaults("lumped"), seed=3,
                                       durations=(seconds, seconds / 3), roles=("identification", "validation"),
                                       fs=rate)
            out = Path(tmp) / f"o{case}"
            t0 = time.perf_counter()
            proc = subprocess.run([sys.executable, "-m", "tuner", "fit", "--dataset", str(data), "--out", str(out),
                                   "--workers", str(args.workers)], cwd=ROOT, capture_output=True, text=True)
            wall = time.perf_counter() - t0
            if proc.returncode != 0:
                print(proc.stdout[-3000:], proc.stderr[-3000:])
                return 1
            metrics = json.loads((out / "metrics.json").read_text())
            diag = json.loads((out / "diagnosis.json").read_text()) if (out / "diagnosis.json").exists() else {}
            hist = json.loads((out / "history_lumped.json").read_text())
            val = [t for t, r in metrics["tests"].items() if r["role"] == "validation"][0]
            rows.append((case, wall, hist["identification_rmse_n"], hist["noise_floor_n"],
                         metrics["tests"][val]["models"]["lumped"]["rmse"], diag.get("cause", "-")))
    print(f"{'case (Hz x s)':>14} {'wall [s]':>9} {'id RMSE [N]':>12} {'noise [N]':>10} {'val RMSE [N]':>13}  diagnosis")
    for case, wall, rid, noise, rval, cause in rows:
        print(f"{case:>14} {wall:9.0f} {rid:12.1f} {noise:10.1f} {rval:13.1f}  {cause}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
