"""Does the default fit reach the best point the data allow? The default beside longer global stages.

    python benchmarks/global_stage.py --mr ../shared/realdata/mr-damper-0.5A [--models twochamber,lumped]
    python benchmarks/global_stage.py --class-seed 3 --models twochamber [--quick]
    [--variants default,paper,random,cma] [--cma-evaluations 4000] [--out DIR]

For each model it identifies the same data several ways, each through the same FMU engine and workers:

* ``default``: the tuner's fit (``tuner.identification.fit.identify`` with ``FitSettings()``): the seeded
  Firefly with its stop rule, the refinements and the restart check;
* ``paper``: the Firefly as printed, its whole budget (150 iterations, ``stop_tol=None``), then the same
  refinements and check;
* ``random``: the same without the seeded fireflies (``init='random'``);
* ``cma``: a long CMA-ES run (``cma``, bounded in the scaled space, from the data-driven start, population
  16, ``--cma-evaluations`` simulations), then one refinement: an independent global method as a reference.

It prints per model the identification RMSE [N] of each, its distance from the best of them in standard errors
of the RMSE (``tuner.metrics.rmse_standard_error`` at the default's point), its wall time [s] and whether the
tuner called it converged. The default should be within one standard error of the best.

``--mr DIR``: an MR damper folder of the shared real data (``sine/`` with six tests named
``<amplitude>mm<frequency>Hz<current>.txt``): identification on the 0.1, 0.5 and 3 Hz tests, the lab's moving
average declared per file as on the "Real data" page. ``--class-seed N``: a random damper of the model's class
(``campaign.damper_class``), its four identification tests (``--quick``: 6 s tests).
"""
from __future__ import annotations

import argparse
import json
import math
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from damper_fmu.fmu import ensure_fmu  # noqa: E402
from tuner.data.read_options import ReadOptions  # noqa: E402
from tuner.data.reading import load_dataset, load_files  # noqa: E402
from tuner.identification.engine import Engine  # noqa: E402
from tuner.identification.fit import FitSettings, identify, initial_guess  # noqa: E402
from tuner.identification.polish import polish  # noqa: E402
from tuner.identification.problem import DataSettings, Problem  # noqa: E402
from tuner.metrics import rmse_standard_error  # noqa: E402

#: the lab smoothed each sine test with a causal moving average over a tenth of its period (docs/real-data.md)
MR_IDENTIFICATION = ("25mm0x1Hz", "25mm0x5Hz", "5mm3Hz")
MR_OPTIONS = ReadOptions(time_col=1, stroke_col=2, force_col=4, stroke_unit="mm", force_unit="N", damper_class="any")


def mr_tests(folder: Path) -> list:
    """The MR damper's identification tests of ``folder`` (its ``sine/``), the lab's filter declared per file."""
    tests = []
    for stem in MR_IDENTIFICATION:
        path = next((folder / "sine").glob(f"{stem}*.txt"), None)
        if path is None:
            raise SystemExit(f"{folder / 'sine'}: no test {stem}*.txt (expected the shared MR damper's layout)")
        hz = float(re.match(r"\d+mm([\dx]+)Hz", path.name).group(1).replace("x", "."))
        window = max(1, round(1000.0 / (10.0 * hz)))  # a tenth of the period at the lab's 1 kHz
        tests += load_files([path], "identification", MR_OPTIONS.merged(prefilter=f"moving-average:{window}@1000"))
    return tests


def class_tests(model: str, seed: int, quick: bool, scratch: Path) -> list:
    from campaign.damper_class import write_class_dataset

    kwargs = {"durations": (6.0, 6.0, 6.0, 6.0)} if quick else {}
    folder = write_class_dataset(scratch / f"{model}-{seed}", model, seed, **kwargs)
    return [t for t in load_dataset(folder) if t.role == "identification"]


def run_identify(model: str, problem: Problem, settings: FitSettings, scratch: Path) -> dict:
    par = problem.parametrization(model)
    t0 = time.perf_counter()
    found = identify(model, problem.sig_id, settings, par, scratch / f"{model}-{time.time_ns()}.json", problem.digest,
                     lambda m: None)
    h = found.history
    return {"rmse_n": h["best_fitness_final"] ** -0.5, "seconds": time.perf_counter() - t0,
            "converged": h["converged"], "values": found.values,
            "search": f"{h['stop_reason']} after {h['iterations']}"}


