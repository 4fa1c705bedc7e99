"""The identification's parameter uncertainty carried to the vehicle: 95 % intervals of the hunting critical
speed and of the curve entry's peak yaw-damper force, for each tuned FMU.

Per tuned FMU of a fit output folder (``fmu/<Model>_tuned.fmu``, its model's entry in ``parameters.json``):

* parameter sets drawn from the fitted covariance in the identification's coordinates, where it is
  Gaussian, with the representation shift as a rank-one term, so each parameter spreads as its interval
  says (std^2 + s^2; ``tuner.identification.parameter_draws``: reflected at the bounds; the coordinates
  the tests do not see drawn uniformly within their bounds);
* each set is the four yaw dampers of the vehicle (``VehicleCosim.set_fmu_parameters``: the tuned FMU with
  those parameter values, not re-exported): the critical speed from the same kick runs as
  ``tuner.vehicle.compare`` (kick, growth rate of the least damped mode), found by
  ``hunting.critical_speed_near``: its bracket started around the fitted FMU's critical speed, its zero
  the robust line through the growth rates near it (a run whose growth rate is wrong does not decide it,
  as it can a bisection); and the curve entry's peak damper force (the same irregularity realisation for
  every draw: the interval is the parameters' alone). The fitted parameter set itself is run the same way:
  the nominal value the intervals are quoted with (within about 1 km/h of ``vehicle.json``'s bisection),
  searched also from half a bracket below and above: half the range of the three is the search's own
  scatter, stated beside the interval;
* the draws run in rounds of ``batch`` on a ``tuner.executors.FleetExecutor`` (a local process pool,
  a Dask LocalCluster or a Dask cluster), or in this process when no scheduler is given; an FMU stops
  drawing once both intervals' Monte-Carlo errors are below their targets, or at ``draws``;
* the 95 % interval (``figure_interval``): with enough draws for a distribution-free confidence interval
  of the 2.5 % and 97.5 % quantiles (the order statistics at ranks n p +- 1.96 sqrt(n p (1 - p)) inside the
  sample: from 200 draws), the empirical quantiles, their Monte-Carlo standard error from that
  confidence interval; with fewer, mean +- 1.96 standard deviations of the draws (normal theory), the
  standard error of its ends sd sqrt(1/n + 1.96^2 / (2 (n - 1))). The method and the error are stated.
  A draw stable up to the search's top speed, or unstable at its bottom one, counts at that speed
  (censored: said, and the percentile ends are used).

A draw whose simulation fails is left out and counted (``failed``). Units: SI inside (m/s, N); the
texts and the report in km/h and kN.
"""
from __future__ import annotations

import math
import time
from contextlib import nullcontext
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from damper_fmu.fmu import SLAVES
from tuner import strict_json
from tuner.executors import FleetExecutor
from tuner.identification.parameter_draws import draw_parameter_sets
from tuner.metrics import Z95
from tuner.progress import advance
from tuner.vehicle.compare import VEHICLE_FOLDER, run_figures, scenario_run
from tuner.vehicle.cosim import DEFAULT_STEP, VehicleCosim
from tuner.vehicle.hunting import DEFAULT_KICK, NearSearch, critical_speed_near

__all__ = ["PropagationSettings", "DrawTask", "DrawOutcome", "FigureInterval", "FmuIntervals", "run_draw",
           "figure_interval", "propagate", "close_cached", "INTERVALS_FILE", "INTERVALS_FOR", "NOMINAL_OFFSETS"]

#: the vehicle intervals' file in ``<out>/vehicle/``
INTERVALS_FILE = "intervals.json"
#: the fitted set's critical speed is searched from these guesses (the fitted FMU's critical speed plus the
#: offset times the first bracket's half width; indices -1, -2, -3): the first is the nominal value, the
#: spread of the three the search's own scatter
NOMINAL_OFFSETS = (0.0, -0.5, 0.5)
#: which tuned FMUs of a job get intervals (``tuner.job.interval_models``): the recommended model's, or all
INTERVALS_FOR = ("recommended", "all")
#: |skewness| of the draws beyond which the normal-theory interval is said to be rough
SKEWED = 1.0
_COSIMS: dict = {}


