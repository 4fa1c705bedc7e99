"""Blind diagnoses of random physical twin-tube dampers with a catalogue fault, a pair of faults or nothing hidden.

    python benchmarks/blind_physical.py [--seeds 3] [--seed-offset 0]
                                        [--cases free_play_soft,free_play_stiff,friction,preload,valve_lag,
                                                 time_delay,none | pairs]
                                        [--test-length S] [--out results/blind_physical]
                                        [--scheduler pool | pool:N | local:N | tcp://HOST:PORT]
                                        [--compare-class results/blind_class]

The data come from no base form of the tuner: each run draws a physical twin-tube damper
(``campaign.rig_class.random_rig_damper``: piston and rod diameters, chamber lengths and dead volumes, oil
stiffness and entrained air, reservoir gas, the piston and foot valves reshaped, mounts from soft rubber to steel,
3e6-3e9 N/m, damped from light to heavy, 1e2-1e6 N s/m), the sampling rate 500, 1000 or 2000 Hz and the force
noise 10-50 N rms (``blind_common.acquisition_draw``), six tests of 12-16 s (four identification, two validation;
``campaign.damper_class``'s stroke generators), and hides the case's faults in the damper or in the rig chain after
it (``campaign.rig_class.RigFaults``): ``free_play_soft`` (a dead band in the actuator-side mount, its contact the
mount as drawn), ``free_play_stiff`` (the same with both mounts ten times stiffer: impact-like contact),
``friction`` (rod-seal Coulomb friction), ``preload`` (the rig's zero off by a constant force of either sign: an
un-tared share of the gas force or a load-cell offset, the catalogue's preload), ``valve_lag`` (a first-order lag of
the blow-off valves' openings), ``time_delay`` (the force channel lagging the stroke's, before the anti-alias filter
and ADC), the pairs of ``blind_class`` (``--cases pairs``) and ``none``. Each magnitude is drawn in its typical
range on the damper's size as its clean tests show it (``blind_common.typical_draw``: the catalogue's range scaled
as the diagnosis scales it). The diagnosis then runs blind exactly as in ``blind_class.py``
(``blind_common.blind_diagnosis``: both base forms identified, the better on held-out data kept).

The base forms then carry a real model-form error, as on a real damper, and no base made the data: a fault counts
"on the preferred base" when every hidden fault is named and the base kept is the one whose model the held-out data
prefer (the lowest held-out RMSE among the final models when the diagnosis ran on both bases, else among the
identified bases: ``blind_common.held_out``).

Printed per run: the case, seed, rate, noise, what was hidden, the causes named, the base kept, the fitted
magnitudes, the time (and the time the six tests took to make); then per case: runs, every hidden fault named,
named on the base the held-out data prefer, named or said to be absorbed by the base, unexplained, a false cause,
failed runs and the median time. ``--compare-class DIR`` prints the model-class benchmark's table beside it from
``DIR/rows.jsonl`` (``blind_class.py``'s rows; its "on its base" is the base that made those data). Appends each
run's row to ``rows.jsonl`` in ``--out`` as it ends, so that the same command resumes and more seeds
(``--seed-offset``) add to it; writes ``blind_physical.json`` and each run's diagnosis log (``logs/<case>-<seed>.log``).
"""
from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.blind_common import (Campaign, run_campaign, MAGNITUDE_OF, PAIRS, CaseCounts, acquisition_draw, blind_diagnosis,  # noqa: E402
                                     case_counts, done_rows, expected, preferred_base, row_line,
                                     typical_draw)
from campaign.rig_class import (RigFaults, damper_summary, random_rig_damper, rig_class_tests,  # noqa: E402
                                write_rig_class_dataset)
from tuner.diagnosis.effect_sizes import DamperSize  # noqa: E402
from tuner.executors import FleetExecutor  # noqa: E402
from tuner.identification.engine import IDENTIFICATION_STEP as DEFAULT_STEP  # noqa: E402
from tuner.identification.problem import DataSettings  # noqa: E402

SINGLES = ("free_play_soft", "free_play_stiff", "friction", "preload", "valve_lag", "time_delay", "none")
CASES = SINGLES + PAIRS
#: the stiff contact's mounts: this many times the drawn stiffness (``blind_class``'s tenfold series element)
STIFF_CONTACT = 10.0


