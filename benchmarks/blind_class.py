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
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from campaign.damper_class import class_tests, random_damper, write_class_dataset  # noqa: E402
from tuner.data.reading import load_dataset  # noqa: E402
from tuner.diagnosis.diagnose import DiagnosisSettings, diagnose  # noqa: E402
from tuner.diagnosis.effect_sizes import DamperSize, typical_range  # noqa: E402
from tuner.diagnosis.rules import untold  # noqa: E402
from tuner.executors import FleetExecutor  # noqa: E402
from tuner.identification.engine import IDENTIFICATION_STEP as DEFAULT_STEP, fastest_engine  # noqa: E402
from tuner.identification.problem import DataSettings  # noqa: E402
from tuner.results.fleet_summary import write_atomic  # noqa: E402

SINGLES = ("free_play_soft", "free_play_stiff", "bypass", "none")
PAIRS = ("free_play+friction", "free_play+preload", "free_play+valve_lag", "friction+time_delay", "valve_lag+preload")
CASES = SINGLES + PAIRS
#: the magnitude parameter of each catalogue effect a case can hide
MAGNITUDE_OF = {"free_play": "free_play", "friction": "friction_force", "preload": "preload_force",
                "valve_lag": "valve_tau", "time_delay": "time_delay", "bypass": "bypass_ratio"}


def expected(case: str) -> tuple[str, ...]:
    """The effects the diagnosis should name for ``case`` (empty: nothing)."""
    if case == "none":
        return ()
    if case.startswith("free_play_"):
        return ("free_play",)
    return tuple(case.split("+"))


def _typical_draw(rng, effect: str, size: DamperSize) -> float:
    """One magnitude [SI] of ``effect`` in its typical range on a damper of ``size`` (the catalogue's range scaled
    as the diagnosis scales it, ``tuner.diagnosis.effect_sizes.typical_range``): a free play log-uniform, the
    others uniform, a preload of either sign."""
    lo, hi = typical_range(MAGNITUDE_OF[effect], size)
    if effect == "free_play":
        return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
    sign = float(rng.choice([-1.0, 1.0])) if effect == "preload" else 1.0
    return sign * float(rng.uniform(lo, hi))


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
BROAD_RATES_HZ = (500.0, 1000.0, 2000.0)
BROAD_NOISE_N = (10.0, 50.0)


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
    return {MAGNITUDE_OF[e]: _typical_draw(rng, e, size) for e in expected(case["case"])}


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
        # the generator's sign and unit conventions are ours: the reader's plausibility check (there for a user's
        # sign or unit mistakes) is not asked; it refused one passive damper of the class (seed 1128: a 7 ms valve
        # lag with 1e9 N/m blocks damped at 2.3e4 N s/m, force and velocity correlated -0.14 on one test)
        tests = load_dataset(data, check_plausible=False)
        log_file = Path(case["log_dir"]) / f"{case['case']}-{case['seed']}.log" if case.get("log_dir") else None
        with open(log_file or "/dev/null", "w") as out:
            res = diagnose([t for t in tests if t.role == "identification"],
                           [t for t in tests if t.role == "validation"],
                           DiagnosisSettings(engine=fastest_engine(), workers=case["workers"],
                                             base_model=case.get("base_setting", "auto"),
                                             data=DataSettings(sim_step_s=case.get("sim_step_s", DEFAULT_STEP))),
                           log=lambda m: print(m, file=out, flush=True))
    names = [MAGNITUDE_OF[e] for e in expected(case["case"])]
    fitted = {n: (res["effect_parameters"].get(n) or {}).get("value") for n in names}
    return {**case, "causes": res["causes"], "named": res["cause"], "base": res["base_model"],
            "fitted": fitted, "truth": {n: case["hidden"][n] for n in names}, "confounded": confounded(res),
            "grid_refined": bool((res.get("grid") or {}).get("refined")),
            "elapsed_s": time.perf_counter() - t0}


def confounded(res: dict) -> dict:
    """{effect: share of its force the base absorbs} of the effects the verdict says these tests cannot tell from
    the base's own elements: ``tuner.diagnosis.rules.untold`` of their detection limits, and the candidates an
    unexplained residual lists as explaining the same residual as the base (``unexplained.indistinguishable``)."""
    said = {e: lim["absorbed_share"] for e, lim in (res.get("detection_limits") or {}).items() if untold(lim)}
    for r in (res.get("unexplained") or {}).get("indistinguishable") or []:
        said.setdefault(r["effect"], r["absorbed_share"])
    return said


def failed_row(case: dict, err: BaseException) -> dict:
    """The row of a run that raised: kept in the table as a failure, never dropped."""
    return {**case, "causes": [], "named": "failed", "base": None, "fitted": {}, "confounded": {},
            "error": f"{type(err).__name__}: {err}"[:500], "elapsed_s": None}


