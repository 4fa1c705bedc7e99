"""Blind diagnoses of random dampers of the model classes with a hidden free play or form gap.

    python benchmarks/blind_class.py [--seeds 3] [--cases free_play_soft,free_play_stiff,bypass,none]
                                     [--model lumped|twochamber] [--noise 25] [--out results/blind_class]
                                     [--scheduler pool | pool:N | local:N | tcp://HOST:PORT]

Each run draws a damper of the class (``campaign.damper_class.random_damper``: unlike the preset),
six tests of 12-16 s at 500 Hz with ``--noise`` N rms on the force (``class_tests``), hides one effect
in the model that makes the data and runs the diagnosis blind (``base_model='auto'``: both base forms
identified, the better one on held-out data kept). Cases:

* ``free_play_soft`` / ``free_play_stiff``: a free play drawn log-uniformly in 0.05-1 mm, with the
  silent blocks as drawn (soft contact) or ten times stiffer (impact-like contact);
* ``bypass``: a bypass groove (damping lowered by 15-35 % within 4-10 mm of mid-stroke): a form gap
  the catalogue cannot represent and the bypass form can;
* ``none``: clean data.

Printed per run: what was hidden, the causes named, the base form kept, the fitted magnitude and the
time; then per case the share named correctly, named "unexplained", and the false causes (a catalogue
effect named that was not hidden, in particular one at its search bound). A free play must be named on
the base that made the data (``--model``). Writes ``blind_class.json``.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from campaign.damper_class import random_damper, write_class_dataset  # noqa: E402
from tuner.data.reading import load_dataset  # noqa: E402
from tuner.diagnosis.diagnose import DiagnosisSettings, diagnose  # noqa: E402
from tuner.executors import FleetExecutor  # noqa: E402
from tuner.identification.engine import fastest_engine  # noqa: E402
from tuner.results.fleet_summary import write_atomic  # noqa: E402

CASES = ("free_play_soft", "free_play_stiff", "bypass", "none")
#: the parameter a case's magnitude is read from (None: clean data)
MAGNITUDE = {"free_play_soft": "free_play", "free_play_stiff": "free_play", "bypass": "bypass_ratio", "none": None}
#: the name the diagnosis should give
EXPECTED = {"free_play_soft": "free_play", "free_play_stiff": "free_play", "bypass": "bypass", "none": "none"}


def case_seed(case: str, k: int) -> int:
    """The seed of a case's k-th run: the same whichever other cases are listed (free_play_stiff: 601, 612, ...)."""
    if case not in CASES:
        raise ValueError(f"unknown case {case!r}: choose from {', '.join(CASES)}")
    return 500 + 11 * k + 101 * CASES.index(case)


def hidden_parameters(case: str, model: str, seed: int) -> dict:
    """The parameters hidden in the random damper of ``model`` drawn with ``seed`` (SI)."""
    rng = np.random.default_rng([seed, CASES.index(case), 4242])
    if case == "none":
        return {}
    if case.startswith("free_play"):
        hidden = {"free_play": float(math.exp(rng.uniform(math.log(0.05e-3), math.log(1e-3))))}
        if case.endswith("stiff"):
            key = "k_B" if model == "lumped" else "k_M"
            hidden[key] = 10.0 * random_damper(model, seed)[key]
        return hidden
    return {"bypass_ratio": float(rng.uniform(0.15, 0.35)), "bypass_center": 0.0,
            "bypass_width": float(rng.uniform(4e-3, 10e-3))}


def run_case(case: dict) -> dict:
    """One blind diagnosis (``case``: case name, model, seed, noise_n, workers); the row of the table."""
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        data = write_class_dataset(Path(tmp) / "data", case["model"], case["seed"], noise_n=case["noise_n"],
                                   sample_rate=500.0, hidden=case["hidden"])
        tests = load_dataset(data)
        res = diagnose([t for t in tests if t.role == "identification"], [t for t in tests if t.role == "validation"],
                       DiagnosisSettings(engine=fastest_engine(), workers=case["workers"]),
                       log=lambda m: None)
    name = MAGNITUDE[case["case"]]
    fitted = (res["effect_parameters"].get(name) or {}).get("value") if name else None
    return {**case, "causes": res["causes"], "named": res["cause"], "base": res["base_model"],
            "fitted": fitted, "truth": case["hidden"].get(name) if name else None,
            "elapsed_s": time.perf_counter() - t0}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--model", choices=("lumped", "twochamber"), default="lumped")
    ap.add_argument("--noise", type=float, default=25.0, help="force noise [N rms]")
    ap.add_argument("--workers", type=int, default=0, help="evaluation processes inside each run")
    ap.add_argument("--scheduler", default=None, metavar="SPEC")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "blind_class")
    a = ap.parse_args(argv)
    cases = [{"case": c, "model": a.model, "seed": case_seed(c, k), "noise_n": a.noise, "workers": a.workers,
              "hidden": hidden_parameters(c, a.model, case_seed(c, k))} for c in a.cases.split(",") for k in range(a.seeds)]
    rows = []
    with FleetExecutor(a.scheduler) as ex:
        print(f"{len(cases)} blind diagnoses of random {a.model} dampers on a {ex.description}", flush=True)
        for i, row, err in ex.run(run_case, cases):
            if err is not None:
                raise RuntimeError(f"run {i} ({cases[i]['case']}, seed {cases[i]['seed']}) failed: {err}") from err
            rows.append(row)
            hid = ", ".join(f"{k} {v:.3g}" for k, v in row["hidden"].items()) or "nothing"
            print(f"{row['case']:16s} seed {row['seed']:4d}  hidden {hid:40s} -> {'+'.join(row['causes']) or row['named']:22s}"
                  f" base {row['base']:10s}" + (f" fitted {row['fitted']:.3g}" if row["fitted"] is not None else "")
                  + f"  [{row['elapsed_s']:.0f} s]", flush=True)
    a.out.mkdir(parents=True, exist_ok=True)
    write_atomic(a.out / "blind_class.json", json.dumps({"rows": rows}, indent=1))
    print(f"\n{'case':16s} {'runs':>5s} {'named right':>12s} {'on its base':>12s} {'unexplained':>12s} {'false cause':>12s}"
          f" {'median s':>9s}")
    for c in a.cases.split(","):
        sub = [r for r in rows if r["case"] == c]
        right = [r for r in sub if EXPECTED[c] in r["causes"] or (c == "none" and not r["causes"])]
        false = [r for r in sub if any(x != EXPECTED[c] for x in r["causes"])]
        print(f"{c:16s} {len(sub):5d} {len(right):12d} {sum(r['base'] == a.model for r in right):12d} "
              f"{sum(r['named'] == 'unexplained' for r in sub):12d} {len(false):12d} "
              f"{float(np.median([r['elapsed_s'] for r in sub])):9.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
