"""Linear critical speed of the Cooperrider car on S1002/UIC60 contact with each damper FMU as its four yaw
dampers, beside the car's own ``D6`` dashpots (``python -m tuner vehicle --fmus ... --cooperrider``).

The critical speed is the one of the DYTSI benchmark (``benchmarks/dytsi_cooperrider.py``,
:mod:`campaign.cooperrider_runs`): at each speed the car starts from a lateral offset of its leading
wheelset (0.1 mm) and runs for ``duration`` (10 s); the growth rate of the leading wheelset's response is
the logarithm of the ratio of its largest |y| over the last fifth of the run to that over 40-60 % of it
(8-10 s against 4-6 s), over the time between the windows' starts. The linear critical speed is where that
growth rate turns from negative to positive, interpolated linearly between the last decaying and the first
growing speed. The speeds are searched in ``rounds`` batches of ``per_round`` speeds run together
(:class:`tuner.vehicle.cooperrider_cosim.CooperriderCosim`): first spread over ``v_min``..``v_max``, then
inside the bracket found, so that the last bracket is ``(v_max - v_min) / ((per_round - 1)
(per_round + 1) ^ (rounds - 1))`` wide (0.39 m/s by default). A speed whose response leaves ``abort``
(5 mm) counts as growing; if the first growing speed of the last bracket did, only the bracket is given.

Above the critical speed, the response grows into a limit cycle: at 1.05 times each damper's critical speed
the car runs ``cycle_time`` (120 s) from the same offset and the cycle's amplitude is half the leading
wheelset's peak-to-peak motion over the last 10 s (the benchmark's measure: the amplitude beats for tens of
seconds before it settles; with the car's own dashpots it is 5 % larger over 50-60 s than over 110-120 s).
A run leaving the contact table's range (16 mm) gives no amplitude.

Writes ``cooperrider.json`` (strict JSON, SI units and km/h as the keys say) into the output folder (in a fit
output folder: its ``vehicle/`` sub-folder), which the report's vehicle section shows beside the cone car.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from campaign.contact_table import read_contact_table
from campaign.cooperrider_params import read_cooperrider_xml
from campaign.cooperrider_runs import DEFAULT_OFFSET, cycle_amplitude, offset_state, response_growth
from tuner import strict_json
from tuner.vehicle.compare import fmu_labels
from tuner.vehicle.cooperrider_cosim import (DEFAULT_ABORT, DEFAULT_COMM_STEP, DEFAULT_SUBSTEPS, CooperriderCosim,
                                             DamperCarRun)
from tuner.vehicle.cosim import check_damper_fmu

__all__ = ["CooperriderSearch", "CriticalSpeedSearch", "search_critical_speed", "growth_rates", "cycle_above",
           "cooperrider_study", "format_cooperrider_table", "speed_text", "cycle_text", "COOPERRIDER_FILE", "BUILT_IN",
           "CYCLE_FACTOR", "CYCLE_WINDOW", "CYCLE_ABORT"]

COOPERRIDER_FILE = "cooperrider.json"
"""The study's file in its output folder."""
BUILT_IN = "built-in D6 dashpot"
"""Label of the reference row: the car's own linear yaw dampers."""
CYCLE_FACTOR = 1.05
"""The limit cycle's speed, relative to the critical speed."""
CYCLE_WINDOW = 10.0
"""The last seconds [s] of the cycle run over which its amplitude is taken."""
CYCLE_ABORT = 0.016
"""Lateral displacement [m] of any wheelset that ends the cycle run (the contact table ends at 17 mm)."""


@dataclass(frozen=True)
class CooperriderSearch:
    """Settings of the search (SI units): speeds ``v_min``..``v_max`` [m/s], ``per_round`` speeds per batch,
    ``rounds`` batches, each run ``duration`` [s] from the leading wheelset's ``offset`` [m], stopped past
    ``abort`` [m]; the limit cycle's run ``cycle_time`` [s] (0: none); the co-simulation's communication
    ``step`` [s] and ``substeps``."""

    v_min: float = 30.0
    v_max: float = 250.0
    per_round: int = 8
    rounds: int = 3
    duration: float = 10.0
    offset: float = DEFAULT_OFFSET
    abort: float = DEFAULT_ABORT
    cycle_time: float = 120.0
    step: float = DEFAULT_COMM_STEP
    substeps: int = DEFAULT_SUBSTEPS

    def to_json(self) -> dict:
        """The settings as ``cooperrider.json``'s ``search`` (units in the keys)."""
        return {"v_min_ms": self.v_min, "v_max_ms": self.v_max, "per_round": self.per_round, "rounds": self.rounds,
                "duration_s": self.duration, "offset_m": self.offset, "abort_m": self.abort,
                "cycle_time_s": self.cycle_time, "cycle_factor": CYCLE_FACTOR, "cycle_window_s": CYCLE_WINDOW,
                "cycle_abort_m": CYCLE_ABORT, "step_s": self.step, "substeps": self.substeps}

    def __post_init__(self) -> None:
        if not (25.0 <= self.v_min < self.v_max and math.isfinite(self.v_max)):
            raise ValueError(f"need 25 m/s <= v_min < v_max (the car's Runge-Kutta step is stable from about "
                             f"25 m/s), got {self.v_min}, {self.v_max}")
        if not (isinstance(self.per_round, int) and self.per_round >= 2 and isinstance(self.rounds, int)
                and self.rounds >= 1):
            raise ValueError(f"need per_round >= 2 and rounds >= 1 (integers), got {self.per_round}, {self.rounds}")
        if not (self.duration >= 1.0 and 0.0 < self.offset < self.abort):
            raise ValueError(f"need duration >= 1 s and 0 < offset < abort, got {self.duration}, {self.offset}, "
                             f"{self.abort}")
        if not (self.cycle_time == 0.0 or self.cycle_time >= 2.0 * CYCLE_WINDOW):
            raise ValueError(f"cycle_time must be 0 (no cycle) or at least {2.0 * CYCLE_WINDOW:g} s, "
                             f"got {self.cycle_time}")