@dataclass(frozen=True)
class PropagationSettings:
    """How many draws and how each is run (module docstring); the unit ends each field's name.

    draws: the most parameter sets per FMU; batch: draws per round (and the fewest drawn); target_speed_ms:
    stop once the critical speed interval's ends are known to this Monte-Carlo standard error [m/s] ...;
    target_force_fraction: ... and the peak force's ends to this share of its nominal value; seed: of the
    draws; irregularity_seed: of the curve's irregularity; v_min_ms, v_max_ms, kick_m, step_s: the
    critical speed search's range and kick and the communication step (``tuner.vehicle.compare.compare_fmus``'s
    defaults); half_width_ms: the first bracket around the fitted FMU's critical speed; points, stages: kick
    runs per stage and stages of ``hunting.critical_speed_near``; models: the models whose tuned FMUs are drawn
    (None: every one in the folder). Two stages, not three (8 kick runs a draw, not
    11): on the bundled fit's two-chamber FMU a third stage brought the draws no closer to a finer search's (4
    stages of 4 runs: rms difference 2.1 km/h with either), nor on its lumped FMU, where 3 of 16 draws have two
    zero crossings 15-20 km/h apart that any of these searches may take (docs/measurements.md)."""

    draws: int = 24
    batch: int = 8
    target_speed_ms: float = 2.0 / 3.6
    target_force_fraction: float = 0.01
    seed: int = 0
    irregularity_seed: int = 0
    v_min_ms: float = 100.0 / 3.6
    v_max_ms: float = 1000.0 / 3.6
    kick_m: float = DEFAULT_KICK
    step_s: float = DEFAULT_STEP
    half_width_ms: float = 30.0 / 3.6
    points: int = 3
    stages: int = 2
    models: tuple[str, ...] | None = None

    def check(self) -> None:
        """ValueError naming the setting (its command-line option where there is one) and the fix."""
        if not isinstance(self.draws, int) or self.draws < 2:
            raise ValueError(f"--vehicle-draws must be an integer >= 2 (0 to skip the intervals), got {self.draws}")
        if not isinstance(self.batch, int) or self.batch < 2:
            raise ValueError(f"the draws per round must be an integer >= 2, got {self.batch}")
        if not (self.target_speed_ms > 0 and self.target_force_fraction > 0):
            raise ValueError("the Monte-Carlo error targets must be > 0")
        if not (0 < self.v_min_ms < self.v_max_ms and self.kick_m > 0 and self.half_width_ms > 0
                and 0 < self.step_s <= 0.01 and self.points >= 2 and self.stages >= 1):
            raise ValueError("need 0 < v_min < v_max, kick > 0, half_width > 0, 0 < step <= 0.01 s, points >= 2 "
                             "and stages >= 1")


@dataclass
class DrawTask:
    """One parameter set of one FMU to run in the vehicle (``run_draw``): index -1 is the fitted set;
    guess: where its critical speed is expected [m/s]."""

    fmu: str
    parameters: dict
    index: int
    guess: float
    settings: PropagationSettings


@dataclass
class DrawOutcome:
    """What one parameter set gives in the vehicle: critical_speed [m/s] (``inf``: stable up to v_max;
    v_min with unstable_at_min), peak_curve_force [N] (largest of the four dampers on the curve entry),
    kick runs of the search, wall and processor time [s] (the processor's is what a draw costs on a shared
    machine); error: why the draw could not be run (then the figures are NaN)."""

    index: int
    critical_speed: float
    unstable_at_min: bool
    peak_curve_force: float
    runs: int
    wall_time_s: float
    cpu_time_s: float = 0.0
    error: str | None = None


def _cosim(fmu: str, step: float) -> VehicleCosim:
    """The vehicle with four instances of ``fmu``, kept open in this process for the following draws."""
    key = (str(fmu), float(step))
    if key not in _COSIMS:
        _COSIMS[key] = VehicleCosim(fmu, step=step)
    return _COSIMS[key]


