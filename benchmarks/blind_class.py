"""Blind diagnoses of random dampers of the model classes with a hidden free play, form gap or pair of faults.

    python benchmarks/blind_class.py [--seeds 3] [--seed-offset 0]
                                     [--cases free_play_soft,free_play_stiff,bypass,none]
                                     [--model lumped|twochamber] [--noise 25] [--broad] [--out results/blind_class]
                                     [--scheduler pool | pool:N | local:N | tcp://HOST:PORT]
    python benchmarks/blind_class.py --broad --cases pairs --seeds 10     # the fault pairs, data as broad as users'

Each run draws a damper of the class (``campaign.damper_class.random_damper``: unlike the preset),
six tests of 12-16 s at 500 Hz with ``--noise`` N rms on the force (``class_tests``), hides one effect
in the model that makes the data and runs the diagnosis blind (``base_model='auto'``: both base forms
identified, the better one on held-out data kept). Cases:

* ``free_play_soft`` / ``free_play_stiff``: a free play drawn log-uniformly in 0.05-1 mm, with the
  silent blocks as drawn (soft contact) or ten times stiffer (impact-like contact);
* ``bypass``: a bypass groove (damping lowered by 15-35 % within 4-10 mm of mid-stroke): a form gap
  the catalogue cannot represent and the bypass form can;
* ``none``: clean data;
* pairs of faults hidden together (``PAIRS``; ``--cases pairs`` lists them all): ``free_play+friction``
  (a worn damper: free play and rod-seal friction), ``free_play+preload``, ``free_play+valve_lag``,
  ``friction+time_delay`` and ``valve_lag+preload``, each magnitude drawn in its typical range on the damper
  drawn, scaled as the diagnosis scales it (``tuner.diagnosis.effect_sizes``: the catalogue's friction 50-300 N
  and preload 30-400 N of either sign times peak force / 20 kN, its free play 0.1-1 mm times stroke range /
  40 mm up to 1, valve lag and delay 1-10 ms), the size taken from the damper's clean tests.

``--broad``: the data as broad as users' (``broad_data``): the silent blocks' (lumped) or mounts'
(two-chamber) stiffness and damping drawn over decades, from soft, heavily damped contact to impact-like
contact (damping far below critical), the sampling rate 500, 1000 or 2000 Hz and the force noise uniform
in 10-50 N rms, per seed; without it the damper's own draw, 500 Hz and ``--noise``.

Printed per run: what was hidden, the sampling rate and noise, the causes named, the base form kept, the
fitted magnitudes and the time; then per case the runs with every hidden effect named, with some named, with
all named on the base that made the data (``--model``: a free play must be found there), named
"unexplained", and with a false cause (a catalogue effect named that was not hidden), with every hidden effect
named or said to be absorbed by the base (the verdict's "these tests cannot tell ... from the base model's own
elements"), and failed runs (kept as rows; the other runs go on). Appends each run's row to ``rows.jsonl`` in
``--out`` as it ends, so that the same command resumes a stopped run and more seeds (``--seed-offset``) add to
it (the table counts every row of the cases and seeds listed); writes ``blind_class.json`` and each run's
diagnosis log (``logs/<case>-<seed>.log``) there.
"""
from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.blind_common import (Campaign, run_campaign, BROAD_NOISE_N, BROAD_RATES_HZ, MAGNITUDE_OF, PAIRS, blind_diagnosis,  # noqa: E402
                                     case_counts, confounded, done_rows, expected, failed_row, row_line,
                                     typical_draw)
from campaign.damper_class import class_tests, random_damper, write_class_dataset  # noqa: E402
from tuner.diagnosis.effect_sizes import DamperSize  # noqa: E402
from tuner.executors import FleetExecutor  # noqa: E402
from tuner.identification.engine import IDENTIFICATION_STEP as DEFAULT_STEP  # noqa: E402
from tuner.identification.problem import DataSettings  # noqa: E402

__all__ = ["SINGLES", "PAIRS", "CASES", "MAGNITUDE_OF", "expected", "case_seed", "broad_data", "hidden_parameters",
           "run_case", "confounded", "failed_row", "done_rows", "run_key", "main"]

