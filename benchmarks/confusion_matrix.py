"""Confusion matrix of the diagnosis: hidden effects on the virtual rig vs the cause it names.

    python benchmarks/confusion_matrix.py [--seeds 3] [--t-end 6] [--damper lumped|twin-tube]
                                          [--chamber] [--out results/confusion]
                                          [--scheduler pool | pool:N | local:N | tcp://HOST:PORT]

For every catalogue effect, every form beyond it (``--effects none,hysteresis,bypass``: the rig's own
Bouc-Wen pre-yield element and rebound bypass groove, ``campaign.effects.FORMS``; the diagnosis's forms
are a Dahl element and a scaled groove, other equations) and for clean data, ``--seeds`` datasets are
generated with the virtual rig (a new dataset seed each time; the effect magnitude drawn uniformly inside its documented
range with a seeded generator and never passed to the diagnosis), the diagnosis runs blind
(in-process engine: the same equations as the FMU), and the named cause is recorded. Prints the
confusion matrix, the detection rate per effect, the false-cause rate on clean data and the
magnitude error of correct detections. Writes confusion.json.

For a hidden effect the same seed's clean dataset is generated too (the same strokes and sensor
noise): their difference is the force the effect adds [N rms] on the identification and on the
validation tests, printed beside the measured noise. The decision is the held-out gain, so a run
whose effect moves the validation force by less than the noise cannot be named; the detection
rate is also given without those runs.

The runs are independent and go to the fleet executor of ``tuner.executors`` (one run = one task):
by default a local process pool of ``os.cpu_count()`` processes, ``--scheduler local:N`` a Dask
LocalCluster, ``--scheduler tcp://HOST:PORT`` a running Dask cluster (so a cluster can run the
large matrix). Each run evaluates in its own process (``--workers 0``). The dataset seed and the
drawn magnitude of every run are fixed before anything is scheduled (the same as when the runs
went one after the other), so the matrix does not depend on the executor or the completion order.

``--damper lumped`` mounts a damper the base model represents exactly (no model-form error);
``twin-tube`` the physical damper (a model-form error of ~3 % of peak force remains). ``--chamber``
runs every manoeuvre at its own oil temperature (``CHAMBER_TEMPERATURES_C``), as in a climatic
chamber; it is the same campaign design for every row, clean data included.
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from campaign.effects import FORMS, SPECS  # noqa: E402
from campaign.generate import CHAMBER_TEMPERATURES_C, CampaignPlan, generate_dataset  # noqa: E402
from tuner.data.reading import load_dataset  # noqa: E402
from tuner.identification.engine import fastest_engine  # noqa: E402
from tuner.executors import FleetExecutor  # noqa: E402
from tuner.results.fleet_summary import write_atomic  # noqa: E402
from damper_fmu.effect_catalogue import FORM_EFFECTS  # noqa: E402
from tuner.diagnosis.diagnose import CANDIDATES, DiagnosisSettings, diagnose  # noqa: E402


def effect_force_n(tests, clean, role: str) -> float:
    """Force [N rms] a hidden effect adds to the measured force: the dataset minus the same seed's
    clean one (same strokes, same sensor noise), pooled over the tests of ``role``."""
    se = n = 0.0
    for a, b in zip(tests, clean):
        if a.role == role:
            d = a.force - b.force
            se, n = se + float(d @ d), n + d.size
    return (se / n) ** 0.5


def run_case(case: dict) -> dict:
    """One blind diagnosis: generate the case's dataset, diagnose it, return the result row."""
    truth, effects = case["truth"], case["effects"]
    tmp = Path(tempfile.mkdtemp(prefix="confusion_"))
    try:
        t0 = time.perf_counter()
        plan = CampaignPlan(t_end=case["t_end"], oil_temperatures=CHAMBER_TEMPERATURES_C if case["chamber"] else None)
        data = generate_dataset(tmp / "data", seed=case["seed"], effects=effects, damper=case["damper"], plan=plan,
                                log=lambda m: None)
        tests = load_dataset(data)
        effect_force = {}
        if truth != "none":  # what the hidden effect does to the measured force: the same seed without it
            clean = load_dataset(generate_dataset(
                tmp / "clean", seed=case["seed"], effects={}, damper=case["damper"], plan=plan, log=lambda m: None))
            effect_force = {r: effect_force_n(tests, clean, r) for r in ("identification", "validation")}
        res = diagnose([t for t in tests if t.role == "identification"],
                       [t for t in tests if t.role == "validation"],
                       DiagnosisSettings(engine=fastest_engine(), workers=case["workers"], base_iterations=0),
                       log=lambda m: None)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    row = {"truth": truth, "magnitude": effects.get(truth), "named": res["cause"],
           "causes": res["causes"], "extra_causes": [c for c in res["causes"][1:] if c != truth],
           "unexplained_ratio": (res.get("unexplained") or {}).get("ratio"),
           "score": res["ranking"][0]["score"], "elapsed_s": time.perf_counter() - t0, "seed": case["seed"],
           "screen": res["evidence"]["joint_screen"]["kept"], "base": res["base_model"],
           "effect_force_id_n": effect_force.get("identification"),
           "effect_force_val_n": effect_force.get("validation"), "noise_n": res["noise_std_n"],
           "first_base": (res.get("base_choice") or {}).get("first_choice", res["base_model"])}
    row["form"] = res.get("form")
    row["forms_tried"] = {r["added"]: {"score": r["score"], "mse_change_pct": r["validation_mse_change_pct"],
                                       "excess_explained": r.get("excess_explained"), "parameters": r["parameters"],
                                       "settings": r.get("settings")} for r in res.get("forms_tried") or []}
    if truth in FORMS:  # the form's fitted magnitude; a bypass ratio is no multiple of the rig's groove area
        tried = next((r for r in res.get("forms_tried") or [] if r["added"] == truth), None)
        name = FORMS[truth].model_parameter
        row["fitted"] = tried["parameters"][name] if tried else float("nan")
        row["relative_error"] = (row["fitted"] / (FORMS[truth].model_sign * effects[truth]) - 1.0
                                 if truth == "hysteresis" else float("nan"))
        row["mse_change_pct"] = tried["validation_mse_change_pct"] if tried else float("nan")
    elif truth != "none":
        name, factor = SPECS[truth].model_parameter, SPECS[truth].model_sign
        ext = next(r for r in res["ranking"] if r["effect"] == truth)
        row["fitted"] = ext["parameters"][name]
        row["relative_error"] = ext["parameters"][name] / (factor * effects[truth]) - 1.0
        row["mse_change_pct"] = ext["validation_mse_change_pct"]
    return row


