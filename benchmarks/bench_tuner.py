"""Benchmark of the tuner: evaluation throughput of the FMU engine and optimisers at equal budgets.

    python benchmarks/bench_tuner.py [--quick] [--no-compare] [--budget 1200] [--engine inprocess]

Data: the bundled dataset (data/default); identification tests at the fit rate (200 Hz, internal
step 1/200 s), 0.5 s warm-up skipped, force limit as tuner.identification.fit derives it. Prints:
  (1) evaluations/s of the lumped FMU engine with 1 and 2 workers on the same batches of random
      candidates (interleaved, pool start-up excluded); target 2 workers / 1 worker >= 1.7;
  (2) the same candidates through a warm fmpy.simulate_fmu + reset, serial, one FMU instance;
      target engine (1 worker) / simulate_fmu >= 2;
  (3) projected wall time of the paper's budget (20 x 151 = 3020 evaluations) with 2 workers, per
      model and for lumped + Maxwell; target < 10 min;
  (4) (--compare) Firefly, scipy differential evolution and CMA-ES at equal evaluation budgets on
      the same scaled space: identification RMSE and validation RMSE/MSE, raw and after the polish.
Medians of interleaved repeats, so machine load hits all variants alike; only ratios measured side
by side are meaningful on a shared machine. Exit status 0 (a report, not a test).
"""
from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_fmu_step import SimulateFmuWay  # noqa: E402
from damper_fmu.fmu import ensure_fmu  # noqa: E402
from damper_fmu import simulate  # noqa: E402
from damper_fmu.parameters import defaults  # noqa: E402
from tuner.identification import firefly  # noqa: E402
from tuner.data.preprocess import prepare  # noqa: E402
from tuner.data.reading import load_dataset  # noqa: E402
from tuner.identification.engine import Engine  # noqa: E402
from tuner.identification.fit import FitSettings, initial_guess  # noqa: E402
from tuner.identification.problem import to_signals  # noqa: E402
from tuner.metrics import error_metrics  # noqa: E402
from tuner.identification.parametrization import Parametrization  # noqa: E402
from tuner.identification.polish import polish  # noqa: E402

FIT_RATE, WARMUP = 200.0, 0.5
PAPER_EVALS = 20 * 151
PENALTY = 1e30  # SSE [N^2] given to the minimisers for a failed simulation


class SimulateFmuCalibration(SimulateFmuWay):
    """Warm simulate_fmu + reset with the candidate's parameters as start values."""

    def run(self, t, x, v, params=None):
        from fmpy import simulate_fmu

        if not self.first:
            self.fmu.reset()
        self.first = False
        # other inputs (e.g. oil_temperature) held at their start values, as the engine leaves them
        extra = {u.name: float(u.start) for u in self.md.modelVariables
                 if u.causality == "input" and u.name not in ("stroke", "stroke_velocity")}
        sig = np.zeros(t.size, dtype=[(n, float) for n in ("time", "stroke", "stroke_velocity", *extra)])
        sig["time"], sig["stroke"], sig["stroke_velocity"] = t, x, v
        for n, value in extra.items():
            sig[n] = value
        h = float(t[1] - t[0])
        start = {"input_interpolation": 1, "max_internal_step": 1.0 / FIT_RATE, **(params or {})}
        res = simulate_fmu(self.unzip, model_description=self.md, fmu_instance=self.fmu, start_time=float(t[0]),
                           stop_time=float(t[-1]), step_size=h, output_interval=h, input=sig,
                           start_values=start, output=["force"], terminate=False)
        return res["force"]

    def sse(self, params, signals) -> float:
        try:
            r = np.concatenate([(s.force - self.run(s.time, s.stroke, s.stroke_velocity, params)[:s.time.size])[s.mask]
                                for s in signals])
        except Exception:  # noqa: BLE001 - a failed candidate counts as inf, as in the engine
            self.fmu.reset()
            return math.inf
        return float(r @ r) if np.all(np.isfinite(r)) else math.inf