def close_cached() -> None:
    """Free the vehicles (and their FMU instances) ``run_draw`` kept open in this process."""
    while _COSIMS:
        _COSIMS.popitem()[1].close()


def run_draw(task: DrawTask) -> DrawOutcome:
    """The critical speed and the curve's peak damper force with the parameters of ``task`` (a worker
    function of the executors, ``tuner.executors``; the vehicle is kept open for the next draw of the same FMU)."""
    s = task.settings
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        co = _cosim(task.fmu, s.step_s)
        co.set_fmu_parameters(task.parameters)
        hunt = critical_speed_near(co, task.guess, search=NearSearch(
            half_width=s.half_width_ms, v_min=s.v_min_ms, v_max=s.v_max_ms, kick=s.kick_m, points=s.points,
            stages=s.stages))
        peak = run_figures(scenario_run(co, "curve_entry", s.irregularity_seed))["peak_damper_force_n"]
    except Exception as err:  # noqa: BLE001 -- a draw the FMU cannot run is counted, not fatal
        return DrawOutcome(task.index, math.nan, False, math.nan, 0, time.perf_counter() - t0,
                           time.process_time() - c0, f"{type(err).__name__}: {err}")
    return DrawOutcome(task.index, float(hunt.speed), hunt.unstable_at_min, float(peak), len(hunt.runs),
                       time.perf_counter() - t0, time.process_time() - c0)


# -- the statistics -----------------------------------------------------------------------------------

@dataclass
class FigureInterval:
    """The 95 % interval of one vehicle figure over the draws (module docstring), SI units.

    nominal: with the fitted parameters; low/high: the interval's ends; mean/std: of the draws; draws:
    counted draws; failed: draws left out; censored_low/high: draws at the search range's bottom/top
    (unstable at v_min / stable to v_max); method: 'normal' or 'percentile'; mc_error: Monte-Carlo standard
    error of the ends (None when the draws cannot tell); skewness: of the draws (normal theory assumes about
    0: beyond SKEWED, ``error_text`` says the ends are rough)."""

    quantity: str
    unit: str
    nominal: float | None
    low: float
    high: float
    mean: float
    std: float
    draws: int
    failed: int
    method: str
    mc_error: float | None
    censored_low: int = 0
    censored_high: int = 0
    skewness: float = 0.0

    def text(self, scale: float = 1.0, unit: str | None = None, spec: str = ".0f") -> str:
        """'804 km/h (95 %: 790-815)' in ``unit`` (the values times ``scale``)."""
        u = self.unit if unit is None else unit
        f = lambda v: format(v * scale, spec)  # noqa: E731
        nominal = "-" if self.nominal is None else f(self.nominal)
        low = f"<= {f(self.low)}" if self.censored_low and self.low <= self.mean else f(self.low)
        high = f">= {f(self.high)}" if self.censored_high and self.high >= self.mean else f(self.high)
        return f"{nominal} {u} (95 %: {low}-{high})"

    def error_text(self, scale: float = 1.0, unit: str | None = None, spec: str = ".1f") -> str:
        """'ends +-1.8 km/h (Monte-Carlo, 24 draws, normal theory)'."""
        u = self.unit if unit is None else unit
        err = "not estimable" if self.mc_error is None else f"+-{format(self.mc_error * scale, spec)} {u}"
        method = "normal theory" if self.method == "normal" else "empirical quantiles"
        failed = f", {self.failed} failed" if self.failed else ""
        skew = (f"; the draws are skewed (skewness {self.skewness:+.1f}): the normal-theory ends are rough, about "
                f"200 draws give the empirical quantiles" if self.method == "normal" and abs(self.skewness) > SKEWED
                else "")
        return f"ends {err} (Monte-Carlo, {self.draws} draws{failed}, {method}){skew}"

    def to_dict(self) -> dict:
        return asdict(self)


