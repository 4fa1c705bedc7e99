"""What the damper model changes in the vehicle: the same scenarios with several yaw damper FMUs.

Scenarios (vehicle of :mod:`campaign.vehicle`, four identical damper FMUs, 1 ms communication step):

* ``critical_speed``: hunting critical speed from lateral kick runs (:mod:`tuner.vehicle.hunting`);
  for an FMU of the linear Maxwell model also the eigenvalue critical speed at its ``k_s`` and ``c``;
* ``curve_entry``: straight -> clothoid -> R 500 m curve, cant 84 mm -> clothoid at 86 km/h with the low
  ERRI B176 lateral irregularity (the bundled campaign's ``val3_curve_R500_86``), 21 s;
* ``straight_irregular``: straight track at 300 km/h with the low ERRI B176 lateral irregularity, 10 s.

Figures per run (SI units; reported in the table in kN, m/s^2, mrad): peak and RMS yaw damper force
(largest over the four dampers), peak and RMS carbody lateral acceleration (accelerometer in the track
plane), peak bogie yaw relative to the track (largest of the two bogies).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from fmpy import read_model_description

from campaign.irregularity import A_LATERAL, synthesize
from campaign.scenarios import SCENARIOS, START_OFFSET, Scenario
from campaign.track import straight
from tuner.progress import advance, stage
from tuner.vehicle.cosim import VehicleCosim, check_damper_fmu
from tuner.vehicle.hunting import critical_speed_time_domain, eigen_critical_speed
from tuner import strict_json

__all__ = ["SCENARIO_NAMES", "compare_fmus", "fmu_scenarios", "ScenarioOptions", "ScenarioTask", "FmuScenarios", "scenario_runs",
           "run_figures", "summary_rows", "format_table",
           "VEHICLE_FOLDER", "fmu_labels", "maxwell_values"]

SCENARIO_NAMES = ("critical_speed", "curve_entry", "straight_irregular")
#: sub-folder of a tuner output folder for the vehicle consequences (``tuner.job``, the report)
VEHICLE_FOLDER = "vehicle"
_STRAIGHT_KMH = 300.0
_STRAIGHT_S = 10.0


def scenario_runs() -> dict[str, Scenario]:
    """The time-history scenarios (name -> campaign Scenario)."""
    curve = SCENARIOS["val3_curve_R500_86"]
    st = Scenario("straight_irregular", "validation", "Straight track at 300 km/h, low ERRI B176 lateral "
                  "irregularity", _STRAIGHT_KMH, (straight(2 * START_OFFSET + _STRAIGHT_KMH / 3.6 * _STRAIGHT_S + 50.0),),
                  True, _STRAIGHT_S, 0)
    return {"curve_entry": curve, "straight_irregular": st}


def _irregularity(sc: Scenario, seed: int, params):
    if not sc.irregular:
        return None
    V, T = sc.speed, sc.duration_s
    length = START_OFFSET + params.half_bogie_distance + params.semi_wheelbase + V * T + 10.0
    return synthesize(length, sc.seed_sequence(seed), A=A_LATERAL[sc.irregularity_level],
                      taper=2.0 * START_OFFSET + 0.5 * V)


def run_figures(run) -> dict[str, float]:
    """Peak/RMS figures of a :class:`tuner.vehicle.cosim.VehicleRun` (SI units)."""
    F = run.forces
    acc = run.carbody_lateral_acceleration
    return {
        "peak_damper_force_n": float(np.max(np.abs(F))),
        "rms_damper_force_n": float(np.max(np.sqrt(np.mean(F ** 2, axis=0)))),
        "peak_carbody_lateral_acceleration_ms2": float(np.max(np.abs(acc))),
        "rms_carbody_lateral_acceleration_ms2": float(np.sqrt(np.mean(acc ** 2))),
        "peak_bogie_yaw_rad": float(np.max(np.abs(run.bogie_yaw))),
    }


def maxwell_values(path: Path) -> dict | None:
    """``k_s`` [N/m] and ``c`` [N s/m] start values of a linear Maxwell FMU, else None."""
    md = read_model_description(str(path))
    names = {v.name: v for v in md.modelVariables}
    if md.coSimulation.modelIdentifier != "DamperMaxwell" or not {"k_s", "c"} <= set(names):
        return None
    return {"k_s": float(names["k_s"].start), "c": float(names["c"].start)}


def fmu_labels(paths) -> list[str]:
    """One label per FMU path: its file stem, ``-2``, ``-3``... appended to repeats."""
    labels = []
    for p in paths:
        lab = Path(p).stem
        k = 2
        base = lab
        while lab in labels:
            lab = f"{base}-{k}"
            k += 1
        labels.append(lab)
    return labels


@dataclass(frozen=True)
class ScenarioOptions:
    """How ``compare_fmus`` runs each FMU's ``scenarios`` (of SCENARIO_NAMES): the co-simulation ``step`` [s], the
    irregularity realisations' master ``seed``; the hunting search between ``v_min`` and ``v_max`` to ``tol`` [m/s]
    after a lateral ``kick`` [m]."""

    scenarios: tuple = SCENARIO_NAMES
    step: float = 1e-3
    seed: int = 0
    v_min: float = 100 / 3.6
    v_max: float = 1000 / 3.6
    tol: float = 1 / 3.6
    kick: float = 3e-3


@dataclass(frozen=True)
class ScenarioTask:
    """One FMU's scenarios for ``fmu_scenarios`` (a worker's task): its label, its path and the ``options``."""

    label: str
    fmu: str
    options: ScenarioOptions


@dataclass
class FmuScenarios:
    """What ``fmu_scenarios`` found for one FMU: its ``vehicle.json`` entry per scenario, the time histories and
    hunting searches the figures draw, and its log lines (said when the FMU is done)."""

    label: str
    entries: dict
    histories: dict
    lines: list


def fmu_scenarios(task: ScenarioTask, log=None) -> FmuScenarios:
    """Every scenario of ``task`` with its FMU as the four yaw dampers. ``log``: progress lines and stages as they
    come (None, in a worker: the lines are kept in the result for the job's log)."""
    lines, entries, histories = [], {"fmu": task.fmu}, {}
    say = log if log is not None else lines.append
    runs, lab, o = scenario_runs(), task.label, task.options
    with VehicleCosim(Path(task.fmu), step=o.step) as co:
        for name in o.scenarios:
            stage(say, f"{lab}: {name}")
            t0 = time.perf_counter()
            if name == "critical_speed":
                say(f"{lab}: critical speed, kick runs of 8 s between {o.v_min * 3.6:.0f} and "
                    f"{o.v_max * 3.6:.0f} km/h")
                res = critical_speed_time_domain(co, o.v_min, o.v_max, tol=o.tol, kick=o.kick, log=say)
                entry = {"critical_speed_kmh": res.speed_kmh if math.isfinite(res.speed) else None,
                         "stable_up_to_max": not math.isfinite(res.speed), "unstable_at_min": res.unstable_at_min,
                         "runs": [{"speed_kmh": v * 3.6, "growth_rate_per_s": s, "completed": d}
                                  for v, s, d in res.runs], "kick_m": o.kick}
                mx = maxwell_values(Path(task.fmu))
                if mx is not None:
                    ve = eigen_critical_speed(mx["k_s"], mx["c"], co.params, v_max=o.v_max)
                    entry["eigenvalue_critical_speed_kmh"] = ve * 3.6 if math.isfinite(ve) else None
                histories[name] = res
            else:
                sc = runs[name]
                run = co.run(sc.speed, sc.track(), _irregularity(sc, o.seed, co.params), sc.duration_s,
                             s0=START_OFFSET)
                entry = run_figures(run)
                histories[name] = run
            entry["wall_time_s"] = time.perf_counter() - t0
            entries[name] = entry
            advance(say, 1.0)
            say(f"{lab}: {name} done in {entry['wall_time_s']:.1f} s")
    return FmuScenarios(lab, entries, histories, lines)


def compare_fmus(fmus, out: Path, *, options: ScenarioOptions = ScenarioOptions(), executor=None, log=print) -> dict:
    """Run the scenarios of ``options`` (``ScenarioOptions``) with each damper FMU of ``fmus`` (paths), write
    ``vehicle.json`` and one figure per scenario (``<scenario>.png``) into ``out``; return the JSON content.
    ``executor``: an entered
    ``tuner.executors.FleetExecutor`` on which the FMUs run side by side (None: one after the other in
    this process; the results are the same). ``log``: progress lines (a :class:`tuner.progress.JobProgress`
    also gets the stages; each FMU's lines come when it is done)."""
    options = replace(options, scenarios=tuple(options.scenarios))
    scenarios, step, seed, kick = options.scenarios, options.step, options.seed, options.kick
    paths = [Path(f) for f in fmus]
    if not paths:
        raise ValueError("give at least one damper FMU")
    for p in paths:
        check_damper_fmu(p)
    unknown = [s for s in scenarios if s not in SCENARIO_NAMES]
    if unknown:
        raise ValueError(f"unknown scenario(s) {unknown}; choose from {list(SCENARIO_NAMES)}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tasks = [ScenarioTask(lab, str(p), options) for lab, p in zip(fmu_labels(paths), paths)]
    done = {}
    for k, found, err in (executor.run(fmu_scenarios, tasks) if executor is not None else
                          ((k, fmu_scenarios(t, log), None) for k, t in enumerate(tasks))):
        if err is not None:
            raise RuntimeError(f"vehicle: {tasks[k].fmu}: {type(err).__name__}: {err}") from err
        done[k] = found
        for line in found.lines:
            log(line)
        for name in scenarios if executor is not None else ():
            stage(log, f"{found.label}: {name}")
            advance(log, 1.0)
    results = {done[k].label: done[k].entries for k in sorted(done)}
    histories = {s: {done[k].label: done[k].histories[s] for k in sorted(done)} for s in scenarios}
    runs = scenario_runs()
    data = {"scenarios": {n: (runs[n].description if n in runs else "hunting critical speed, lateral kick "
                              f"{kick * 1e3:g} mm, straight ideal track") for n in scenarios},
            "step_s": step, "seed": seed, "results": results}
    (out / "vehicle.json").write_text(strict_json.dumps(data, indent=1))
    _figures(histories, out)
    return data


def _figures(histories: dict, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for name, by_fmu in histories.items():
        if not by_fmu:
            continue
        if name == "critical_speed":
            fig, ax = plt.subplots(figsize=(7, 4))
            for lab, res in by_fmu.items():
                v = np.array([r[0] for r in res.runs]) * 3.6
                s = np.array([r[1] for r in res.runs])
                o = np.argsort(v)
                ax.plot(v[o], s[o], "o-", label=f"{lab}: {res.speed_kmh:.0f} km/h" if math.isfinite(res.speed)
                        else f"{lab}: stable")
            ax.axhline(0.0, color="k", lw=0.8)
            ax.set_xlabel("speed [km/h]")
            ax.set_ylabel("growth rate after the kick [1/s]")
            ax.set_title("Hunting: growth rate of the least damped mode")
            ax.legend(fontsize=8)
        else:
            fig, axes = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
            for lab, run in by_fmu.items():
                axes[0].plot(run.t, run.forces[:, 0] * 1e-3, lw=0.8, label=lab)
                axes[1].plot(run.t, run.bogie_yaw[:, 0] * 1e3, lw=0.8, label=lab)
                axes[2].plot(run.t, run.carbody_lateral_acceleration, lw=0.8, label=lab)
            axes[0].set_ylabel("front right damper\nforce [kN]")
            axes[1].set_ylabel("front bogie yaw\n[mrad]")
            axes[2].set_ylabel("carbody lateral\nacceleration [m/s²]")
            axes[2].set_xlabel("time [s]")
            axes[0].legend(fontsize=8)
            axes[0].set_title(name.replace("_", " "))
        fig.tight_layout()
        fig.savefig(out / f"{name}.png", dpi=110)
        plt.close(fig)


def summary_rows(data: dict) -> tuple[list[str], list[tuple[str, list[str]]]]:
    """(FMU labels, [(quantity, cell text per label)]) of ``compare_fmus``'s result, in kN, m/s^2,
    mrad, km/h: the one layout of the side-by-side table (text and report)."""
    labels = list(data["results"])
    rows = []

    def fmt(v, scale=1.0, spec=".3g"):
        return "-" if v is None else format(v * scale, spec)

    for lab in labels:
        r = data["results"][lab]
        cs = r.get("critical_speed")
        if cs is not None:
            v = cs["critical_speed_kmh"]
            txt = (f"> {cs['runs'][1]['speed_kmh']:.0f}" if cs["stable_up_to_max"] else
                   f"< {cs['runs'][0]['speed_kmh']:.0f}" if cs["unstable_at_min"] else f"{v:.1f}")
            if cs.get("eigenvalue_critical_speed_kmh") is not None:
                txt += f" (eig {cs['eigenvalue_critical_speed_kmh']:.1f})"
            rows.append((lab, "critical speed [km/h]", txt))
        for name in ("curve_entry", "straight_irregular"):
            if name in r:
                f = r[name]
                rows.append((lab, f"{name}: peak / rms damper force [kN]",
                             f"{fmt(f['peak_damper_force_n'], 1e-3)} / {fmt(f['rms_damper_force_n'], 1e-3)}"))
                rows.append((lab, f"{name}: peak / rms carbody lat. acc. [m/s2]",
                             f"{fmt(f['peak_carbody_lateral_acceleration_ms2'])} / "
                             f"{fmt(f['rms_carbody_lateral_acceleration_ms2'])}"))
                rows.append((lab, f"{name}: peak bogie yaw [mrad]", fmt(f["peak_bogie_yaw_rad"], 1e3)))
    quantities = list(dict.fromkeys(q for _, q, _ in rows))
    cell = {(lab, q): v for lab, q, v in rows}
    return labels, [(q, [cell.get((lab, q), "-") for lab in labels]) for q in quantities]


def format_table(data: dict) -> str:
    """The side-by-side table of ``compare_fmus``'s result as text (``summary_rows``)."""
    labels, rows = summary_rows(data)
    w0 = max(len(q) for q, _ in rows)
    ws = [max(len(lab), *(len(cells[i]) for _, cells in rows)) for i, lab in enumerate(labels)]
    lines = ["  ".join([" " * w0, *(lab.rjust(w) for lab, w in zip(labels, ws))])]
    for q, cells in rows:
        lines.append("  ".join([q.ljust(w0), *(c.rjust(w) for c, w in zip(cells, ws))]))
    return "\n".join(lines)


def scenario_run(cosim, name: str, seed: int = 0):
    """One time-history scenario of ``scenario_runs`` (``curve_entry``, ``straight_irregular``) with the
    vehicle and dampers of ``cosim`` (a :class:`tuner.vehicle.cosim.VehicleCosim`): its ``VehicleRun``
    (``run_figures`` gives the figures). ``seed``: master seed of the irregularity realisation."""
    runs = scenario_runs()
    if name not in runs:
        raise ValueError(f"unknown time-history scenario {name!r}; choose from {list(runs)}")
    sc = runs[name]
    return cosim.run(sc.speed, sc.track(), _irregularity(sc, seed, cosim.params), sc.duration_s, s0=START_OFFSET)
