"""What the blind benchmarks share (``blind_class.py``: data of the base model classes; ``blind_physical.py``:
data of the physical twin-tube damper): the faults a case hides and their typical magnitudes, the data's breadth,
the diagnosis run blind on a dataset folder, what its verdict says, the rows written as runs end (so that a
stopped benchmark resumes) and the per-case counts of the tables.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tuner.data.reading import load_dataset
from tuner.diagnosis.diagnose import DiagnosisSettings, diagnose
from tuner.diagnosis.effect_sizes import DamperSize, typical_range
from tuner.diagnosis.rules import untold
from tuner.identification.engine import IDENTIFICATION_STEP as DEFAULT_STEP, fastest_engine
from tuner.identification.problem import DataSettings

PAIRS = ("free_play+friction", "free_play+preload", "free_play+valve_lag", "friction+time_delay", "valve_lag+preload")
#: the magnitude parameter of each catalogue effect a case can hide
MAGNITUDE_OF = {"free_play": "free_play", "friction": "friction_force", "preload": "preload_force",
                "valve_lag": "valve_tau", "time_delay": "time_delay", "bypass": "bypass_ratio"}
#: the broad data's sampling rates [Hz] (one per seed) and force noise [N rms] (uniform)
BROAD_RATES_HZ = (500.0, 1000.0, 2000.0)
BROAD_NOISE_N = (10.0, 50.0)


def expected(case: str) -> tuple[str, ...]:
    """The effects the diagnosis should name for ``case`` (empty: nothing)."""
    if case == "none":
        return ()
    if case.startswith("free_play_"):
        return ("free_play",)
    return tuple(case.split("+"))


def typical_draw(rng, effect: str, size: DamperSize) -> float:
    """One magnitude [SI] of ``effect`` in its typical range on a damper of ``size`` (the catalogue's range scaled
    as the diagnosis scales it, ``tuner.diagnosis.effect_sizes.typical_range``): a free play log-uniform, the
    others uniform, a preload of either sign."""
    lo, hi = typical_range(MAGNITUDE_OF[effect], size)
    if effect == "free_play":
        return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
    sign = float(rng.choice([-1.0, 1.0])) if effect == "preload" else 1.0
    return sign * float(rng.uniform(lo, hi))


def acquisition_draw(seed: int) -> dict:
    """The seed's sampling rate [Hz] (one of ``BROAD_RATES_HZ``) and force noise [N rms] (uniform in
    ``BROAD_NOISE_N``): {"sample_rate", "noise_n"}, on the seed's own stream."""
    rng = np.random.default_rng([seed, 7178])
    return {"sample_rate": float(rng.choice(BROAD_RATES_HZ)), "noise_n": float(rng.uniform(*BROAD_NOISE_N))}


def blind_diagnosis(data: Path, case: dict) -> dict:
    """The diagnosis run blind (``base_model`` from the case, 'auto' by default: both base forms identified, the
    better kept) on the dataset folder ``data``, its log to ``<log_dir>/<case>-<seed>.log``; the row's result
    fields: causes, the cause named, the base kept, the fitted and true magnitudes of the faults hidden
    (``case['hidden']``: {magnitude: value}), what the verdict says the base absorbs, the grid refinement and the
    held-out RMSE [N] of each base form (``held_out``)."""
    # the generators' sign and unit conventions are ours: the reader's plausibility check (there for a user's
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
    return {"causes": res["causes"], "named": res["cause"], "base": res["base_model"], "fitted": fitted,
            "truth": {n: case["hidden"][n] for n in names}, "confounded": confounded(res),
            "grid_refined": bool((res.get("grid") or {}).get("refined")), "held_out": held_out(res),
            # every named effect's magnitudes [SI], hidden or not (a physical damper's implied causes are judged by them)
            "effect_values": {n: p.get("value") for n, p in (res.get("effect_parameters") or {}).items()}}


def confounded(res: dict) -> dict:
    """{effect: share of its force the base absorbs} of the effects the verdict says these tests cannot tell from
    the base's own elements: ``tuner.diagnosis.rules.untold`` of their detection limits, and the candidates an
    unexplained residual lists as explaining the same residual as the base (``unexplained.indistinguishable``)."""
    said = {e: lim["absorbed_share"] for e, lim in (res.get("detection_limits") or {}).items() if untold(lim)}
    for r in (res.get("unexplained") or {}).get("indistinguishable") or []:
        said.setdefault(r["effect"], r["absorbed_share"])
    return said


def held_out(res: dict) -> dict:
    """{"rmse_n": {base form: held-out RMSE [N]}, "of": what was compared}: the final models' when the diagnosis
    ran on more than one base, else the identified base models' (the diagnosis then ran on the one with the lowest
    and its final model can only be better there); {} when the record has neither."""
    choice = res.get("base_choice") or {}
    after = choice.get("after_diagnosis")
    if after:
        return {"rmse_n": {k: math.sqrt(v["validation_mse"]) for k, v in after.items()}, "of": "final models"}
    mse = choice.get("validation_mse")
    return {"rmse_n": {k: math.sqrt(v) for k, v in mse.items()}, "of": "identified bases"} if mse else {}


def preferred_base(row: dict) -> str | None:
    """The base form whose model the held-out data prefer (``held_out``: the lowest RMSE), None when unknown."""
    rmse = (row.get("held_out") or {}).get("rmse_n") or {}
    return min(rmse, key=rmse.get) if rmse else None


def failed_row(case: dict, err: BaseException) -> dict:
    """The row of a run that raised: kept in the table as a failure, never dropped."""
    return {**case, "causes": [], "named": "failed", "base": None, "fitted": {}, "confounded": {},
            "error": f"{type(err).__name__}: {err}"[:500], "elapsed_s": None}