@dataclass
class CriticalSpeedSearch:
    """What :func:`search_critical_speed` found: every run's ``speeds`` [m/s], ``growth`` [1/s] (inf: stopped
    past the abort limit), the ``bracket`` (last decaying, first growing speed) [m/s] or None, the
    ``critical_speed`` [m/s] (None without a bracket or when its growing end was stopped), whether the car
    was stable up to ``v_max`` or unstable already at ``v_min``, and the ``wall_time_s``."""

    speeds: list = field(default_factory=list)
    growth: list = field(default_factory=list)
    bracket: tuple | None = None
    critical_speed: float | None = None
    stable_up_to_max: bool = False
    unstable_at_min: bool = False
    wall_time_s: float = 0.0

    def to_json(self) -> dict:
        """The strict-JSON entry of ``cooperrider.json`` (speeds in m/s and km/h, growth rates in 1/s)."""
        runs = [{"speed_ms": v, "growth_rate_per_s": g if math.isfinite(g) else None, "stopped_past_abort": not
                 math.isfinite(g)} for v, g in sorted(zip(self.speeds, self.growth))]
        v = self.critical_speed
        return {"critical_speed_ms": v, "critical_speed_kmh": None if v is None else 3.6 * v,
                "bracket_ms": None if self.bracket is None else list(self.bracket),
                "stable_up_to_max": self.stable_up_to_max, "unstable_at_min": self.unstable_at_min,
                "runs": runs, "wall_time_s": self.wall_time_s}


def growth_rates(run: DamperCarRun, duration: float) -> np.ndarray:
    """Growth rate [1/s] of the leading wheelset's response at each speed of ``run`` (module docstring;
    windows 0.4-0.6 and 0.8-1 of ``duration`` [s]); inf where the run stopped past the abort limit."""
    y, out = run.signal(), np.full(run.speeds.size, np.inf)
    for j in range(run.speeds.size):
        if not np.isfinite(run.stopped_at[j]):
            out[j] = response_growth(run.t, y[:, j], early=(0.4 * duration, 0.6 * duration),
                                     late=(0.8 * duration, duration))
    return out


def _bracket(speeds: list, growth: list) -> tuple | None:
    """The lowest (last decaying, first growing) pair of neighbouring speeds, or None."""
    order = np.argsort(speeds)
    v, g = np.asarray(speeds)[order], np.asarray(growth)[order]
    for j in range(1, v.size):
        if g[j - 1] <= 0.0 < g[j]:
            return (float(v[j - 1]), float(v[j])), (float(g[j - 1]), float(g[j]))
    return None


def search_critical_speed(cosim: CooperriderCosim, search: CooperriderSearch, *, log=print) -> CriticalSpeedSearch:
    """The linear critical speed of the car of ``cosim`` by ``search`` (module docstring)."""
    t0 = time.perf_counter()
    res, lo, hi = CriticalSpeedSearch(), search.v_min, search.v_max
    found = None
    for r in range(search.rounds):
        speeds = (np.linspace(lo, hi, search.per_round) if r == 0 else
                  np.linspace(lo, hi, search.per_round + 2)[1:-1])
        run = cosim.run(speeds, offset_state(search.offset)[:, 0], search.duration, abort=search.abort)
        g = growth_rates(run, search.duration)
        res.speeds += [float(v) for v in speeds]
        res.growth += [float(x) for x in g]
        log("  " + ", ".join(f"{v:.2f} m/s: " + (f"{x:+.4f} 1/s" if math.isfinite(x) else "past the limit")
                             for v, x in zip(speeds, g)))
        found = _bracket(res.speeds, res.growth)
        if found is None:
            break
        (lo, hi), _ = found
    if found is None:
        res.stable_up_to_max = all(x <= 0.0 for x in res.growth)
        res.unstable_at_min = all(x > 0.0 for x in res.growth)
    else:
        (v0, v1), (g0, g1) = found
        res.bracket = (v0, v1)
        if math.isfinite(g1):
            res.critical_speed = v0 - g0 * (v1 - v0) / (g1 - g0)
    res.wall_time_s = time.perf_counter() - t0
    return res