def case_seed(case: str, k: int) -> int:
    """The seed of a case's k-th run: the same whichever other cases are listed (free_play_soft: 3000, 3011, ...)."""
    if case not in CASES:
        raise ValueError(f"unknown case {case!r}: choose from {', '.join(CASES)} (or 'pairs')")
    return 3000 + 11 * k + 101 * CASES.index(case)


def case_damper(case: dict):
    """The physical damper of ``case`` (``DamperParams``): the seed's draw, its mounts ``STIFF_CONTACT`` times
    stiffer for an impact-like free play."""
    params = random_rig_damper(case["seed"])
    if case["case"] == "free_play_stiff":
        params = replace(params, mount_stiffness=STIFF_CONTACT * params.mount_stiffness)
    return params


def damper_size(params, case: dict) -> DamperSize:
    """The size of the damper ``params`` as its clean tests show it (peak |force| [N], stroke range [m]): what the
    diagnosis scales the typical effect sizes with."""
    made = rig_class_tests(params, case["seed"], sample_rate=case["sample_rate"], noise_n=0.0,
                           durations=case.get("durations"))
    stroke = np.concatenate([t["frame"]["stroke"].to_numpy() for t in made.tests])
    return DamperSize(float(max(np.abs(f).max() for f in made.clean)), float(stroke.max() - stroke.min()))


def hidden_faults(case: dict, size: DamperSize) -> dict:
    """{catalogue magnitude: value [SI]} of the case's faults, each drawn in its typical range on a damper of
    ``size``, on the seed's own random stream."""
    rng = np.random.default_rng([case["seed"], CASES.index(case["case"]), 4242])
    return {MAGNITUDE_OF[e]: typical_draw(rng, e, size) for e in expected(case["case"])}


def run_case(case: dict) -> dict:
    """One blind diagnosis of a physical damper (``case``: name, seed, sample rate, noise, workers, ...); the row."""
    t0 = time.perf_counter()
    params = case_damper(case)
    hidden = hidden_faults(case, damper_size(params, case)) if expected(case["case"]) else {}
    case = {**case, "hidden": hidden, "damper": damper_summary(params)}
    made = rig_class_tests(params, case["seed"], faults=RigFaults.of(hidden), sample_rate=case["sample_rate"],
                           noise_n=case["noise_n"], durations=case.get("durations"))
    with tempfile.TemporaryDirectory() as tmp:
        found = blind_diagnosis(write_rig_class_dataset(Path(tmp) / "data", made), case)
    return {**case, **found, "data_s": made.seconds, "elapsed_s": time.perf_counter() - t0}


def run_key(row: dict) -> tuple:
    """What makes a run the same run again (resume): case, seed, test length [s] (None: drawn), simulation grid [s]."""
    durations = row.get("durations")
    return row["case"], row["seed"], tuple(durations) if durations else None, row.get("sim_step_s", DEFAULT_STEP)


def _case(name: str, k: int, a: argparse.Namespace) -> dict:
    seed = case_seed(name, k)
    return {"case": name, "seed": seed, **acquisition_draw(seed), "workers": a.workers, "hidden": {},
            "durations": [a.test_length] * 6 if a.test_length else None, "log_dir": str(a.out / "logs"),
            "sim_step_s": 1e-3 * a.sim_step}