def run_cma(model: str, problem: Problem, evaluations: int, workers: int) -> dict:
    import cma

    par = problem.parametrization(model)
    x0 = np.clip(par.from_params(initial_guess(model, problem.sig_id, par)), 0.01, 0.99)
    t0 = time.perf_counter()
    with Engine(model, problem.sig_id, engine="fmu", workers=workers, fmu_path=ensure_fmu(model)) as eng:
        es = cma.CMAEvolutionStrategy(list(x0), 0.2, {"bounds": [0, 1], "seed": 1, "maxfevals": evaluations,
                                                      "verbose": -9, "popsize": 16})
        best_sse, best_x = math.inf, x0
        while not es.stop():
            X = es.ask()
            sse = np.asarray(eng.sse_batch([par.to_params(x) for x in X]), dtype=float)
            sse = np.where(np.isfinite(sse), sse, 1e30)
            es.tell(X, list(sse))
            if sse.min() < best_sse:
                best_sse, best_x = float(sse.min()), np.asarray(X[int(np.argmin(sse))])
        pol = polish(eng, par, best_x, max_jacobians=100, log=lambda m: None)
    return {"rmse_n": pol.fitness ** -0.5, "seconds": time.perf_counter() - t0, "converged": pol.converged,
            "values": par.to_params(pol.z), "search": f"CMA-ES {es.countevals} evaluations"}


def standard_error(model: str, problem: Problem, values: dict) -> float:
    with Engine(model, problem.sig_id, engine="fmu", workers=0, fmu_path=ensure_fmu(model)) as eng:
        return rmse_standard_error(eng.residuals_batch([values])[0])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--mr", type=Path, help="a shared MR damper folder (with sine/)")
    src.add_argument("--class-seed", type=int, help="a random damper of the (first) model's class")
    ap.add_argument("--models", default="twochamber,lumped")
    ap.add_argument("--variants", default="default,paper,random,cma")
    ap.add_argument("--cma-evaluations", type=int, default=4000)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="class damper: 6 s tests")
    ap.add_argument("--out", type=Path, help="write the rows as JSON here")
    args = ap.parse_args(argv)
    models, variants = args.models.split(","), args.variants.split(",")
    rows = []
    with tempfile.TemporaryDirectory(prefix="global-stage-") as tmp:
        scratch = Path(tmp)
        tests = mr_tests(args.mr) if args.mr else class_tests(models[0], args.class_seed, args.quick, scratch)
        problem = Problem.build(tests, [], DataSettings())
        label = args.mr.name if args.mr else f"{models[0]} class seed {args.class_seed}"
        for model in models:
            done = {}
            for variant in variants:
                if variant == "cma":
                    done[variant] = run_cma(model, problem, args.cma_evaluations, args.workers)
                else:
                    extra = {"paper": {"stop_tol": None}, "random": {"stop_tol": None, "init": "random"}}
                    settings = FitSettings(models=(model,), workers=args.workers, **extra.get(variant, {}))
                    done[variant] = run_identify(model, problem, settings, scratch)
                print(f"  {label} {model} {variant}: {done[variant]['rmse_n']:.3f} N, {done[variant]['seconds']:.0f} s",
                      flush=True)
            se = standard_error(model, problem, done.get("default", next(iter(done.values())))["values"])
            best = min(r["rmse_n"] for r in done.values())
            for variant, r in done.items():
                rows.append({"data": label, "model": model, "variant": variant, "rmse_n": r["rmse_n"],
                             "standard_error_n": se, "above_best_se": (r["rmse_n"] - best) / se,
                             "seconds": r["seconds"], "converged": r["converged"], "search": r["search"]})
    print("\n| data | model | variant | RMSE [N] | above the best [standard errors] | wall [s] | converged | search |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        print(f"| {r['data']} | {r['model']} | {r['variant']} | {r['rmse_n']:.2f} | {r['above_best_se']:.1f} | "
              f"{r['seconds']:.0f} | {'yes' if r['converged'] else 'no'} | {r['search']} |")
    if args.out:
        args.out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
