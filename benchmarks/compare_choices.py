"""Are our departures from the paper better? Paper procedure vs ours, same budget, same data.

    python benchmarks/compare_choices.py [--iterations 150] [--out results/compare_choices]

Runs the lumped-model identification on the bundled dataset four ways, all with the paper's
Firefly (population 20, same seed, same evaluation budget):
  paper      : linear scaling of every parameter (k_B, c_B over seven decades), independent table
               ordinates, random initial population (the paper's procedure);
  +log+mono  : our 'improved' parametrization (log-scaled k_B/c_B, monotone slope-parametrised
               tables), random initial population;
  +seeded    : improved parametrization and a seeded initial population (data-driven guess + preset);
and each of them followed by the least-squares polish. Prints the identification and validation
RMSE of every variant and writes a figure (fitness histories, validation RMSE bars).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from damper_fmu import simulate  # noqa: E402
from tuner.data.preprocess import prepare  # noqa: E402
from tuner.data.reading import load_dataset  # noqa: E402
from tuner.identification.fit import FitSettings, identify  # noqa: E402
from tuner.identification.problem import DataSettings, to_signals  # noqa: E402
from tuner.identification.parametrization import Parametrization  # noqa: E402

VARIANTS = {"paper": ("paper", "random"), "+log+mono": ("improved", "random"), "+seeded": ("improved", "seeded")}


def validation_rmse(params, tests, warmup):
    errs = []
    for t in tests:
        p = prepare(t, t.sample_rate)
        m = (p.time - p.time[0]) >= warmup
        f = simulate("lumped", p.time, p.stroke, p.stroke_velocity, params=params)
        errs.append(float(np.sqrt(np.mean((p.force - f)[m] ** 2))))
    return errs


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--iterations", type=int, default=150)
    ap.add_argument("--polish", type=int, default=15)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--engine", default="inprocess", choices=["inprocess", "fmu"])
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "compare_choices")
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    tests = load_dataset(ROOT / "data" / "default")
    ident = [t for t in tests if t.role == "identification"]
    valid = [t for t in tests if t.role == "validation"]
    sig = [to_signals(prepare(t, 200.0), 0.5) for t in ident]
    peak = max(float(np.abs(s.force[s.mask]).max()) for s in sig)
    results = {}
    for name, (scheme, init) in VARIANTS.items():
        par = Parametrization("lumped", scheme, force_limit=float(f"{1.5 * peak:.2g}"))
        settings = FitSettings(models=("lumped",), data=DataSettings(parametrization=scheme), iterations=a.iterations,
                               workers=a.workers, engine=a.engine, init=init, stop_tol=None, polish_jacobians=a.polish)
        ckpt = a.out / f"ckpt_{name.replace('+', 'p')}.json"
        ckpt.unlink(missing_ok=True)
        t0 = time.perf_counter()
        found = identify("lumped", sig, settings, par, ckpt, "compare", lambda m: None)
        best, hist = found.values, found.history
        firefly_best = hist["firefly_best_fitness"]
        failed = sum(1 for g in hist["mean_fitness"] if g == 0.0)
        results[name] = {"history": hist["best_fitness"],
                         "firefly_rmse": 1 / math.sqrt(firefly_best) if firefly_best > 0 else math.inf,
                         "polished_rmse": (1 / math.sqrt(hist["best_fitness_final"])
                                           if hist["best_fitness_final"] > 0 else math.inf),
                         "generations_without_any_simulable_candidate": failed,
                         "validation_rmse": (validation_rmse(best, valid, 0.5) if firefly_best > 0
                                             else [math.inf] * len(valid)),
                         "elapsed_s": time.perf_counter() - t0}
        r = results[name]
        print(f"{name:10s} Firefly RMSE {r['firefly_rmse']:7.1f} N -> polished {r['polished_rmse']:7.1f} N; "
              f"validation RMSE " + " / ".join(f"{e:.0f}" for e in r["validation_rmse"]) + f" N ({r['elapsed_s']:.0f} s)"
              f"; generations with no simulable candidate: {r['generations_without_any_simulable_candidate']}",
              flush=True)
    (a.out / "compare_choices.json").write_text(json.dumps(results, indent=1))
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 4))
    FigureCanvasAgg(fig)
    ax1, ax2 = fig.subplots(1, 2)
    for name, r in results.items():
        h = np.asarray(r["history"])
        if np.any(h > 0):
            ax1.semilogy(np.where(h > 0, 1 / np.sqrt(np.maximum(h, 1e-300)), np.nan), label=name)
        else:
            ax1.plot([], [], label=f"{name}: no candidate could be simulated")
    ax1.set_xlabel("Firefly generation")
    ax1.set_ylabel("best identification RMSE [N] (= 1/sqrt(G))")
    ax1.set_title("Firefly search, same budget and seed")
    ax1.legend()
    ax1.grid(alpha=0.3)
    names = list(results)
    x = np.arange(len(valid))
    w = 0.8 / len(names)
    for i, name in enumerate(names):
        vals = [v if np.isfinite(v) else 0.0 for v in results[name]["validation_rmse"]]
        ax2.bar(x + i * w, vals, w, label=f"{name} (+ polish)" + ("" if any(vals) else ": failed"))
    ax2.set_xticks(x + 0.4 - w / 2, [t.name for t in valid], fontsize=8)
    ax2.set_ylabel("validation RMSE [N]")
    ax2.set_title("After the least-squares polish")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(a.out / "compare_choices.png", dpi=100)
    print(f"figure: {a.out / 'compare_choices.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