def load(data: Path):
    """(identification Signals at the fit rate, validation PreparedTests at their own rate, F_max [N])."""
    tests = load_dataset(data)
    signals = [to_signals(prepare(t, FIT_RATE), WARMUP) for t in tests if t.role == "identification"]
    validation = [prepare(t, t.sample_rate) for t in tests if t.role == "validation"]
    peak = max(float(np.abs(s.force[s.mask]).max()) for s in signals)
    return signals, validation, float(f"{1.5 * peak:.2g}")  # as tuner.identification.fit


def throughput(args, signals) -> dict:
    """Parts 1-3: evaluations/s, interleaved batch by batch; returns the medians [1/s]."""
    rng = np.random.default_rng(args.seed)
    par = {m: Parametrization(m) for m in ("lumped", "maxwell")}
    batches = {m: [[p.to_params(z) for z in rng.random((args.batch, p.dimension))] for _ in range(args.batches + 1)]
               for m, p in par.items()}
    step = 1.0 / FIT_RATE
    engines = {
        "lumped FMU engine, 1 worker": Engine("lumped", signals, engine="fmu", workers=1,
                                              fmu_path=ensure_fmu("lumped"), max_internal_step=step),
        "lumped FMU engine, 2 workers": Engine("lumped", signals, engine="fmu", workers=2,
                                               fmu_path=ensure_fmu("lumped"), max_internal_step=step),
        "maxwell FMU engine, 2 workers": Engine("maxwell", signals, engine="fmu", workers=2,
                                                fmu_path=ensure_fmu("maxwell"), max_internal_step=step),
    }
    warm = SimulateFmuCalibration(ensure_fmu("lumped"))
    variants = {name: (lambda b, e=e: e.sse_batch(b)) for name, e in engines.items()}
    variants["lumped warm simulate_fmu+reset, serial"] = lambda b: np.array([warm.sse(p, signals) for p in b])
    model = {name: ("maxwell" if name.startswith("maxwell") else "lumped") for name in variants}
    sse = {}
    for name, f in variants.items():  # warm-up (pool start-up, imports), batch 0 not timed
        f(batches[model[name]][0])
    rates = {name: [] for name in variants}
    for i in range(1, args.batches + 1):
        for name, f in variants.items():
            t0 = time.perf_counter()
            sse[name, i] = f(batches[model[name]][i])
            rates[name].append(args.batch / (time.perf_counter() - t0))
    for e in engines.values():
        e.close()
    warm.close()
    med = {k: statistics.median(v) for k, v in rates.items()}
    print(f"\n(1-2) evaluations per second, lumped model, {len(signals)} identification tests, "
          f"{sum(s.time.size for s in signals)} samples at {FIT_RATE:g} Hz, internal step 1/{FIT_RATE:g} s;")
    print(f"      median of {args.batches} interleaved batches of {args.batch} random candidates "
          f"(load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores):")
    for name, value in med.items():
        print(f"  {name:42s} {value:7.2f} eval/s  ({1e3 / value:6.1f} ms per evaluation)")
    a, b = sse[next(iter(engines)), 1], sse["lumped warm simulate_fmu+reset, serial", 1]
    ok = np.isfinite(a) & np.isfinite(b)
    print(f"  check: SSE engine vs simulate_fmu on batch 1, median relative difference "
          f"{np.median(np.abs(b[ok] / a[ok] - 1)) if ok.any() else float('nan'):.2g} "
          f"({int(ok.sum())}/{a.size} candidates finite in both; simulate_fmu applies start-of-step inputs)")
    out = {"1w": med["lumped FMU engine, 1 worker"], "2w": med["lumped FMU engine, 2 workers"],
           "sim": med["lumped warm simulate_fmu+reset, serial"], "mx2w": med["maxwell FMU engine, 2 workers"]}
    out["par_ratio"], out["sim_ratio"] = out["2w"] / out["1w"], out["1w"] / out["sim"]
    print(f"  2 workers / 1 worker (target >= 1.7):              {out['par_ratio']:5.2f}")
    print(f"  engine 1 worker / simulate_fmu (target >= 2):      {out['sim_ratio']:5.2f}")
    polish_evals = {m: FitSettings().polish_jacobians * (par[m].dimension + 1) for m in par}
    out["t_lumped"], out["t_maxwell"] = PAPER_EVALS / out["2w"], PAPER_EVALS / out["mx2w"]
    out["t_both"] = out["t_lumped"] + out["t_maxwell"]
    t_pol = out["t_both"] + polish_evals["lumped"] / out["2w"] + polish_evals["maxwell"] / out["mx2w"]
    print(f"\n(3) projected wall time of the paper's budget ({PAPER_EVALS} evaluations per model), 2 workers:")
    print(f"  lumped {out['t_lumped'] / 60:5.1f} min, Maxwell {out['t_maxwell'] / 60:5.1f} min, "
          f"together {out['t_both'] / 60:5.1f} min (target < 10 min); with the default polish "
          f"(+{polish_evals['lumped']} / +{polish_evals['maxwell']} evaluations) {t_pol / 60:5.1f} min")
    return out