def run_key(row: dict) -> tuple:
    """What makes a run the same run again (resume): case, model, seed, data breadth, base setting (the row's
    ``base`` is the base form the diagnosis kept), simulation grid [s]."""
    return (row["case"], row["model"], row["seed"], bool(row.get("broad")), row.get("base_setting", "auto"),
            row.get("sim_step_s", DEFAULT_STEP))


def done_rows(path: Path) -> list[dict]:
    """The rows of ``path`` (one JSON object a line, as ``main`` appends them); [] without the file."""
    if not path.exists():
        return []
    rows = []
    for i, line in enumerate(path.read_text().splitlines(), 1):
        try:
            rows.append(json.loads(line))
        except json.JSONDecodeError as exc:
            raise SystemExit(f"{path}, line {i}: not a JSON row ({exc}); remove the line or the file to start "
                             "over") from exc
    return rows


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


def _row_line(row: dict) -> str:
    hid = ", ".join(f"{k} {v:.3g}" for k, v in row["hidden"].items()) or "nothing"
    fit = ", ".join(f"{k} {v:.3g}" for k, v in row["fitted"].items() if v is not None)
    return (f"{row['case']:20s} seed {row['seed']:4d} {row['sample_rate']:5.0f} Hz {row['noise_n']:3.0f} N  "
            f"hidden {hid:60s}"
            f" -> {'+'.join(row['causes']) or row['named']:22s} base {row['base']:10s}"
            + (f" fitted {fit}" if fit else "") + (" (again on a finer grid)" if row.get("grid_refined") else "")
            + f"  [{row['elapsed_s']:.0f} s]")


def _table(rows: list[dict], names: list[str], model: str) -> None:
    """Per case: runs, every hidden effect named, some named, on the base that made the data, every hidden effect
    named or said to be absorbed by the base (``confounded``), unexplained, a false cause (an effect named that was
    not hidden), failed runs, median time."""
    print(f"\n{'case':20s} {'runs':>5s} {'all named':>10s} {'some named':>11s} {'on its base':>12s} "
          f"{'named/said':>11s} {'unexplained':>12s} {'false cause':>12s} {'failed':>7s} {'median s':>9s}")
    for c in names:
        sub = [r for r in rows if r["case"] == c]
        if not sub:
            continue
        want = set(expected(c))
        right = [r for r in sub if want <= set(r["causes"]) and (want or not r["causes"])]
        said = [r for r in sub if want <= set(r["causes"]) | set(r.get("confounded") or {})]
        some = [r for r in sub if want & set(r["causes"])]
        false = [r for r in sub if set(r["causes"]) - want]
        times = [r["elapsed_s"] for r in sub if "error" not in r]
        print(f"{c:20s} {len(sub):5d} {len(right):10d} {len(some):11d} {sum(r['base'] == model for r in right):12d} "
              f"{len(said):11d} {sum(r['named'] == 'unexplained' for r in sub):12d} {len(false):12d} "
              f"{sum('error' in r for r in sub):7d} {float(np.median(times)) if times else math.nan:9.0f}")


def main(argv=None) -> int:
    a = _arguments(argv)
    (a.out / "logs").mkdir(parents=True, exist_ok=True)
    rows_file = a.out / "rows.jsonl"
    rows = done_rows(rows_file)
    done = {run_key(r) for r in rows}
    # seed by seed across the cases, so that a run stopped early leaves every case with as many seeds
    cases = [_case(c, k, a) for k in range(a.seed_offset, a.seed_offset + a.seeds) for c in a.case_names]
    todo = [c for c in cases if run_key(c) not in done]
    with FleetExecutor(a.scheduler) as ex:
        print(f"{len(todo)} blind diagnoses of random {a.model} dampers on a {ex.description}"
              + (f" ({len(cases) - len(todo)} done before, in {rows_file})" if len(todo) < len(cases) else ""),
              flush=True)
        for i, row, err in ex.run(run_case, todo):
            if err is not None:  # kept as a failure: the other runs go on, and the table counts it
                row = failed_row(todo[i], err)
                print(f"run {i} ({todo[i]['case']}, seed {todo[i]['seed']}) failed: {row['error']}", flush=True)
            rows.append(row)
            with open(rows_file, "a") as f:  # one strict-JSON row a line, so that a stopped run resumes
                f.write(json.dumps(row, allow_nan=False) + "\n")
            if err is None:
                print(_row_line(row), flush=True)
    write_atomic(a.out / "blind_class.json", json.dumps({"rows": rows}, indent=1, allow_nan=False))
    keys = {run_key(c) for c in cases}
    _table([r for r in rows if run_key(r) in keys], a.case_names, a.model)
    return 0


if __name__ == "__main__":
    sys.exit(main())