def _arguments(argv) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--t-end", type=float, default=6.0, help="duration of each scenario [s] (None: full)")
    ap.add_argument("--workers", type=int, default=0,
                    help="evaluation processes inside each run (default 0: in the run's own process; the runs are "
                         "the parallel level)")
    ap.add_argument("--scheduler", default=None, metavar="SPEC",
                    help="pool (default, os.cpu_count() processes), pool:N, local:N (Dask LocalCluster) or a Dask "
                         "scheduler address tcp://HOST:PORT")
    ap.add_argument("--damper", choices=("twin-tube", "lumped"), default="twin-tube",
                    help="damper on the virtual rig (campaign.rig.DAMPERS)")
    ap.add_argument("--chamber", action="store_true", help="each manoeuvre at its own oil temperature")
    ap.add_argument("--effects", default=",".join(["none", *CANDIDATES]))
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "confusion")
    ap.add_argument("--seed-offset", type=int, default=0,
                    help="shifts every dataset seed and the magnitude draws: new seeds for a rerun (default 0)")
    return ap.parse_args(argv)


def _cases(a: argparse.Namespace, truths: list[str]) -> list[dict]:
    """The runs, in the order of the sequential benchmark: the same seeds and magnitudes."""
    rng = np.random.default_rng(20231121 + a.seed_offset)
    cases = []
    for truth in truths:
        for k in range(a.seeds):
            effects = {}
            if truth != "none":
                spec = SPECS[truth]
                effects[truth] = float(rng.uniform(spec.low, spec.high))
            cases.append({"truth": truth, "effects": effects, "seed": 1000 + a.seed_offset + 17 * k + 3 * len(cases),
                          "t_end": a.t_end, "damper": a.damper, "chamber": a.chamber, "workers": a.workers})
    return cases


def _row_line(row: dict) -> str:
    """One run's line: hidden, named, score, magnitude, forces, forms, screen, base, time."""
    truth = row["truth"]
    return (f"{truth:14s} {row['magnitude'] if row['magnitude'] is not None else '':>12}  -> "
            f"{'+'.join(row['causes']) or row['named']:14s} score {row['score']:+.3f}" +
            (f"  fitted {row['fitted']:.4g} ({100 * row['relative_error']:+.0f} %), "
             f"MSE {row['mse_change_pct']:+.1f} %" if truth != "none" else "")
            + (f"  effect force {row['effect_force_id_n']:.3g} / {row['effect_force_val_n']:.3g} N "
               f"(identification / validation; noise {row['noise_n']:.3g} N)"
               if row.get("effect_force_val_n") is not None else "")
            + "".join(f"  form {k} {v['mse_change_pct']:+.0f} % "
                      f"({100 * (v['excess_explained'] or 0):.0f} % of the excess)"
                      for k, v in row["forms_tried"].items())
            + f"  screen {'+'.join(row['screen']) or '-'}  base {row['base']}"
            + (f" (first {row['first_base']})" if row["first_base"] != row["base"] else "")
            + f"  [{row['elapsed_s']:.0f} s]")