def _rank_interval(n: int, p: float) -> tuple[int, int] | None:
    """0-based order statistics (a, b) bounding the p-quantile of n draws with 95 % confidence, or None
    when they fall outside the sample (too few draws)."""
    s = math.sqrt(n * p * (1.0 - p))
    a, b = round(n * p - Z95 * s) - 1, round(n * p + Z95 * s) - 1  # 1-based ranks n p -+ 1.96 s
    return (a, b) if a >= 0 and b <= n - 1 else None


def figure_interval(values, nominal: float | None, quantity: str, unit: str, *, failed: int = 0,
                    bottom: float = -math.inf, top: float = math.inf) -> FigureInterval:
    """The 95 % interval of ``values`` (one per counted draw, SI) (module docstring); values at or beyond
    ``bottom``/``top`` (the search range) are censored there."""
    x = np.sort(np.clip(np.asarray(values, dtype=float), bottom, top))
    n = x.size
    if n < 2:
        raise ValueError(f"{quantity}: need at least 2 draws that ran, got {n} ({failed} failed)")
    cens_lo, cens_hi = int(np.sum(x <= bottom)), int(np.sum(x >= top))
    mean, std = float(np.mean(x)), float(np.std(x, ddof=1))
    skew = float(np.mean((x - mean) ** 3) / std ** 3) if std > 0 else 0.0
    ranks = [_rank_interval(n, p) for p in (0.025, 0.975)]
    if all(ranks) or cens_lo or cens_hi:
        low, high = (float(v) for v in np.quantile(x, [0.025, 0.975]))
        err = (max(x[b] - x[a] for a, b in ranks) / (2.0 * Z95)) if all(ranks) else None
        method = "percentile"
    else:
        low, high = mean - Z95 * std, mean + Z95 * std
        err, method = std * math.sqrt(1.0 / n + Z95 ** 2 / (2.0 * (n - 1))), "normal"
    return FigureInterval(quantity, unit, nominal, low, high, mean, std, n, failed, method,
                          None if err is None else float(err), cens_lo, cens_hi, skew)


# -- the whole folder ---------------------------------------------------------------------------------

@dataclass
class FmuIntervals:
    """The vehicle intervals of one tuned FMU: label (the FMU's stem, as ``vehicle.json``'s), model kind,
    fmu path, draws (``ParameterDraws.to_dict()``: how they were made), critical_speed [m/s] and
    peak_curve_force [N] (``FigureInterval``), outcomes (every ``DrawOutcome``, the fitted set's indices -1 to
    -3), stop: why drawing stopped; search_scatter [m/s]: half the range of the fitted set's critical speeds
    searched from the three guesses of ``NOMINAL_OFFSETS`` (the search's own resolution)."""

    label: str
    model: str
    fmu: str
    draws: dict
    critical_speed: FigureInterval
    peak_curve_force: FigureInterval
    outcomes: list = field(default_factory=list)
    stop: str = ""
    search_scatter: float | None = None

    def headline(self, name: str | None = None) -> str:
        """'critical speed 804 km/h (95 %: 790-815), curve peak damper force 9.5 kN (95 %: 9.3-9.7) with the
        lumped FMU' (``name``: how to call the FMU; default its model kind)."""
        return (f"critical speed {self.critical_speed.text(3.6, 'km/h')}, curve entry peak damper force "
                f"{self.peak_curve_force.text(1e-3, 'kN', '.2f')} with the {name or self.model} FMU")

    def to_dict(self) -> dict:
        return {"model": self.model, "fmu": self.fmu, "draws": self.draws, "stop": self.stop,
                "search_scatter_ms": self.search_scatter,
                "critical_speed": self.critical_speed.to_dict(), "peak_curve_force": self.peak_curve_force.to_dict(),
                "critical_speed_text": self.critical_speed.text(3.6, "km/h"),
                "peak_curve_force_text": self.peak_curve_force.text(1e-3, "kN", ".2f"),
                "outcomes": [asdict(o) for o in sorted(self.outcomes, key=lambda o: o.index)]}