def cycle_above(cosim: CooperriderCosim, critical_speed: float, search: CooperriderSearch) -> dict:
    """The limit cycle at :data:`CYCLE_FACTOR` times ``critical_speed`` [m/s] (module docstring), as its
    ``cooperrider.json`` entry: ``cycle_speed_ms``, ``cycle_amplitude_m`` (None when the run left
    :data:`CYCLE_ABORT`), ``cycle_stopped_at_s`` (None: ran to the end), ``cycle_time_s``."""
    speed = CYCLE_FACTOR * critical_speed
    run = cosim.run([speed], offset_state(search.offset)[:, 0], search.cycle_time, abort=CYCLE_ABORT)
    stopped = float(run.stopped_at[0])
    amp = None if math.isfinite(stopped) else cycle_amplitude(run.t, run.signal()[:, 0], window=CYCLE_WINDOW)
    return {"cycle_speed_ms": speed, "cycle_amplitude_m": amp, "cycle_stopped_at_s": stopped if math.isfinite(stopped)
            else None, "cycle_time_s": search.cycle_time}


def cooperrider_study(fmus, out: Path, input_file, search: CooperriderSearch | None = None, *,
                      table_path=None, log=print) -> dict:
    """The linear critical speed of the Cooperrider car (parameters from the simulator's ``input_file``,
    :func:`campaign.cooperrider_params.read_cooperrider_xml`; contact table at ``table_path``, default the one
    the input file names) with its own ``D6`` dashpots and with each damper FMU of ``fmus`` (paths) as its yaw
    dampers; writes ``out / COOPERRIDER_FILE`` and returns its content."""
    search = search if search is not None else CooperriderSearch()
    paths = [Path(f) for f in fmus]
    for p in paths:
        check_damper_fmu(p)
    model = read_cooperrider_xml(input_file)
    table_path = Path(table_path) if table_path is not None else model.table_path
    table = read_contact_table(table_path)
    results = {}
    for label, fmu in [(BUILT_IN, None), *zip(fmu_labels(paths), paths)]:
        log(f"Cooperrider car, {label}: {search.rounds} rounds of {search.per_round} speeds, "
            f"{search.duration:g} s each")
        with CooperriderCosim(fmu, model.params, table, step=search.step, substeps=search.substeps) as co:
            res = search_critical_speed(co, search, log=log)
            results[label] = {"fmu": None if fmu is None else str(fmu), **res.to_json()}
            log(f"Cooperrider car, {label}: " + speed_text(results[label]) + f" ({res.wall_time_s:.0f} s)")
            if search.cycle_time > 0.0 and res.critical_speed is not None:
                t0 = time.perf_counter()
                results[label].update(cycle_above(co, res.critical_speed, search))
                results[label]["cycle_wall_time_s"] = time.perf_counter() - t0
                log(f"Cooperrider car, {label}: " + cycle_text(results[label]) + f" ({time.perf_counter() - t0:.0f} s)")
    p = model.params
    data = {"model": {"input_file": str(input_file),
                      "contact_table": str(table_path), "yaw_damper_D6_ns_per_m": p.D6,
                      "yaw_spring_k6_n_per_m": p.k6},
            "search": search.to_json(), "results": results}
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / COOPERRIDER_FILE).write_text(strict_json.dumps(data, indent=1))
    return data


def speed_text(entry: dict) -> str:
    """The critical speed of a ``cooperrider.json`` entry as text (m/s and km/h, or what was found instead: the
    bracket when its growing end left the abort limit, '> v' stable up to the top speed, '< v' unstable at the
    lowest)."""
    v, b = entry["critical_speed_ms"], entry["bracket_ms"]
    if v is not None:
        return f"{v:.2f} m/s ({3.6 * v:.0f} km/h)"
    if b is not None:
        return f"between {b[0]:.2f} and {b[1]:.2f} m/s (growing side past the limit)"
    if entry["stable_up_to_max"]:
        return f"> {max(r['speed_ms'] for r in entry['runs']):.0f} m/s"
    if entry["unstable_at_min"]:
        return f"< {min(r['speed_ms'] for r in entry['runs']):.0f} m/s"
    return "no change from decay to growth found"


def cycle_text(entry: dict) -> str:
    """The limit cycle of a ``cooperrider.json`` entry as text ('' when none was run)."""
    if entry.get("cycle_speed_ms") is None:
        return ""
    v, a = entry["cycle_speed_ms"], entry["cycle_amplitude_m"]
    if a is None:
        return f"at {v:.2f} m/s past {1e3 * CYCLE_ABORT:g} mm after {entry['cycle_stopped_at_s']:.1f} s"
    return f"cycle {1e3 * a:.3f} mm at {v:.2f} m/s"


def format_cooperrider_table(data: dict) -> str:
    """The study's critical speeds (and limit cycles) as text, one line per damper."""
    w = max(len(k) for k in data["results"])
    return "\n".join(f"{lab.ljust(w)}  {speed_text(r)}" + (f"; {cycle_text(r)}" if cycle_text(r) else "")
                     for lab, r in data["results"].items())
