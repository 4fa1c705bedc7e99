"""Evaluation speed of the tuner's engines, measured side by side in one run.

    python benchmarks/bench_native.py [--batches 5] [--batch 8] [--baseline-commit cb21df9]

Data: the bundled dataset's identification tests at the fit rate (200 Hz), as ``tuner.identification.fit`` sees
them, with the tuner's identification settings (fixed internal steps of 1 ms; the baseline ran one
5 ms step per sample); candidates: random points of the improved parametrization (seeded). Variants, each in one worker
process of its own (workers = 1: two pythonfmu FMUs of different versions cannot share a process),
interleaved batch by batch so machine load hits all alike:

* ``before``: the pythonfmu FMU of the baseline commit (the project before the native kernel),
  through ``tuner.identification.runner`` (built from a git worktree of that commit; skipped if git is missing);
* ``pythonfmu FMU``: today's pythonfmu FMU (same algorithm as the native one);
* ``native FMU``: the C FMU through fmpy (``--engine fmu``, the default);
* ``C kernel``: the same C code called once per test (``--engine native``);
* ``Python``: the Python reference (``--engine inprocess``).

Prints evaluations/s, the ratio to ``before`` and the largest relative SSE difference between the
native FMU and the C kernel (equal results). Exit status 0: a report, not a test.
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from damper_fmu.fmu import ensure_fmu  # noqa: E402
from tuner.data.preprocess import prepare  # noqa: E402
from tuner.data.reading import load_dataset  # noqa: E402
from tuner.identification.engine import Engine  # noqa: E402
from tuner.identification.problem import to_signals  # noqa: E402
from tuner.identification.parametrization import Parametrization  # noqa: E402

FIT_RATE, WARMUP = 200.0, 0.5


def baseline_fmu(commit: str, tmp: Path) -> Path | None:
    """Build the lumped pythonfmu FMU of ``commit`` in a git worktree; None if that fails."""
    wt = tmp / "baseline"
    try:
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(wt), commit], check=True,
                       capture_output=True)
        out = tmp / "fmu"
        subprocess.run([sys.executable, str(wt / "build_fmu.py"), "--out", str(out), "lumped"], check=True,
                       capture_output=True, cwd=wt)
        return out / "DamperLumped.fmu"
    except (OSError, subprocess.CalledProcessError) as err:
        print(f"baseline FMU of {commit} not built ({err}); 'before' skipped")
        return None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--batches", type=int, default=5)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--baseline-commit", default="cb21df9")
    args = ap.parse_args()

    tests = load_dataset(ROOT / "data" / "default")
    signals = [to_signals(prepare(t, FIT_RATE), WARMUP) for t in tests if t.role == "identification"]
    n = sum(s.time.size for s in signals)
    par = Parametrization("lumped")
    rng = np.random.default_rng(args.seed)
    batches = [[par.to_params(z) for z in rng.random((args.batch, par.dimension))] for _ in range(args.batches + 1)]
    step = 1.0 / FIT_RATE
    with tempfile.TemporaryDirectory(prefix="bench_native_") as tmp:
        engines = {}
        old = baseline_fmu(args.baseline_commit, Path(tmp))
        if old is not None:
            # as the baseline's tuner ran it: one internal step per 5 ms sample (it had no tolerance)
            engines["before (pythonfmu, baseline commit)"] = Engine("lumped", signals, engine="fmu", workers=1,
                                                                    fmu_path=old, max_internal_step=step,
                                                                    tolerance=None)
        engines["pythonfmu FMU"] = Engine("lumped", signals, engine="fmu", workers=1,
                                          fmu_path=ensure_fmu("lumped", flavour="python"))
        engines["native FMU through fmpy (default)"] = Engine("lumped", signals, engine="fmu", workers=1,
                                                              fmu_path=ensure_fmu("lumped", flavour="native"))
        engines["C kernel (--engine native)"] = Engine("lumped", signals, engine="native", workers=1)
        engines["Python reference (--engine inprocess)"] = Engine("lumped", signals, engine="inprocess",
                                                                  workers=1)
        rates = {k: [] for k in engines}
        sse = {}
        for name, e in engines.items():
            e.sse_batch(batches[0][:2])  # warm-up
        for i in range(1, args.batches + 1):
            for name, e in engines.items():
                t0 = time.perf_counter()
                sse[name, i] = e.sse_batch(batches[i])
                rates[name].append(len(batches[i]) / (time.perf_counter() - t0))
        for e in engines.values():
            e.close()
        if old is not None:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(Path(tmp) / "baseline")],
                           capture_output=True)
    med = {k: statistics.median(v) for k, v in rates.items()}
    ref = next(iter(med.values()))
    print(f"lumped model, {len(signals)} identification tests, {n} samples at {FIT_RATE:g} Hz; "
          f"{args.batches} batches of {args.batch} random candidates, one worker each")
    print(f"{'variant':45s} {'eval/s':>9s} {'x before':>9s}")
    for k, r in med.items():
        print(f"{k:45s} {r:9.1f} {r / ref:9.2f}")
    a = np.concatenate([sse["native FMU through fmpy (default)", i] for i in range(1, args.batches + 1)])
    b = np.concatenate([sse["C kernel (--engine native)", i] for i in range(1, args.batches + 1)])
    ok = np.isfinite(a) & np.isfinite(b)
    print(f"native FMU vs C kernel: largest relative SSE difference {np.max(np.abs(a[ok] - b[ok]) / b[ok]):.2e} "
          f"({int(ok.sum())} finite of {a.size}; failed alike: {bool(np.all(np.isfinite(a) == np.isfinite(b)))})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