class _InProcess:
    """The executors' interface, run one task after another in this process (no scheduler given)."""

    description = "this process"

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        close_cached()

    def run(self, fn, tasks: list):
        for i, t in enumerate(tasks):
            yield i, fn(t), None


@dataclass
class _Plan:
    """One FMU's draws in progress."""

    model: str
    fmu: Path
    draws: object  # ParameterDraws
    guess: float
    done: dict = field(default_factory=dict)  # index -> DrawOutcome
    next_index: int = 0
    stop: str = ""


def _figures(plan: _Plan, s: PropagationSettings) -> tuple[FigureInterval, FigureInterval]:
    """The two intervals of ``plan``'s draws so far."""
    nominal = plan.done.get(-1)
    ok = [o for k, o in plan.done.items() if k >= 0 and o.error is None]
    failed = sum(1 for k, o in plan.done.items() if k >= 0 and o.error is not None)
    speeds = [-math.inf if o.unstable_at_min else o.critical_speed for o in ok]
    nom_speed = None if nominal is None or nominal.error or not math.isfinite(nominal.critical_speed) \
        else nominal.critical_speed
    nom_force = None if nominal is None or nominal.error else nominal.peak_curve_force
    cs = figure_interval(speeds, nom_speed, "critical speed", "m/s", failed=failed, bottom=s.v_min_ms,
                         top=s.v_max_ms)
    pf = figure_interval([o.peak_curve_force for o in ok], nom_force, "curve entry peak damper force", "N",
                         failed=failed)
    return cs, pf


def _stop_reason(plan: _Plan, s: PropagationSettings) -> str:
    """Why ``plan`` draws no more ('' while it goes on)."""
    ok = sum(1 for k, o in plan.done.items() if k >= 0 and o.error is None)
    if plan.next_index >= s.draws:
        return f"all {s.draws} draws run" + ("" if ok >= 2 else f" ({s.draws - ok} failed)")
    if ok < 2:
        return ""
    cs, pf = _figures(plan, s)
    if cs.mc_error is not None and pf.mc_error is not None and cs.mc_error <= s.target_speed_ms \
            and pf.mc_error <= s.target_force_fraction * abs(pf.nominal or pf.mean):
        return (f"Monte-Carlo errors below their targets ({s.target_speed_ms * 3.6:g} km/h, "
                f"{100 * s.target_force_fraction:g} % of the force) after {plan.next_index} draws")
    return ""


def _run_rounds(plans: list[_Plan], s: PropagationSettings, executor, log) -> None:
    """Rounds of ``s.batch`` draws of every FMU still drawing (the fitted sets in the first), until each stops."""
    total = sum(s.draws + len(NOMINAL_OFFSETS) for _ in plans)
    finished = 0
    first = True
    while any(not p.stop for p in plans):
        tasks = []
        for p in plans:
            if p.stop:
                continue
            if first:  # the fitted set, from the guess and from half a bracket below and above it
                tasks += [DrawTask(str(p.fmu), dict(p.draws.fitted), -1 - k, p.guess + d * s.half_width_ms, s)
                          for k, d in enumerate(NOMINAL_OFFSETS)]
            k1 = min(p.next_index + s.batch, s.draws)
            tasks += [DrawTask(str(p.fmu), p.draws.sets[k], k, p.guess, s) for k in range(p.next_index, k1)]
            p.next_index = k1
        first = False
        owner = {id(t): p for p in plans for t in tasks if t.fmu == str(p.fmu)}
        for i, res, err in executor.run(run_draw, tasks):
            t = tasks[i]
            owner[id(t)].done[t.index] = res if err is None else DrawOutcome(
                t.index, math.nan, False, math.nan, 0, 0.0, 0.0, f"{type(err).__name__}: {err}")
            finished += 1
            advance(log, finished / total)
        for p in plans:
            if not p.stop:
                p.stop = _stop_reason(p, s)
                if p.stop:
                    total -= s.draws - p.next_index
                    log(f"vehicle intervals: {p.fmu.name}: {p.stop}")


