"""Does the identification converge on any damper of the model's class? Random dampers fitted blind.

    python benchmarks/convergence.py --model lumped [--dampers 30] [--seed-offset 0] [--out DIR]
                                     [--engine fmu] [--durations 12,16] [--quick]

For each seed a random damper of the model's class is drawn from the wide priors of
``campaign.damper_class`` (asymmetric tables, knees anywhere, soft to stiff, other masses, blocks,
mounts and chambers; 5-50 N load-cell noise; strokes from the campaign, multisines, sweeps and
hunting-like motion), its rig data are written (four identification and two validation tests of
12-16 s at 500 Hz) and ``tuner.identification.fit.fit`` runs on them with the default settings
(only ``models`` set to the one model). Per damper it records:

* the identification RMSE, the in-band load-cell noise (the data's known noise pushed through the
  rig's sensor chain and the tuner's resampler to the fit rate), and the RMSE the TRUE parameters
  score through the same objective (the reachable floor: it also holds the stroke channel's
  noise, 2 um and a 3 um ADC step, which the model sees through its velocity);
* whether the tuner says converged (its first-order test), Jacobians, evaluations, wall time.

Converged here: identification RMSE <= 1.2 x the truth's RMSE. A tuner verdict "converged" on a
damper that misses that is a false claim (a local minimum) and is counted separately.
Results go to ``--out`` (one JSON per damper: an interrupted run resumes); the table is printed
at the end and written to ``convergence.json``. ``--quick`` is the CI-sized version: shorter tests.
"""
from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from campaign.damper_class import OVERSAMPLING, SAMPLE_RATE_HZ, write_class_dataset  # noqa: E402
from campaign.sensors import SensorChain  # noqa: E402
from tuner.data.preprocess import Resampler  # noqa: E402
from tuner.data.reading import load_dataset, read_manifest  # noqa: E402
from tuner.identification.engine import simulate_signals  # noqa: E402
from tuner.identification.fit import FitSettings, fit  # noqa: E402
from tuner.identification.problem import Problem, model_abscissae  # noqa: E402

RATIO = 1.2


def in_band_noise(noise_n: float, fit_rate_hz: float, n: int = 200_000) -> float:
    """Load-cell noise [N rms] left in the fit band: white noise through the rig's sensor chain
    (``campaign.sensors``, no quantisation) and the tuner's resampler to ``fit_rate_hz``."""
    chain = SensorChain(force_noise=noise_n, oversampling=OVERSAMPLING, adc_bits=32, force_range=1e6)
    m = OVERSAMPLING * (n - 1) + 1
    _, f, _ = chain.acquire(np.zeros(m), np.zeros(m), np.zeros(m), seed=12345)
    return float(Resampler.design(SAMPLE_RATE_HZ, fit_rate_hz).apply(f).std())


def truth_rmse(model: str, folder: Path, settings: FitSettings, engine: str) -> tuple[float, bool]:
    """(RMSE [N] of the true parameters through the identification objective, whether the tuner's
    table abscissae are the truth's)."""
    truth = read_manifest(folder)["generator"]["parameters"]
    ident = [t for t in load_dataset(folder) if t.role == "identification"]
    problem = Problem.build(ident, [], settings.data)
    signals = problem.sig_id
    fixed = model_abscissae(model, problem.axes)
    same = all(math.isclose(truth[k], v, rel_tol=1e-12) for k, v in fixed.items())
    res = [(simulate_signals(model, truth, s, engine=engine) - s.force)[s.mask] for s in signals]
    r = np.concatenate(res)
    return float(np.sqrt(np.mean(r * r))), same