def done_rows(path: Path) -> list[dict]:
    """The rows of ``path`` (one JSON object a line, as ``run_rows`` appends them); [] without the file."""
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


def run_rows(ex, run_case, todo: list[dict], rows: list[dict], rows_file: Path, line) -> None:
    """Run ``run_case`` on each case of ``todo`` on the executor ``ex`` (``tuner.executors.FleetExecutor``'s
    interface), appending each row to ``rows`` and to ``rows_file`` as it ends (one strict-JSON row a line, so that
    a stopped run resumes) and printing it (``line``: its text); a run that raises is kept as a failed row and
    the others go on."""
    for i, row, err in ex.run(run_case, todo):
        if err is not None:  # kept as a failure: the other runs go on, and the table counts it
            row = failed_row(todo[i], err)
            print(f"run {i} ({todo[i]['case']}, seed {todo[i]['seed']}) failed: {row['error']}", flush=True)
        rows.append(row)
        with open(rows_file, "a") as f:
            f.write(json.dumps(row, allow_nan=False) + "\n")
        if err is None:
            print(line(row), flush=True)


@dataclass(frozen=True)
class Campaign:
    """One blind benchmark's command-line run: its ``cases`` (the inputs of every run asked for), what each is called
    in the log (``what``: 'random lumped dampers'), the runner ``run_case`` and the line printer ``line``, the
    ``out`` folder (``rows.jsonl`` there resumes), the JSON file of all rows written there (``json_name``) and the
    executor class the runs go to (``executor``: ``tuner.executors.FleetExecutor``'s interface)."""

    cases: list
    what: str
    run_case: object
    line: object
    out: Path
    json_name: str
    executor: object


def run_campaign(c: Campaign, scheduler: str | None, run_key) -> list[dict]:
    """The runs of ``c`` not in its ``rows.jsonl`` yet (``run_key``: what makes a run the same run), on
    ``scheduler`` (``c.executor``), seed by seed as listed; every row appended as it ends, then all rows in
    ``json_name``. Returns the rows of the cases asked for (a resumed file may hold others)."""
    from tuner.results.fleet_summary import write_atomic

    (c.out / "logs").mkdir(parents=True, exist_ok=True)
    rows_file = c.out / "rows.jsonl"
    rows = done_rows(rows_file)
    done = {run_key(r) for r in rows}
    todo = [case for case in c.cases if run_key(case) not in done]
    with c.executor(scheduler) as ex:
        print(f"{len(todo)} blind diagnoses of {c.what} on a {ex.description}"
              + (f" ({len(c.cases) - len(todo)} done before, in {rows_file})" if len(todo) < len(c.cases) else ""),
              flush=True)
        run_rows(ex, c.run_case, todo, rows, rows_file, c.line)
    write_atomic(c.out / c.json_name, json.dumps({"rows": rows}, indent=1, allow_nan=False))
    keys = {run_key(case) for case in c.cases}
    return [r for r in rows if run_key(r) in keys]


def row_line(row: dict) -> str:
    """One run in a line: case, seed, rate, noise, what was hidden, the causes named, the base, the fitted values,
    the time."""
    hid = ", ".join(f"{k} {v:.3g}" for k, v in row["hidden"].items()) or "nothing"
    fit = ", ".join(f"{k} {v:.3g}" for k, v in row["fitted"].items() if v is not None)
    return (f"{row['case']:20s} seed {row['seed']:4d} {row['sample_rate']:5.0f} Hz {row['noise_n']:3.0f} N  "
            f"hidden {hid:60s}"
            f" -> {'+'.join(row['causes']) or row['named']:22s} base {row['base']:10s}"
            + (f" fitted {fit}" if fit else "") + (" (again on a finer grid)" if row.get("grid_refined") else "")
            + f"  [{row['elapsed_s']:.0f} s]")


@dataclass(frozen=True)
class CaseCounts:
    """One case's line of a table: runs, every hidden effect named (and nothing else when nothing was hidden), some
    named, every one named on the base asked for (``case_counts``' ``on_base``), every one named or said to be
    absorbed by the base (``confounded``), unexplained, a false cause (an effect named that was not hidden), failed
    runs, the median wall time [s] of the runs that ended (NaN without one)."""

    runs: int
    all_named: int
    some_named: int
    on_base: int
    named_or_said: int
    unexplained: int
    false_cause: int
    failed: int
    median_s: float


def case_counts(rows: list[dict], case: str, on_base, implied=None) -> CaseCounts | None:
    """The counts of ``case``'s rows (None without one); ``on_base(row)``: the row's base is the one asked for;
    ``implied(row)``: the causes the data of that row hold beside the hidden faults by physics (a set; not required
    to be named, not false when named; None: none)."""
    sub = [r for r in rows if r["case"] == case]
    if not sub:
        return None
    want = set(expected(case))
    allowed = {id(r): want | (implied(r) if implied else set()) for r in sub}
    right = [r for r in sub if want <= set(r["causes"]) and (want or not set(r["causes"]) - allowed[id(r)])]
    times = [r["elapsed_s"] for r in sub if "error" not in r]
    return CaseCounts(
        runs=len(sub), all_named=len(right), some_named=sum(bool(want & set(r["causes"])) for r in sub),
        on_base=sum(bool(on_base(r)) for r in right),
        named_or_said=sum(want <= set(r["causes"]) | set(r.get("confounded") or {}) for r in sub),
        unexplained=sum(r["named"] == "unexplained" for r in sub),
        false_cause=sum(bool(set(r["causes"]) - allowed[id(r)]) for r in sub), failed=sum("error" in r for r in sub),
        median_s=float(np.median(times)) if times else math.nan)