def _summary(rows: list[dict], truths: list[str], matrix: dict) -> dict:
    """Per hidden effect: runs, named right, rate, median magnitude error, runs below the noise, joint screen's
    top term right; printed as it goes."""
    print("\ndetection rate per effect (target >= 95 %), clean data named none or unexplained:")
    summary = {}
    for t in truths:
        n = sum(matrix[t].values())
        ok = matrix[t][t] + (matrix[t]["unexplained"] if t == "none" else 0)
        errs = [abs(r["relative_error"]) for r in rows if r["truth"] == t and r["named"] == t and t != "none"
                and np.isfinite(r["relative_error"])]
        summary[t] = {"runs": n, "correct": ok, "rate": ok / n if n else float("nan"),
                      "median_magnitude_error": float(np.median(errs)) if errs else None}
        extra = f", median |magnitude error| {100 * np.median(errs):.0f} %" if errs else ""
        label = "clean (no false cause)" if t == "none" else t
        # runs whose hidden effect moves the held-out force by less than the noise: the decision is the
        # held-out gain, so no such run can be named
        weak = [r for r in rows if r["truth"] == t and t != "none" and (r.get("effect_force_val_n") or 0.0) < r["noise_n"]]
        summary[t]["below_noise_runs"] = len(weak)
        if weak:
            n_ok = sum(1 for r in weak if r["named"] == t)
            extra += (f"; {len(weak)} runs with the effect's held-out force below the noise ({n_ok} named), "
                      f"{ok - n_ok}/{n - len(weak)} of the others")
        print(f"  {label:24s} {ok}/{n} = {100 * ok / n:.0f} %{extra}")
    # the joint screen (residual on all catalogue signatures at once, before any refit): how often its
    # largest kept term is the hidden effect, and how often it keeps a term on clean data
    print("\njoint screen before the refits: largest kept term = hidden effect (clean: nothing kept)")
    for t in truths:
        rs = [r for r in rows if r["truth"] == t]
        hit = sum(1 for r in rs if (r["screen"][:1] == [t] if t != "none" else not r["screen"]))
        summary[t]["screen_top_correct"] = hit
        print(f"  {t:24s} {hit}/{len(rs)}")
    return summary


def main(argv=None) -> int:
    a = _arguments(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    truths = [e.strip() for e in a.effects.split(",")]
    cases = _cases(a, truths)
    done = {}
    with FleetExecutor(a.scheduler) as ex:
        print(f"{len(cases)} blind diagnoses on a {ex.description}", flush=True)
        for i, row, err in ex.run(run_case, cases):
            if err is not None:
                raise RuntimeError(f"run {i} ({cases[i]['truth']}, seed {cases[i]['seed']}) failed: {err}") from err
            done[i] = row
            print(_row_line(row), flush=True)
    rows = [done[i] for i in range(len(cases))]
    write_atomic(a.out / "confusion.json", json.dumps({"rows": rows}, indent=1))
    labels = ["none", "unexplained", *CANDIDATES, *FORM_EFFECTS]
    matrix = {t: {n: sum(1 for r in rows if r["truth"] == t and r["named"] == n) for n in labels} for t in truths}
    print("\nconfusion matrix (rows: hidden effect, columns: named cause)")
    print(" " * 15 + "".join(f"{n[:9]:>10}" for n in labels))
    for t in truths:
        print(f"{t:15s}" + "".join(f"{matrix[t][n]:10d}" for n in labels))
    wrong = [r for r in rows if r["named"] not in ("none", "unexplained", r["truth"]) or r["extra_causes"]]
    print(f"\nfalse causes (a named effect that was not hidden, first or added): {len(wrong)}/{len(rows)} runs"
          + "".join(f"\n  {r['truth']} -> {'+'.join(r['causes'])}" for r in wrong))
    summary = _summary(rows, truths, matrix)
    write_atomic(a.out / "confusion.json", json.dumps({"rows": rows, "matrix": matrix, "summary": summary,
                                                      "false_cause_runs": len(wrong)}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