SINGLES = ("free_play_soft", "free_play_stiff", "bypass", "none")
CASES = SINGLES + PAIRS


def damper_size(model: str, seed: int, hidden: dict, sample_rate: float) -> DamperSize:
    """The size of the damper drawn with ``seed`` as its clean tests show it (peak |force| [N], stroke range [m]):
    what the diagnosis scales the typical effect sizes with."""
    tests, _ = class_tests(model, seed, noise_n=0.0, sample_rate=sample_rate, hidden=hidden)
    force = np.concatenate([t["frame"]["force"].to_numpy() for t in tests])
    stroke = np.concatenate([t["frame"]["stroke"].to_numpy() for t in tests])
    return DamperSize(float(np.abs(force).max()), float(stroke.max() - stroke.min()))


def case_seed(case: str, k: int) -> int:
    """The seed of a case's k-th run: the same whichever other cases are listed (free_play_stiff: 601, 612, ...)."""
    if case not in CASES:
        raise ValueError(f"unknown case {case!r}: choose from {', '.join(CASES)} (or 'pairs')")
    return 500 + 11 * k + 101 * CASES.index(case)


#: silent-block (lumped) or mount (two-chamber) stiffness [N/m] and damping [N s/m] of the broad data:
#: log-uniform over decades within the models' bounds (critical damping of the contact is ~1e5 N s/m)
BROAD_SERIES = {"lumped": {"k_B": (3e7, 1e9), "c_B": (1e3, 1e7)},
                "twochamber": {"k_M": (3e6, 3e9), "c_M": (1e2, 1e6)}}


def broad_data(model: str, seed: int) -> dict:
    """The seed's broad draw: {"series": {parameter: value}, "sample_rate": Hz, "noise_n": N rms}."""
    rng = np.random.default_rng([seed, 7177])
    series = {k: float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
              for k, (lo, hi) in BROAD_SERIES[model].items()}
    return {"series": series, "sample_rate": float(rng.choice(BROAD_RATES_HZ)),
            "noise_n": float(rng.uniform(*BROAD_NOISE_N))}


def hidden_parameters(case: str, model: str, seed: int) -> dict:
    """The parameters hidden in the random damper of ``model`` drawn with ``seed`` (SI); a pair's magnitudes are
    drawn by ``pair_magnitudes``, on the damper's size."""
    rng = np.random.default_rng([seed, CASES.index(case), 4242])
    if case == "none":
        return {}
    if case in PAIRS:  # drawn when the damper's size is known (``pair_magnitudes``)
        return {}
    if case.startswith("free_play"):
        hidden = {"free_play": float(math.exp(rng.uniform(math.log(0.05e-3), math.log(1e-3))))}
        if case.endswith("stiff"):
            key = "k_B" if model == "lumped" else "k_M"
            hidden[key] = 10.0 * random_damper(model, seed)[key]
        return hidden
    return {"bypass_ratio": float(rng.uniform(0.15, 0.35)), "bypass_center": 0.0,
            "bypass_width": float(rng.uniform(4e-3, 10e-3))}


def pair_magnitudes(case: dict) -> dict:
    """The magnitudes [SI] of a pair case's two effects, each in its typical range on the damper drawn (with the
    case's series element), on the seed's own random stream."""
    size = damper_size(case["model"], case["seed"], case["hidden"], case["sample_rate"])
    rng = np.random.default_rng([case["seed"], CASES.index(case["case"]), 4242])
    return {MAGNITUDE_OF[e]: typical_draw(rng, e, size) for e in expected(case["case"])}


def _case(name: str, k: int, a: argparse.Namespace) -> dict:
    """The k-th run of case ``name`` under the command line ``a`` (the row's inputs)."""
    seed = case_seed(name, k)
    hidden = hidden_parameters(name, a.model, seed)
    rate, noise = 500.0, a.noise
    if a.broad:
        draw = broad_data(a.model, seed)
        hidden = {**draw["series"], **hidden}  # a stiff case's tenfold stiffness stays
        rate, noise = draw["sample_rate"], draw["noise_n"]
    return {"case": name, "model": a.model, "seed": seed, "noise_n": noise, "sample_rate": rate,
            "workers": a.workers, "hidden": hidden, "log_dir": str(a.out / "logs"),
            "base_setting": a.base, "broad": a.broad, "sim_step_s": 1e-3 * a.sim_step}