def _arguments(argv) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--seed-offset", type=int, default=0, help="start at each case's k-th seed (new seeds)")
    ap.add_argument("--cases", default=",".join(SINGLES), help="comma-separated; 'pairs' stands for every pair")
    ap.add_argument("--test-length", type=float, default=None, metavar="S",
                    help="every test this long [s] (default: drawn in 12-16 s)")
    ap.add_argument("--workers", type=int, default=0, help="evaluation processes inside each run")
    ap.add_argument("--sim-step", type=float, default=1e3 * DataSettings().sim_step_s, metavar="MS",
                    help="the diagnosis's simulation grid [ms] (DataSettings.sim_step_s, default %(default)g)")
    ap.add_argument("--scheduler", default=None, metavar="SPEC")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "blind_physical")
    ap.add_argument("--compare-class", type=Path, default=None, metavar="DIR",
                    help="print the model-class benchmark's table (DIR/rows.jsonl of blind_class.py) beside")
    a = ap.parse_args(argv)
    a.case_names = [n for c in a.cases.split(",") for n in (PAIRS if c == "pairs" else (c,))]
    unknown = [c for c in a.case_names if c not in CASES]
    if unknown:
        ap.error(f"--cases: unknown case {unknown[0]!r}; choose from {', '.join(CASES)} or 'pairs'")
    if a.test_length is not None and not (2.0 <= a.test_length <= 60.0):
        ap.error(f"--test-length {a.test_length:g}: give 2-60 s (the strokes fade in over 1 s)")
    if a.compare_class is not None and not (a.compare_class / "rows.jsonl").is_file():
        ap.error(f"--compare-class {a.compare_class}: no rows.jsonl there (blind_class.py --out DIR writes it)")
    return a


def _line(row: dict) -> str:
    rmse = (row.get("held_out") or {}).get("rmse_n") or {}
    return (row_line(row) + f" data {row['data_s']:.0f} s, held-out "
            + ", ".join(f"{k} {v:.0f} N" for k, v in sorted(rmse.items())))


HEADS = ("runs", "all named", "on pref. base", "named/said", "false cause", "unexplained", "median s")


def _cells(n: CaseCounts | None) -> list[str]:
    if n is None:
        return ["-"] * len(HEADS)
    return [str(v) for v in (n.runs, n.all_named, n.on_base, n.named_or_said, n.false_cause, n.unexplained)] + [
        "-" if math.isnan(n.median_s) else f"{n.median_s:.0f}"]


#: a preload named beside a free play within this factor of the damper's static gas force is the gas force the rig
#: tared with the rod on one side of the gap (``campaign.rig_class``): in the data by physics, not a false cause
GAS_TARE_FACTOR = 2.0


def gas_tare(row: dict) -> set:
    """{'preload'} when ``row`` hid a free play in a gas-charged damper and the diagnosis's preload [N] lies within
    ``GAS_TARE_FACTOR`` of the static gas force |F_gas| [N] (``damper_summary``): inside the gap the tared force reads
    minus the gas force (seed 3000: 354 N named for 402 N); else the empty set."""
    gas = abs((row.get("damper") or {}).get("static_gas_force") or 0.0)
    preload = (row.get("effect_values") or {}).get("preload_force")
    if "free_play" not in expected(row["case"]) or not gas or preload is None:
        return set()
    return {"preload"} if gas / GAS_TARE_FACTOR <= abs(preload) <= gas * GAS_TARE_FACTOR else set()


def table_lines(rows: list[dict], names: list[str], class_rows: list[dict] | None = None) -> list[str]:
    """The table (one line a case; ``class_rows``: the model-class benchmark's beside, its "on its base" the base
    that made its data), as a Markdown table."""
    heads = [f"physical: {h}" for h in HEADS] + ([f"class: {h}" for h in HEADS] if class_rows is not None else [])
    out = ["| case | " + " | ".join(heads) + " |", "|---" * (len(heads) + 1) + "|"]
    for c in names:
        cells = _cells(case_counts(rows, c, lambda r: r["base"] == preferred_base(r), implied=gas_tare))
        if class_rows is not None:
            cells += _cells(case_counts(class_rows, c, lambda r: r["base"] == r.get("model")))
        out.append(f"| {c} | " + " | ".join(cells) + " |")
    return out


def main(argv=None) -> int:
    a = _arguments(argv)
    # seed by seed across the cases, so that a run stopped early leaves every case with as many seeds
    cases = [_case(c, k, a) for k in range(a.seed_offset, a.seed_offset + a.seeds) for c in a.case_names]
    rows = run_campaign(Campaign(cases, "random physical dampers", run_case, _line, a.out, "blind_physical.json",
                                 FleetExecutor),
                        a.scheduler, run_key)
    class_rows = done_rows(a.compare_class / "rows.jsonl") if a.compare_class is not None else None
    print("\n" + "\n".join(table_lines(rows, a.case_names, class_rows)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