def _plans(folder: Path, s: PropagationSettings, log) -> list[_Plan]:
    """One plan per tuned FMU of ``folder`` whose model has a covariance (of ``s.models`` when given); the first
    bracket around the critical speed ``vehicle/vehicle.json`` gives (else the middle of the search range)."""
    path = folder / "parameters.json"
    if not path.is_file():
        raise FileNotFoundError(f"{path}: not found (the vehicle intervals need a fit output folder)")
    params = strict_json.loads(path.read_text())
    vpath = folder / VEHICLE_FOLDER / "vehicle.json"
    known = strict_json.loads(vpath.read_text()).get("results", {}) if vpath.is_file() else {}
    plans = []
    for model, entry in params.items():
        if s.models is not None and model not in s.models:
            continue
        fmu = folder / "fmu" / f"{SLAVES[model]}_tuned.fmu"
        if not fmu.is_file():
            log(f"vehicle intervals: {model}: no {fmu} (skipped)")
            continue
        try:
            draws = draw_parameter_sets(model, entry, s.draws, s.seed)
        except ValueError as err:
            log(f"vehicle intervals: {err} (skipped)")
            continue
        v = ((known.get(fmu.stem) or {}).get("critical_speed") or {}).get("critical_speed_kmh")
        guess = v / 3.6 if v is not None else 0.5 * (s.v_min_ms + s.v_max_ms)
        plans.append(_Plan(model=model, fmu=fmu, draws=draws, guess=guess))
    return plans


def propagate(folder, settings: PropagationSettings = PropagationSettings(), *, scheduler: str | None = None,
              executor=None, log=print) -> dict:
    """The vehicle intervals of every tuned FMU of the fit output folder ``folder`` (module docstring), written
    to ``folder/vehicle/intervals.json`` and returned. ``scheduler``: where the draws run
    (``tuner.executors.parse_scheduler``: pool:N, local:N, a Dask address), None: in this process;
    ``executor``: an entered ``FleetExecutor`` to run them on instead (left open: the caller's).
    ``log``: progress lines (and, for a ``tuner.progress.JobProgress``, the stage's progress)."""
    folder = Path(folder)
    settings.check()
    plans = _plans(folder, settings, log)
    t0 = time.perf_counter()
    own = executor is None
    if own:
        executor = FleetExecutor(scheduler) if scheduler else _InProcess()
    if plans:
        log(f"vehicle intervals: up to {settings.draws} parameter sets per FMU ({len(plans)} FMUs) on "
            f"{executor.description} ...")
        with executor if own else nullcontext(executor):
            _run_rounds(plans, settings, executor, log)
    results, errors = {}, {}
    for p in plans:
        try:
            cs, pf = _figures(p, settings)
        except ValueError as err:  # fewer than two draws ran: said, the other FMUs' intervals stand
            errors[p.fmu.stem] = str(err)
            log(f"vehicle intervals: {p.fmu.name}: {err}")
            continue
        nominal = [o.critical_speed for k, o in p.done.items() if k < 0 and o.error is None]
        scatter = 0.5 * (max(nominal) - min(nominal)) if len(nominal) > 1 and np.all(np.isfinite(nominal)) else None
        used = replace(p.draws, sets=p.draws.sets[:p.next_index])  # the sets drawn, not the most planned
        results[p.fmu.stem] = FmuIntervals(p.fmu.stem, p.model, str(p.fmu), used.to_dict(), cs, pf,
                                           list(p.done.values()), p.stop, scatter)
        log(f"vehicle intervals: {results[p.fmu.stem].headline()}; {cs.error_text(3.6, 'km/h')}")
    data = {"settings": asdict(settings), "where": executor.description, "method": __doc__.split("\n\n")[1],
            "wall_time_s": time.perf_counter() - t0,
            "results": {k: r.to_dict() for k, r in results.items()}, "errors": errors}
    out = folder / VEHICLE_FOLDER
    out.mkdir(parents=True, exist_ok=True)
    (out / INTERVALS_FILE).write_text(strict_json.dumps(data, indent=1))
    return data