def run_one(model: str, seed: int, out: Path, engine: str, durations) -> dict:
    row_path = out / f"{model}_{seed}.json"
    if row_path.exists():
        return json.loads(row_path.read_text())
    data = out / "data" / f"{model}_{seed}"
    if data.exists():
        shutil.rmtree(data)
    kw = {} if durations is None else {"durations": durations}
    write_class_dataset(data, model, seed, **kw)
    gen = read_manifest(data)["generator"]
    tests = load_dataset(data)
    settings = FitSettings(models=(model,), engine=engine)
    fit_dir = out / "fits" / f"{model}_{seed}"
    shutil.rmtree(fit_dir, ignore_errors=True)
    fit_dir.mkdir(parents=True)
    t0 = time.perf_counter()
    res = fit([t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"],
              settings, checkpoints=fit_dir / "checkpoints", log=lambda m: None)
    wall = time.perf_counter() - t0
    res.write(fit_dir)
    hist = res.histories[model]
    floor, same_axes = truth_rmse(model, data, settings, "native" if engine == "fmu" else engine)
    row = {"model": model, "seed": seed, "noise_n": gen["noise_n"], "kinds": gen["kinds"],
           "in_band_noise_n": in_band_noise(gen["noise_n"], settings.data.fit_rate_hz),
           "truth_rmse_n": floor, "truth_on_the_tuner_abscissae": same_axes,
           "rmse_n": hist["identification_rmse_n"], "firefly_rmse_n": 1 / math.sqrt(hist["firefly_best_fitness"]),
           "tuner_converged": hist["converged"], "polish_stop": hist["polish_stop"],
           "jacobians": hist.get("polish_jacobians"), "local_refinements": hist.get("local_refinements"),
           "evaluations": hist["evaluation_count"], "identification_s": hist["elapsed_s"], "wall_s": wall}
    row["converged"] = row["rmse_n"] <= RATIO * row["truth_rmse_n"]
    row_path.write_text(json.dumps(row, indent=1))
    shutil.rmtree(fit_dir / "fmu", ignore_errors=True)  # keep the report and histories, not the FMUs
    return row


def summary(rows: list[dict]) -> str:
    def q(xs, p):
        return float(np.percentile(xs, p)) if xs else float("nan")

    lines = []
    for model in sorted({r["model"] for r in rows}):
        rs = [r for r in rows if r["model"] == model]
        ok = [r for r in rs if r["converged"]]
        false_claims = [r for r in rs if r["tuner_converged"] and not r["converged"]]
        unclaimed = [r for r in rs if r["converged"] and not r["tuner_converged"]]
        ratio = [r["rmse_n"] / r["truth_rmse_n"] for r in rs]
        vs_noise = [r["rmse_n"] / r["in_band_noise_n"] for r in rs]
        floor_noise = [r["truth_rmse_n"] / r["in_band_noise_n"] for r in rs]
        lines += [
            f"== {model}: {len(rs)} random dampers of the class",
            f"converged (RMSE <= {RATIO} x the truth's): {len(ok)}/{len(rs)} = {100 * len(ok) / len(rs):.0f} %",
            f"tuner said converged: {sum(r['tuner_converged'] for r in rs)}/{len(rs)}; of them missing the floor "
            f"(false claims): {len(false_claims)}; at the floor but not claimed: {len(unclaimed)}",
            f"RMSE / truth's RMSE: median {q(ratio, 50):.3f}, 90 % {q(ratio, 90):.3f}, max {max(ratio):.3f}",
            f"RMSE / in-band load-cell noise: median {q(vs_noise, 50):.2f}, 90 % {q(vs_noise, 90):.2f}, "
            f"max {max(vs_noise):.2f} (the truth's own: median {q(floor_noise, 50):.2f}, max {max(floor_noise):.2f})",
            f"Firefly alone / truth's RMSE: median {q([r['firefly_rmse_n'] / r['truth_rmse_n'] for r in rs], 50):.1f}",
            f"Jacobians of the winning refinement: median {q([r['jacobians'] for r in rs], 50):.0f}, "
            f"max {max(r['jacobians'] for r in rs)}; evaluations: median {q([r['evaluations'] for r in rs], 50):.0f}",
            f"identification time: median {q([r['identification_s'] for r in rs], 50):.0f} s, "
            f"max {max(r['identification_s'] for r in rs):.0f} s; whole fit (validation, export, report): "
            f"median {q([r['wall_s'] for r in rs], 50):.0f} s",
        ]
        for r in rs:
            if not r["converged"] or not r["tuner_converged"]:
                lines.append(f"   seed {r['seed']}: RMSE {r['rmse_n']:.1f} N, truth {r['truth_rmse_n']:.1f} N, "
                             f"tuner: {r['polish_stop']}")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--model", choices=("lumped", "twochamber"), required=True)
    ap.add_argument("--dampers", type=int, default=30)
    ap.add_argument("--seed-offset", type=int, default=0)
    ap.add_argument("--engine", default="fmu", choices=("fmu", "native", "inprocess"))
    ap.add_argument("--durations", help="test durations [s], comma-separated (default: six drawn in 12-16 s)")
    ap.add_argument("--quick", action="store_true", help="CI size: four tests of 6 s")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "convergence")
    args = ap.parse_args(argv)
    durations = [6.0, 6.0, 6.0, 6.0] if args.quick else (
        [float(x) for x in args.durations.split(",")] if args.durations else None)
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for k in range(args.dampers):
        seed = args.seed_offset + k
        t0 = time.perf_counter()
        r = run_one(args.model, seed, args.out, args.engine, durations)
        rows.append(r)
        print(f"{args.model} seed {seed}: RMSE {r['rmse_n']:7.2f} N, truth {r['truth_rmse_n']:7.2f} N "
              f"(x{r['rmse_n'] / r['truth_rmse_n']:.3f}), in-band noise {r['in_band_noise_n']:5.1f} N, "
              f"Firefly {r['firefly_rmse_n']:7.1f} N, tuner {'converged' if r['tuner_converged'] else 'NOT converged'}, "
              f"{r['jacobians']} Jacobians, {r['identification_s']:.0f} s ({time.perf_counter() - t0:.0f} s)",
              flush=True)
    text = summary(rows)
    print(text)
    (args.out / f"convergence_{args.model}.json").write_text(json.dumps({"rows": rows, "summary": text}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