def validate(params, validation) -> list[tuple[float, float]]:
    """(RMSE [N], MSE [N^2]) of each validation test at its own rate after the warm-up."""
    out = []
    for p in validation:
        mask = (p.time - p.time[0]) >= WARMUP
        try:
            m = error_metrics(p.force[mask], simulate("lumped", p.time, p.stroke, p.stroke_velocity,
                                                      params=params)[mask])
            out.append((m.rmse, m.mse))
        except Exception:  # noqa: BLE001 - a failed validation run is reported as nan
            out.append((math.nan, math.nan))
    return out


def compare(args, signals, validation, force_limit) -> list[dict]:
    """Part 4: Firefly, DE and CMA-ES at equal budgets, each followed by the same polish."""
    import cma
    from scipy.optimize import differential_evolution

    par = Parametrization("lumped", "improved", force_limit=force_limit)
    d, budget = par.dimension, args.budget
    z_seed = par.from_params(initial_guess("lumped", signals, par))
    fmu_path = ensure_fmu("lumped") if args.engine == "fmu" else None
    rows = []
    with Engine("lumped", signals, engine=args.engine, workers=args.workers, fmu_path=fmu_path,
                max_internal_step=1.0 / FIT_RATE) as eng:
        eng.sse_batch([par.to_params(z_seed)] * max(args.workers, 1))  # pool start-up outside the timings

        def sse(Z):
            s = eng.sse_batch([par.to_params(z) for z in Z])
            return np.where(np.isfinite(s), s, PENALTY)

        def run_firefly():
            opts = firefly.FireflyOptions(population=20, max_iterations=budget // 20 - 1, stop_tol=None)
            init = np.array([z_seed, par.from_params(defaults("lumped"))])
            return firefly.run(lambda Z: eng.fitness_batch([par.to_params(z) for z in Z]), d,
                               options=opts, seed=args.seed, initial=init, max_evaluations=budget).x_best

        def run_de():
            n_pop = d  # popsize multiplier 1: the smallest population scipy allows without a custom init
            res = differential_evolution(lambda X: sse(X.T), [(0.0, 1.0)] * d, popsize=1,
                                         maxiter=budget // n_pop - 1, tol=0.0, atol=0.0, polish=False,
                                         rng=args.seed, x0=z_seed, vectorized=True, updating="deferred")
            return res.x

        def run_cma():
            es = cma.CMAEvolutionStrategy(z_seed, 0.2, {"bounds": [0.0, 1.0], "popsize": 20, "seed": args.seed + 1,
                                                        "maxfevals": budget, "verbose": -9})
            used = 0
            while not es.stop() and used + 20 <= budget:
                X = es.ask()
                es.tell(X, list(sse(np.array(X))))
                used += 20
            return np.clip(es.result.xbest, 0.0, 1.0)

        for name, runner in (("Firefly", run_firefly), ("DE (scipy)", run_de), ("CMA-ES", run_cma)):
            e0, t0 = eng.evaluations, time.perf_counter()
            z = runner()
            r = {"name": name, "evals": eng.evaluations - e0, "time": time.perf_counter() - t0}
            r["rmse"] = math.sqrt(float(sse([z])[0]) / eng.n_samples)
            e1, t1 = eng.evaluations, time.perf_counter()
            polished = polish(eng, par, z, max_jacobians=args.polish, log=lambda *_: None)
            zp, g = polished.z, polished.fitness
            r.update(polish_evals=eng.evaluations - e1, polish_time=time.perf_counter() - t1,
                     rmse_polished=1.0 / math.sqrt(g) if g > 0 else math.inf)
            r["val"], r["val_polished"] = validate(par.to_params(z), validation), validate(par.to_params(zp), validation)
            rows.append(r)
            print(f"  {name}: done ({r['evals']} + {r['polish_evals']} evaluations, "
                  f"{r['time'] + r['polish_time']:.0f} s)", flush=True)
    names = [p.name.split("_")[0] for p in validation]
    head = f"  {'optimiser':22s} {'evals':>6s} {'time s':>7s} {'id RMSE N':>10s}" + "".join(
        f" {n + ' RMSE N (MSE N^2)':>26s}" for n in names)
    print(f"\n(4) lumped model, equal budgets of {budget} evaluations ({args.engine} engine, {args.workers} workers, "
          f"seed {args.seed}; scaled space of Parametrization('lumped', 'improved', force_limit={force_limit:g}))"
          f"\n    polish: tuner.identification.polish.polish, {args.polish} Jacobians; validation at each test's own rate")
    print(head)
    for r in rows:
        for tag, ev, tm, rm, val in (("", r["evals"], r["time"], r["rmse"], r["val"]),
                                     (" + polish", r["evals"] + r["polish_evals"], r["time"] + r["polish_time"],
                                      r["rmse_polished"], r["val_polished"])):
            print(f"  {r['name'] + tag:22s} {ev:6d} {tm:7.1f} {rm:10.1f}"
                  + "".join(f" {rv:12.1f} ({mv:11.4g})" for rv, mv in val))
    print("  (one seed: differences of a few percent are within run-to-run scatter)")
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=ROOT / "data" / "default", help="dataset folder")
    ap.add_argument("--batches", type=int, default=3, help="timed batches per variant (parts 1-2)")
    ap.add_argument("--batch", type=int, default=20, help="candidates per batch (parts 1-2)")
    ap.add_argument("--compare", action=argparse.BooleanOptionalAction, default=True,
                    help="run the optimiser comparison (part 4)")
    ap.add_argument("--budget", type=int, default=1200, help="evaluations per optimiser (part 4)")
    ap.add_argument("--engine", choices=("inprocess", "fmu"), default="inprocess", help="engine of part 4")
    ap.add_argument("--workers", type=int, default=2, help="worker processes of part 4")
    ap.add_argument("--polish", type=int, default=10, help="Jacobians of the polish (part 4)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--quick", action="store_true", help="smoke run: tiny batches and budget")
    args = ap.parse_args(argv)
    if args.quick:
        args.batches, args.batch, args.budget, args.polish = 1, 4, min(args.budget, 120), 2
    if args.budget < 2 * 29 or args.batch < 1 or args.batches < 1:
        raise ValueError("--budget must be >= 58 (two DE generations), --batch and --batches >= 1")
    signals, validation, force_limit = load(args.data)
    t = throughput(args, signals)
    rows = compare(args, signals, validation, force_limit) if args.compare else []
    print("\nFIGURES FOR THE NOTE")
    print(f"  lumped FMU engine at {FIT_RATE:g} Hz: {t['1w']:.2f} eval/s (1 worker), {t['2w']:.2f} eval/s "
          f"(2 workers): x{t['par_ratio']:.2f} (target >= 1.7)")
    print(f"  warm simulate_fmu + reset: {t['sim']:.2f} eval/s; our engine (1 worker) is x{t['sim_ratio']:.2f} "
          f"faster (target >= 2)")
    print(f"  paper budget {PAPER_EVALS} evaluations, 2 workers: lumped {t['t_lumped'] / 60:.1f} min, "
          f"Maxwell {t['t_maxwell'] / 60:.1f} min, both {t['t_both'] / 60:.1f} min (target < 10 min)")
    for r in rows:
        val = ", ".join(f"{m:.3g}" for _, m in r["val"])
        valp = ", ".join(f"{m:.3g}" for _, m in r["val_polished"])
        print(f"  {r['name']:10s} {r['evals']} evals: id RMSE {r['rmse']:.1f} N, val MSE [{val}] N^2; "
              f"+ polish ({r['polish_evals']}): {r['rmse_polished']:.1f} N, [{valp}] N^2")
    return 0


if __name__ == "__main__":
    sys.exit(main())
