"""The real MR damper's currents, fit and diagnosis as a user runs them, one after the other: where the time goes.

    python benchmarks/real_currents.py [--data ../shared/realdata] [--currents 0.25A,0.5A,0.75A] [--out OUT]

Each current (``<data>/mr-damper-<current>/sine/``, read with its mapping file ``docs/real-data/mr-sine*.toml``)
runs the command of docs/real-data.md in a process of its own (identification on the 0.1, 0.5 and 3 Hz tests,
validation on the 0.25, 1 and 5 Hz ones, the default models, the diagnosis after the fit, no figures; its log in
``OUT/<current>.log``), alone on the machine; printed per current: the wall time, the stages' seconds (``time_budget.json``, ``tuner.time_budget``),
the two-chamber and lumped identification RMSE [N] of the FMUs shipped, whether a later stage found a lower point
(``history_<model>.json``'s ``best_point``), and the verdict. Then one table of the stages' seconds per current,
as docs/measurements.md shows it. Rows go to ``OUT/real_currents.json`` (``--out``, default results/real_currents).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
IDENTIFICATION = ("25mm0x1Hz", "25mm0x5Hz", "5mm3Hz")
VALIDATION = ("25mm0x25Hz", "10mm1Hz", "2mm5Hz")
MAPPING = {"0.25A": "mr-sine-0x25A.toml", "0.5A": "mr-sine.toml", "0.75A": "mr-sine-0x75A.toml"}


def command(data: Path, current: str, out: Path) -> list[str]:
    """The command line of docs/real-data.md for ``current`` ('0.5A') into ``out``."""
    tag = current.replace(".", "x")  # the files' names: 25mm0x1Hz0x25A.txt
    folder = data / f"mr-damper-{current}" / "sine"
    files = lambda names: [str(folder / f"{n}{tag}.txt") for n in names]  # noqa: E731
    return [sys.executable, "-m", "tuner", "fit", "--identification", *files(IDENTIFICATION),
            "--validation", *files(VALIDATION), "--columns", str(ROOT / "docs" / "real-data" / MAPPING[current]),
            "--no-figures", "--out", str(out)]


def row(current: str, out: Path, wall: float) -> dict:
    """What one run shows: wall time [s], stages [s], identification RMSE [N] per model, best points, verdict."""
    budget = json.loads((out / "time_budget.json").read_text())
    rmse, best = {}, {}
    for model in ("twochamber", "lumped"):
        path = out / f"history_{model}.json"
        if path.exists():
            h = json.loads(path.read_text())
            rmse[model] = h.get("identification_rmse_n")
            if h.get("best_point"):
                best[model] = h["best_point"]
    diagnosis = json.loads((out / "diagnosis.json").read_text()) if (out / "diagnosis.json").exists() else {}
    return {"current": current, "wall_s": wall, "stages": {s["stage"]: s["seconds"] for s in budget["stages"]},
            "sections": {s["stage"]: {x["section"]: x["seconds"] for x in s["sections"]} for s in budget["stages"]},
            "identification_rmse_n": rmse, "best_point": best, "verdict": diagnosis.get("verdict"),
            "base_model": diagnosis.get("base_model")}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "realdata")
    ap.add_argument("--currents", default="0.25A,0.5A,0.75A")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "real_currents")
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for current in a.currents.split(","):
        if current not in MAPPING:
            raise SystemExit(f"--currents: {current!r} is not one of {', '.join(MAPPING)}")
        out = a.out / current
        if out.exists():
            raise SystemExit(f"{out} exists: remove it or give another --out (nothing is overwritten)")
        t0 = time.perf_counter()
        with open(a.out / f"{current}.log", "w") as log:  # the job's log, for where a figure came from
            done = subprocess.run(command(a.data, current, out), cwd=ROOT, stdout=log, stderr=subprocess.STDOUT)
        if done.returncode != 0:
            raise SystemExit(f"{current}: the job exited with {done.returncode}")
        rows.append(row(current, out, time.perf_counter() - t0))
        r = rows[-1]
        print(f"{current}: {r['wall_s']:.0f} s; two-chamber {r['identification_rmse_n'].get('twochamber', 0):.2f} N, "
              f"lumped {r['identification_rmse_n'].get('lumped', 0):.2f} N; base {r['base_model']}; "
              + (f"best point from a later stage: {', '.join(r['best_point'])}; " if r["best_point"] else "")
              + f"{(r['verdict'] or '')[:120]}", flush=True)
    stages = list(dict.fromkeys(s for r in rows for s in r["stages"]))
    print("\n| stage | " + " | ".join(r["current"] for r in rows) + " |")
    print("| --- |" + " --- |" * len(rows))
    for s in stages:
        print(f"| {s} | " + " | ".join(f"{r['stages'].get(s, 0.0):.0f} s" for r in rows) + " |")
    print("| **wall time** | " + " | ".join(f"**{r['wall_s']:.0f} s**" for r in rows) + " |")
    (a.out / "real_currents.json").write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