def run_case(case: dict) -> dict:
    """One blind diagnosis (``case``: case name, model, seed, noise_n, workers); the row of the table."""
    t0 = time.perf_counter()
    if case["case"] in PAIRS:
        case = {**case, "hidden": {**case["hidden"], **pair_magnitudes(case)}}
    with tempfile.TemporaryDirectory() as tmp:
        data = write_class_dataset(Path(tmp) / "data", case["model"], case["seed"], noise_n=case["noise_n"],
                                   sample_rate=case["sample_rate"], hidden=case["hidden"])
        found = blind_diagnosis(data, case)
    return {**case, **found, "elapsed_s": time.perf_counter() - t0}


def run_key(row: dict) -> tuple:
    """What makes a run the same run again (resume): case, model, seed, data breadth, base setting (the row's
    ``base`` is the base form the diagnosis kept), simulation grid [s]."""
    return (row["case"], row["model"], row["seed"], bool(row.get("broad")), row.get("base_setting", "auto"),
            row.get("sim_step_s", DEFAULT_STEP))


def _arguments(argv) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--seed-offset", type=int, default=0, help="start at each case's k-th seed (new seeds)")
    ap.add_argument("--cases", default=",".join(SINGLES), help="comma-separated; 'pairs' stands for every pair")
    ap.add_argument("--model", choices=("lumped", "twochamber"), default="lumped")
    ap.add_argument("--noise", type=float, default=25.0, help="force noise [N rms] (without --broad)")
    ap.add_argument("--broad", action="store_true", help="series element, sampling rate and noise drawn per seed")
    ap.add_argument("--base", choices=("auto", "lumped", "twochamber"), default="auto",
                    help="the diagnosis's base form: 'auto' identifies both and keeps the better (the blind default)")
    ap.add_argument("--workers", type=int, default=0, help="evaluation processes inside each run")
    ap.add_argument("--sim-step", type=float, default=1e3 * DataSettings().sim_step_s, metavar="MS",
                    help="the diagnosis's simulation grid [ms] (DataSettings.sim_step_s, default %(default)g)")
    ap.add_argument("--scheduler", default=None, metavar="SPEC")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "blind_class")
    a = ap.parse_args(argv)
    a.case_names = [n for c in a.cases.split(",") for n in (PAIRS if c == "pairs" else (c,))]
    return a


def _table(rows: list[dict], names: list[str], model: str) -> None:
    """Per case: runs, every hidden effect named, some named, on the base that made the data, every hidden effect
    named or said to be absorbed by the base (``confounded``), unexplained, a false cause (an effect named that was
    not hidden), failed runs, median time."""
    print(f"\n{'case':20s} {'runs':>5s} {'all named':>10s} {'some named':>11s} {'on its base':>12s} "
          f"{'named/said':>11s} {'unexplained':>12s} {'false cause':>12s} {'failed':>7s} {'median s':>9s}")
    for c in names:
        n = case_counts(rows, c, lambda r: r["base"] == model)
        if n is None:
            continue
        print(f"{c:20s} {n.runs:5d} {n.all_named:10d} {n.some_named:11d} {n.on_base:12d} {n.named_or_said:11d} "
              f"{n.unexplained:12d} {n.false_cause:12d} {n.failed:7d} {n.median_s:9.0f}")


def main(argv=None) -> int:
    a = _arguments(argv)
    # seed by seed across the cases, so that a run stopped early leaves every case with as many seeds
    cases = [_case(c, k, a) for k in range(a.seed_offset, a.seed_offset + a.seeds) for c in a.case_names]
    rows = run_campaign(Campaign(cases, f"random {a.model} dampers", run_case, row_line, a.out, "blind_class.json",
                                 FleetExecutor),
                        a.scheduler, run_key)
    _table(rows, a.case_names, a.model)
    return 0


if __name__ == "__main__":
    sys.exit(main())
