"""Identification: the Firefly algorithm and the local refinement per model, then validation
through the FMU the user gets. ``fit`` returns a ``FitResult``; ``FitResult.write`` stores it (SI units
everywhere); ``tuner.job`` runs the whole job (FMUs, diagnosis, report):

    parameters.json        identified values, units, bounds, parametrization per model, and the 95 %
                           intervals with identifiability flags of every identified parameter
                           (``intervals``: ``tuner.identification.intervals.ModelIntervals.to_dict``;
                           null with ``intervals_note`` saying why when they could not be computed)
    metrics.json           settings/provenance, metrics per test and model, the paper's Table 3,
                           quality gate (the job adds the full-rate check, tuner.identification.full_rate)
    history_<model>.json   mean/best fitness per generation, initial and final populations
    simulations.npz        per test: time, stroke, measured force, simulated force per model
    checkpoints/<model>.json  Firefly state after every iteration (``--resume`` continues from it)

Objective: G = N / SSE over the identification tests at the fit rate (paper eq. 5), skipping the
first ``warmup_s`` of each test (the model starts force-free; the damper may not). Validation
metrics (Table 3, and the diagnosis' before/after: one definition, ``validation_run``) compare
the measured and simulated forces in the fit band, both through the same anti-aliasing low-pass
(``tuner.identification.engine``), the simulation by the built FMU at its own default internal steps. At the
file's own rate the comparison was dominated by the silent block's damping c_B times the noise of
the differentiated stroke velocity (measured: 585 N RMSE at 1 kHz against 54 N in the fit band on
lumped-model data), which no damper parameter can fix.
"""
from __future__ import annotations

import collections
import hashlib
import json
import math
import tempfile
import time
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from damper_fmu.fmu import ensure_fmu
from damper_fmu.models import ConvergenceError
from damper_fmu.parameters import EFFECT_MODELS, SERIES_ELEMENT, defaults

from tuner.data.reading import RigTest
from tuner.identification import firefly
from tuner.identification.engine import Engine, Signals
from tuner.identification.floor import ResidualFloor
from tuner.identification.full_rate import MIN_RATE_RATIO, comparison_rate, full_rate_check
from tuner.identification.intervals import parameter_intervals, reached_ranges
from tuner.identification.parametrization import Parametrization
from tuner.identification.polish import FTOL, TYPICAL_JACOBIANS, PolishResult, polish, resolution_stop, small_progress
from tuner.identification.problem import DataSettings, Problem, prepared_signals, split_data_settings
from tuner.identification.restart_check import (ROUNDS, SOFTEST_SERIES, TYPICAL_RESTARTS, RestartCheck, SeriesHold,
                                               restart_check, series_decades)
from tuner.identification.runner import SimulationError
from tuner.identification.search_window import search_windows
from tuner.identification.validation import validation_run
from tuner.metrics import noise_std, rmse_of_fitness
from tuner.progress import advance, expect, stage
from tuner import strict_json
from tuner.time_budget import section

__all__ = ["FitSettings", "FitResult", "Identified", "IdentifyOptions", "fit", "initial_guess", "validation_run", "identify",
           "search_stop_now", "first_improvement", "search_iterations_left", "quality_gate", "QUALITY_AME_PCT",
           "RACE_RATIO", "RESTART_LADDER",
           "refinement_starts", "fit_order", "Validated", "validated_metrics", "revalidate", "model_intervals"]

#: Log-scaled parameters whose decade decides the basin a local refinement ends in: the data-driven
#: start is refined again with each one a decade up and down (measured on random lumped dampers: one
#: ended at 2.0x the floor with k_B 8e7 N/m from every start near the preset, and at the floor from
#: k_B 1e9 N/m; another at 1.4x in a "blocks as dashpots" basin from the four starts with k_B alone,
#: and at the floor from c_B a decade up or down).
RESTART_LADDER = {"lumped": ("k_B", "c_B")}


#: iterations over which the Firefly's evaluation rate is measured for the progress display: the rate since the
#: start (its first iterations wait for the worker processes: 5.5 eval/s against 20 later) overstated the time left
RATE_WINDOW = 5


def refinement_starts(model: str) -> int:
    """The local refinements ``identify`` runs at most for ``model``: from the Firefly best, the data-driven start
    and, per RESTART_LADDER parameter, that start with it ten times larger and ten times smaller."""
    return 2 + 2 * len(RESTART_LADDER.get(model, ()))


#: A base form whose refinement leaves more than this many times another base form's identification
#: RMSE is clearly the wrong form: its refinement is not restarted (``identify``, ``rival``).
RACE_RATIO = 3.0
#: Quality gate [% of the test's peak force]: a model whose AME exceeds it on a held-out test does
#: not describe the data (the lumped model reaches 1-3 % on yaw-damper data; Maxwell 5-15 %).
QUALITY_AME_PCT = 10.0


@dataclass
class FitSettings:
    """Run settings (units in the names). Defaults: the paper's Firefly budget.

    data: the problem definition (fit rate [Hz], warm-up [s], differentiator band [Hz], table abscissae
    [m/s, m], force limit [N], spring reference [N/m], parametrization: ``DataSettings``)."""

    models: tuple = ("lumped", "maxwell", "twochamber")
    data: DataSettings = field(default_factory=DataSettings)
    population: int = 20
    iterations: int = 150
    workers: int = 2
    seed: int = 0
    engine: str = "fmu"
    init: str = "seeded"
    stop_tol: float | None = 1e-3
    polish_jacobians: int = 100  # a safety cap: the refinement stops when converged
    extra: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """One flat record (the problem definition's fields beside the run's; ``from_dict`` reads it back)."""
        d = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "data"}
        d["models"] = list(self.models)
        return {**d, **self.data.to_dict()}

    @classmethod
    def from_dict(cls, flat: dict) -> "FitSettings":
        """The settings of a flat record (``to_dict``, a fleet row's, metrics.json "settings" of a run: keys
        that are no setting, such as the run's provenance, are refused by name)."""
        data, rest = split_data_settings(flat)
        known = {f.name for f in fields(cls)} - {"data"}
        unknown = sorted(set(rest) - known)
        if unknown:
            raise ValueError(f"unknown fit setting(s) {', '.join(map(repr, unknown))}; known: "
                             f"{', '.join(sorted(known | set(data.to_dict())))}")
        if "models" in rest:
            rest["models"] = tuple(rest["models"])
        return cls(**rest, data=data)


def initial_guess(model: str, tests: list[Signals], par: Parametrization) -> dict:
    """Data-driven starting individual: quasi-static force-velocity table and a Maxwell fit.

    Fc,O ordinates: median measured force among quasi-static samples whose stroke velocity lies
    within +-15 % of each abscissa (monotone envelope; abscissae without samples extrapolated
    with the outermost slope). Quasi-static: the series spring's deflection rate |dF/dt| / k_ref
    is below 20 % of |v|, so the dashpot moves with the stroke. Maxwell: least-squares dashpot c
    from F ~ c v. Other parameters: the preset mapped to the damper's scale (``par.fixed``).
    """
    v = np.concatenate([s.stroke_velocity[s.mask] for s in tests])
    f = np.concatenate([s.force[s.mask] for s in tests])
    dfdt = np.concatenate([np.gradient(s.force, s.time)[s.mask] for s in tests])
    quasi_static = np.abs(dfdt) / par.spring_reference < 0.2 * np.abs(v)
    guess = {**defaults(model), **par.fixed}
    if model == "maxwell":
        c = float(np.dot(v, f) / max(np.dot(v, v), 1e-30))
        lo, hi = par.bounds["c"]
        guess["c"] = min(max(c, lo), hi)
        return guess
    if "Fc_01" not in guess:
        return guess
    names = [n for n in par.names if n.startswith("Fc_")]
    for side_sign in (1.0, -1.0):
        side = sorted([(abs(guess[n.replace("Fc_", "Fc_v")]), n) for n in names
                       if np.sign(guess[n.replace("Fc_", "Fc_v")]) == side_sign])
        prev_v, prev_f, slope = 0.0, 0.0, None
        for vx, n in side:
            sel = (np.abs(side_sign * v - vx) <= 0.15 * vx) & quasi_static
            if sel.sum() >= 5:
                fx = max(abs(float(np.median(f[sel]))), prev_f)
                slope = (fx - prev_f) / (vx - prev_v)
            elif slope is not None:
                fx = prev_f + slope * (vx - prev_v)
            else:
                fx = abs(guess[n])
            fx = min(fx, par.force_limit)
            guess[n] = side_sign * fx
            prev_v, prev_f = vx, fx
    return guess


def _settings_hash(settings: FitSettings, data_digest: str, model: str) -> str:
    # options that may change when a run is resumed: budget, stopping rule, refinement, workers
    free = ("workers", "extra", "iterations", "stop_tol", "polish_jacobians")
    keep = {k: v for k, v in settings.to_dict().items() if k not in free}
    return hashlib.sha256(json.dumps([keep, data_digest, model], sort_keys=True, default=str).encode()).hexdigest()[:16]


@dataclass(frozen=True)
class Identified:
    """One model identified (``identify``): the best parameter values [SI], the history (search, refinement,
    stop rules: ``history_<model>.json``) and, when asked, the intervals (``_intervals``: {"intervals": the
    ``ModelIntervals`` as a dict} or {"intervals": None, "intervals_note": why}); None when not asked."""

    values: dict
    history: dict
    intervals: dict | None = None


@dataclass(frozen=True)
class IdentifyOptions:
    """What ``identify`` knows beside the model and its data. ``rival``: (model, identification RMSE [N]) of another
    base form already fitted to the same data; when the first refinement leaves more than ``RACE_RATIO`` x its
    RMSE, this form is clearly the wrong one and gets no restart (the effort goes to the contender);
    ``rival_at_floor``: the rival's refinement ended at the residual floor, and this form's search stops once it is
    RACE_RATIO x behind (``search_stop_now``). ``intervals``: the parameters' intervals at the best point too,
    through the same engine's workers (d + 1 simulations in parallel). ``floor``: the problem's residual floor; a
    first refinement within ``FLOOR_REACHED`` x of it is not restarted."""

    rival: tuple[str, float] | None = None
    rival_at_floor: bool = False
    intervals: bool = False
    floor: ResidualFloor | None = None


def identify(model: str, signals: list[Signals], settings: FitSettings, par: Parametrization,
             ckpt: Path, digest: str, log, *, options: IdentifyOptions = IdentifyOptions()) -> Identified:
    """Run Firefly and the local refinements for one model (``options``: the rival, the intervals, the residual
    floor; ``IdentifyOptions``), its Firefly state checkpointed in ``ckpt`` under the data's ``digest``."""
    rival, rival_at_floor = options.rival, options.rival_at_floor
    opts = firefly.FireflyOptions(population=settings.population, max_iterations=settings.iterations,
                                  stop_tol=settings.stop_tol)
    windows = search_windows(signals)
    key = _settings_hash(settings, windows.keyed(digest), model)
    state = _resumed_state(ckpt, key, model, log)
    guess_p = initial_guess(model, signals, par)  # seeds the first population and restarts the refinement
    guess = par.from_params(guess_p)
    seeded = settings.init == "seeded" and state is None
    initial = np.array([guess, par.from_params(par.preset)]) if seeded else None
    engine_path = ensure_fmu(model) if settings.engine == "fmu" else None
    t_start = time.perf_counter()
    evals_start = state.evaluations if state else 0
    first_population = {}
    recent = collections.deque([(t_start, evals_start)], maxlen=RATE_WINDOW + 1)  # (time [s], evaluations)

    search_stop = {}
    section(log, "Firefly search")
    log(f"[{model}] {windows.text()}")
    kw = dict(engine=settings.engine, workers=settings.workers, fmu_path=engine_path,
              max_internal_step=settings.data.internal_step_s)
    with Engine(model, signals, **kw) as eng, windows.engine(eng, model, **kw) as search_eng:
        def evaluate(Z):
            return search_eng.fitness_batch([par.to_params(z) for z in Z])

        def at_resolution(st: firefly.FireflyState) -> bool:
            search_stop.update(search_stop_now(st, opts, search_eng, par, rival if rival_at_floor else None))
            if search_stop:
                log(f"[{model}] Firefly {search_stop['text']}: the local refinement takes over"
                    + (" (and its restart check)" if search_stop["reason"] == "stall" else ""))
            return bool(search_stop)

        def callback(st: firefly.FireflyState):
            if st.iteration == 0 and "pop" not in first_population:
                first_population["pop"] = st.population.copy()
            tmp = ckpt.with_suffix(".tmp")
            tmp.write_text(strict_json.dumps({"key": key, "state": st.to_dict(),
                                       "initial_population": (first_population.get("pop", st.population)).tolist()}))
            tmp.replace(ckpt)
            el = time.perf_counter() - t_start
            rate = (st.evaluations - evals_start) / el if el > 0 else float("nan")
            best = st.best_fitness
            rmse = rmse_of_fitness(best)
            left = (settings.iterations - st.iteration) * settings.population / rate if rate > 0 else float("nan")
            log(f"[{model}] iter {st.iteration:3d}/{settings.iterations}  best G {best:.4e} (RMSE {rmse:7.1f} N)"
                f"  mean G {st.history_mean[-1]:.4e}  {rate:5.1f} eval/s  search ~{left / 60:4.1f} min left at most")
            advance(log, 0.85 * st.iteration / max(settings.iterations, 1))
            recent.append((time.perf_counter(), st.evaluations))
            _expect_search(log, model, st, opts, settings.population, par.dimension, recent)
            return at_resolution(st)

        if state is not None and ckpt.exists():
            first_population["pop"] = np.array(strict_json.loads(ckpt.read_text()).get("initial_population"))
        result = firefly.run(evaluate, par.dimension, options=opts, seed=settings.seed, state=state,
                             callback=callback, initial=initial)
        last_failure = search_eng.last_failure
        ref = _refine(eng, model, par, settings, result, guess_p, log, options)
        elapsed = time.perf_counter() - t_start
        section(log, "intervals")
        ivs = (model_intervals(eng, model, signals, par, par.to_params(ref.z), log) if options.intervals and ref.g > 0.0
               else None)
    if ref.g <= 0.0:
        raise ValueError(f"[{model}] no candidate could be simulated; the last failure: {last_failure or 'none'}. "
                         f"Check the units of the input files (a stroke in mm read as m exceeds the FMU's "
                         f"stroke_limit) or use --parametrization improved")
    history = {**_history(result, ref, par, first_population, search_stop, elapsed),
               "search_window": windows.to_dict()}
    log(f"[{model}] done: Firefly {history['stop_reason']} after {result.iterations} iterations on its windows "
        f"(RMSE {rmse_of_fitness(result.fitness_best):.1f} N), {result.evaluations + ref.evaluations} evaluations, "
        f"{elapsed:.0f} s; identification RMSE {rmse_of_fitness(ref.g):.1f} N")
    return Identified(par.to_params(ref.z), history, ivs)


def search_stop_now(st: firefly.FireflyState, opts: firefly.FireflyOptions, eng, par: Parametrization,
                    rival_at_floor: tuple[str, float] | None) -> dict:
    """Why the Firefly search stops after iteration ``st.iteration`` ({} while it goes on; else 'reason' and
    'text'), never before ``opts.stop_start`` iterations nor with the stop off (``--no-stop``: the whole budget,
    as the paper's stagnation test).

    'clearly the wrong form' when ``rival_at_floor`` (model, RMSE [N]), another base form whose refinement ended
    at the residual floor, leaves this one's best more than RACE_RATIO x behind (the rival explains all but the
    noise, this form cannot win: on lumped data the two-chamber search ran 110 iterations, 2 of the job's 4
    minutes, to end 10 x the lumped form's RMSE).

    The paper's brightest firefly does not move, so a seeded start that no firefly has passed stands still
    whatever the swarm does: no change of the best is then no convergence. 'stall' when no firefly has improved
    on the first generation's best (``first_improvement``) in ``opts.stop_window`` iterations: said as such, and
    the refinement's restart check (``tuner.identification.restart_check``) looks elsewhere. Running such a
    search on bought nothing on a real MR damper (docs/identification.md, "The global stage on real data"): at
    three currents the whole budget, seeded or random, then the same refinements and check, ended within one
    standard error of the default in two to five times its time. Once a firefly
    has passed the start, 'data resolution' when the best has moved less than the data resolve over the last
    stop_window iterations, all after that first move (``tuner.identification.polish.resolution_stop``)."""
    if opts.stop_tol is None or st.iteration < opts.stop_start:
        return {}
    rmse = rmse_of_fitness(st.best_fitness)
    if rival_at_floor is not None and rmse > RACE_RATIO * rival_at_floor[1]:
        return {"reason": "clearly the wrong form",
                "text": f"search stopped: {rmse / rival_at_floor[1]:.1f} x the {rival_at_floor[0]} form's RMSE, "
                        f"which is at the residual floor (clearly the wrong form for this damper)"}
    moved = first_improvement(st.history_best)
    if moved is None:
        if st.iteration < opts.stop_window:
            return {}
        return {"reason": "stall",
                "text": f"search stalled: no firefly improved on the start ({rmse:.4g} N) in {st.iteration} "
                        f"iterations (the brightest firefly does not move; the swarm is drawn to it): not a "
                        f"convergence"}
    if st.iteration - moved < opts.stop_window or not small_progress(st.history_best, opts.stop_window):
        return {}
    r = eng.residuals_batch([par.to_params(st.best_x)])[0]
    text = resolution_stop(st.history_best, r, opts.stop_window, "iterations") if r is not None else None
    return {"reason": "data resolution", "text": "search " + text} if text else {}


def first_improvement(history_best: list[float]) -> int | None:
    """The first generation whose best-ever fitness (``history_best``: G = N / SSE [1/N^2] per generation, the
    first population's first) exceeds the first population's (a firefly passed the start), None if none does."""
    return next((k for k, g in enumerate(history_best) if g > history_best[0]), None)


def _expect_search(log, model: str, st: firefly.FireflyState, opts: firefly.FireflyOptions, population: int, d: int,
                   recent) -> None:
    """Tell the progress ``log`` the seconds the Firefly search of ``model`` (``d`` coordinates) takes to its likely
    stop (``search_iterations_left``) and the first two refinements after it (TYPICAL_JACOBIANS Jacobians of d + 1
    simulations each), the other restarts and the restart check's (TYPICAL_RESTARTS) said beside, at the evaluation
    rate over ``recent`` ((time [s], evaluations) of the last RATE_WINDOW iterations)."""
    (t0, n0), (t1, n1) = recent[0], recent[-1]
    rate = (n1 - n0) / (t1 - t0) if t1 > t0 else 0.0  # [evaluations/s]
    if rate <= 0:
        return
    likely = search_iterations_left(st.history_best, st.iteration, opts) * population / rate
    one = TYPICAL_JACOBIANS * (d + 1) / rate  # [s] one refinement
    starts = min(2, refinement_starts(model))
    restarts = max(0, refinement_starts(model) - 2) + TYPICAL_RESTARTS  # and the restart check's
    expect(log, likely + starts * one, (restarts * one, "the refinement is restarted"))


def search_iterations_left(history_best: list[float], iteration: int, opts: firefly.FireflyOptions) -> int:
    """Iterations the Firefly search likely still runs after ``iteration``: to its earliest stop at the data's
    resolution should its best (``history_best``: G = N / SSE [1/N^2] per iteration, the first population's
    first) move no more (``small_progress``: not before ``opts.stop_start``, nor before ``opts.stop_window``
    iterations after the first one within FTOL of the best now), never beyond ``opts.max_iterations``; all of
    them without the stop rule. The progress display's forecast: counting the whole budget, the bundled job said
    "about 8.3 min left" 13 s after its start and ended 1.6 min later (the search stopped after 20 of 150)."""
    if opts.stop_tol is None:
        return max(0, opts.max_iterations - iteration)
    best = history_best[-1]
    first = next((i for i, g in enumerate(history_best) if g > 0 and best / g - 1.0 < FTOL), iteration)
    stop = max(opts.stop_start, first + opts.stop_window, iteration)
    return max(0, min(opts.max_iterations, stop) - iteration)


def fit_order(models, problem: Problem, engine: str) -> list[str]:
    """The order ``models`` are fitted in: as given, except that the base forms among them (``EFFECT_MODELS``) are
    fitted best data-driven start first (one simulation of each form's ``initial_guess``, identification SSE),
    so that the race (``RACE_RATIO``) can spare the clearly wrong form its restarts whichever it is: on the
    bundled twin-tube data the lumped form's start leaves 683 N, the two-chamber form's 23 N, and fitted
    first the lumped form had no rival and took four restarts (5 s) to end at 384 N against the other's 19 N."""
    bases = [m for m in models if m in EFFECT_MODELS]
    if len(bases) < 2:
        return list(models)
    sse = {}
    for kind in bases:
        guess = {**defaults(kind), **initial_guess(kind, problem.sig_id, problem.parametrization(kind))}
        with Engine(kind, problem.sig_id, engine=engine, workers=0) as eng:
            sse[kind] = float(eng.sse_batch([guess])[0])
    ranked = iter(sorted(bases, key=lambda k: sse[k]))
    return [next(ranked) if m in EFFECT_MODELS else m for m in models]



def _resumed_state(ckpt: Path, key: str, model: str, log):
    """The Firefly state of an interrupted search on the same settings and data (None without a checkpoint;
    ValueError for one written with others)."""
    if not ckpt.exists():
        return None
    saved = strict_json.loads(ckpt.read_text())
    if saved.get("key") != key:
        raise ValueError(f"{ckpt} was written with other settings or data; start a new output folder")
    state = firefly.FireflyState.from_dict(saved["state"])
    log(f"[{model}] resuming from iteration {state.iteration} ({state.evaluations} evaluations)")
    return state


@dataclass
class Refinement:
    """The local refinements after the Firefly search: the best point (scaled ``z``, fitness ``g`` = N / SSE
    [1/N^2]), the evaluations they took, the winning refinement (``polished``, a ``PolishResult``), every run,
    the restarts skipped as a clearly wrong form (``race``, or None) and those skipped at the residual floor
    (``floor_stop``, or None)."""

    z: np.ndarray
    g: float
    evaluations: int
    polished: PolishResult
    runs: list
    race: dict | None
    elapsed_s: float = 0.0  # wall time of the refinements [s]
    floor_stop: dict | None = None
    check: RestartCheck | None = None  # the restart check (None: not run, at the floor or a clearly wrong form)

    @property
    def converged(self) -> bool:
        """Whether the fit is converged (``converged_by`` says by what)."""
        return self.converged_by is not None

    @property
    def converged_by(self) -> str | None:
        """What shows the fit converged: the winning refinement's rule ('first-order', 'data resolution',
        'stationary') with no restart of the check ending lower by one standard error, or, for a refinement that
        stalled (its steps achieve less than they predict), the restart check alone ('restart check': every restart
        ends in the same place, within one standard error) or the residual floor ('residual floor': it ends within
        FLOOR_REACHED x the noise, where no start can end lower by more than the noise); None when not converged (a
        spent budget, a restart check whose last round still found a lower point, a stall of the wrong form)."""
        if self.check is not None and not self.check.survived:
            return None
        if self.polished.converged:
            return self.polished.rule
        if self.polished.rule != "stalled":
            return None
        if self.check is not None:
            return "restart check"
        return "residual floor" if self.floor_stop is not None else None


def _refine(eng, model: str, par: Parametrization, settings: FitSettings, result, guess_p: dict, log,
            options: IdentifyOptions) -> Refinement:
    """The local refinements from the Firefly best and the restarts (the data-driven start ``guess_p`` and its
    ``RESTART_LADDER`` variants): the Firefly population often collapses into one basin, on random dampers
    sometimes a degenerate one (silent blocks as pure dashpots, 2.2x the floor) that the data-driven start
    avoids; the best refinement wins (benchmarks/convergence.py); a restart stops once it cannot end below the
    best so far (``polish``'s ``beat``). A form ``RACE_RATIO`` x worse than its
    ``options.rival`` after the first gets no restart, nor one whose first refinement reaches the residual
    ``options.floor`` (``_at_floor``). The progress ``log`` is told the seconds the refinements still to run will
    take, at the measured time of those done."""
    rival, floor, guess = options.rival, options.floor, par.from_params(guess_p)
    g_best = float(eng.fitness_batch([par.to_params(result.x_best)])[0])  # on every sample (the search: its windows)
    none = PolishResult(result.x_best, g_best, 0, stop="no local refinement (--polish 0)",
                        converged=False, rule="not started", jacobians=0, predicted=1.0, budget_spent=False)
    ref = Refinement(result.x_best, g_best, 1, none, [], None)
    if settings.polish_jacobians <= 0:
        return ref
    section(log, "local refinements")
    t0 = time.perf_counter()
    starts = [("Firefly best", result.x_best)]
    if not np.allclose(guess, result.x_best):
        starts.append(("data-driven start", guess))
    for name in RESTART_LADDER.get(model, ()):
        lo, hi = par.bounds[name]
        for factor in (10.0, 0.1):
            value = min(max(guess_p[name] * factor, lo), hi)
            starts.append((f"data-driven start with {name} = {value:.3g}", par.from_params({**guess_p, name: value})))
    for k, (label, z0) in enumerate(starts):
        if ref.runs and rival and ref.runs[0]["rmse_n"] > RACE_RATIO * rival[1]:
            ref.race = {"rival": rival[0], "rival_rmse_n": rival[1], "ratio": ref.runs[0]["rmse_n"] / rival[1],
                        "skipped": [lab for lab, _ in starts[1:]]}
            log(f"[{model}] no restart: {ref.race['ratio']:.1f} x the {rival[0]} form's RMSE, "
                f"clearly the wrong form for this damper")
            break
        if k == 1 and floor is not None and _at_floor(ref, model, par, floor, [lab for lab, _ in starts[1:]], log):
            break
        if k:  # the refinements still to run (none skipped by the race), at the measured time of those done
            expect(log, (len(starts) - k) * (time.perf_counter() - t0) / k)
        log(f"[{model}] local refinement from the {label} (projected Levenberg-Marquardt until converged, "
            f"at most {settings.polish_jacobians} Jacobians of {par.dimension} parallel simulations)")
        beat = eng.n_samples / ref.g if ref.runs and ref.g > 0.0 else None  # a restart matters only below the best
        pol = polish(eng, par, z0, max_jacobians=settings.polish_jacobians, log=log, beat=beat)
        ref.evaluations += pol.evaluations
        g = pol.fitness
        ref.runs.append({"start": label, "rmse_n": rmse_of_fitness(g),
                         "converged": pol.converged, "rule": pol.rule, "jacobians": pol.jacobians, "stop": pol.stop})
        log(f"[{model}] local refinement from the {label}: RMSE {ref.runs[-1]['rmse_n']:.2f} N, {pol.stop}")
        if len(ref.runs) == 1 or g > ref.g:  # polish never returns a point worse than its start
            ref.z, ref.g, ref.polished = pol.z, g, pol
    if ref.g > 0.0 and ref.race is None and ref.floor_stop is None and not (  # (g = 0: nothing could be simulated)
            floor is not None and _at_floor(ref, model, par, floor, ["the restart check"], log)):
        _check_restarts(eng, model, par, settings, ref, result.state, log, series_hold(model, par, guess_p, eng.tests))
    ref.elapsed_s = time.perf_counter() - t0
    return ref


def series_hold(model: str, par: Parametrization, guess_p: dict, signals: list[Signals]) -> SeriesHold | None:
    """The values [N/m] the restart check holds ``model``'s series stiffness at when it ended on a bound: the first
    two of ``series_decades`` of the data-driven guess ``guess_p``, none softer than ``SOFTEST_SERIES`` x the
    identification ``signals``' peak force / stroke range; None for a model without a series element (or one the
    parametrization holds fixed)."""
    names = SERIES_ELEMENT.get(model)
    if names is None or names[0] not in par.names:
        return None
    peak = max(float(np.abs(s.force[s.mask]).max()) for s in signals)
    stroke = max(float(np.ptp(s.stroke[s.mask])) for s in signals)
    values = series_decades(par.bounds[names[0]], guess_p[names[0]], SOFTEST_SERIES * peak / max(stroke, 1e-12))
    return SeriesHold(names[0], tuple(values[:2]))


def _check_restarts(eng, model: str, par: Parametrization, settings: FitSettings, ref: Refinement,
                    state: firefly.FireflyState, log, series: SeriesHold | None = None) -> None:
    """The restart check (``tuner.identification.restart_check``) of the best refinement in ``ref``, from the
    Firefly's last generation (``state``), the series element held at ``series``'s values when it ended on a bound;
    a lower point it finds becomes ``ref``'s, and ``ref.check`` records it."""
    section(log, "restart check")
    log(f"[{model}] restart check: is {rmse_of_fitness(ref.g):.2f} N the fit's minimum or its basin's? (restarts "
        f"from the bounds' mid-ranges and the brightest firefly elsewhere; a restart that ends lower by more than one "
        f"standard error of the RMSE continues the fit)")
    population = state.population[np.argsort(-state.fitness)]
    check = restart_check(eng, par, ref.z, ref.g, population, settings.polish_jacobians, log, series)
    ref.evaluations += check.evaluations
    ref.check = check
    if check.polished is not None:
        ref.z, ref.g, ref.polished = check.z, check.g, check.polished
    rmse = rmse_of_fitness(ref.g)
    moved = f"a restart ended lower, at {rmse:.2f} N; " if check.polished is not None else ""
    log(f"[{model}] restart check: {moved}" + (
        f"{rmse:.2f} N stands: no restart ended more than one standard error ({check.standard_error_n:.2g} "
        f"N) lower" if check.survived else
        f"the last of its {ROUNDS} rounds still ended lower: NOT converged"))


def _at_floor(ref: Refinement, model: str, par: Parametrization, floor: ResidualFloor, skipped: list, log) -> bool:
    """Whether the best refinement of ``ref`` so far ends at the residual ``floor`` of the model at its point
    (``ResidualFloor.reached``: within ``FLOOR_REACHED`` x); if so the restarts (or the restart check)
    ``skipped`` (their labels) are recorded in ``ref.floor_stop`` and the ``log`` says why."""
    rmse = rmse_of_fitness(ref.g)
    level = floor.reached(model, par.to_params(ref.z), rmse)
    if level is None:
        return False
    ref.floor_stop = {"rmse_n": rmse, "residual_floor_n": level, "skipped": skipped}
    log(f"[{model}] no restart: the refinement ends at {rmse:.2f} N, {rmse / level:.2f} x the residual floor "
        f"({level:.2f} N: force noise and the stroke noise through the model); no start can end more than the noise "
        f"below it")
    return True


def _history(result, ref: Refinement, par: Parametrization, first_population: dict, search_stop: dict,
             elapsed: float) -> dict:
    """The history record of one model's identification (``history_<model>.json``)."""
    st = result.state
    return {
        "mean_fitness": list(map(float, st.history_mean)),
        "best_fitness": list(map(float, st.history_best)),
        "generation_best_fitness": list(map(float, st.history_generation_best)),
        "evaluations": list(map(int, st.history_evaluations)),
        "initial_population": [par.to_params(z) for z in first_population.get("pop", st.population)],
        "final_population": [par.to_params(z) for z in st.population],
        "stop_reason": search_stop.get("reason", result.stop_reason),
        "search_stop": search_stop.get("text"),
        "iterations": int(result.iterations),
        "firefly_evaluations": int(result.evaluations),
        "firefly_best_fitness": float(result.fitness_best),
        "polish_fitness": list(map(float, ref.polished.history)),
        "polish_stop": ref.polished.stop,
        "polish_rule": ref.polished.rule,  # tuner.identification.polish: what ended it
        "polish_jacobians": int(ref.polished.jacobians),
        "local_refinements": ref.runs,
        "race": ref.race,  # None, or the restarts skipped as a clearly wrong form (RACE_RATIO)
        "floor_stop": ref.floor_stop,  # None, or the restarts skipped at the residual floor (FLOOR_REACHED)
        "converged": ref.converged,
        "converged_by": ref.converged_by,  # the rule that shows it (Refinement.converged_by), None when not
        "restart_check": ref.check.to_dict() if ref.check is not None else None,
        "polish_evaluations": int(ref.evaluations),
        "polish_elapsed_s": ref.elapsed_s,  # with polish_evaluations: the cost of a full simulation near the fit
        "evaluation_count": int(result.evaluations + ref.evaluations),
        "best_fitness_final": float(ref.g),
        "elapsed_s": elapsed,
        "parametrization": par.describe(),
    }


def full_rate_checks(tests: list[RigTest], params: dict, settings: FitSettings, log=print) -> dict:
    """``tuner.identification.full_rate.full_rate_check`` of every model on every test recorded fast enough:
    {model: {"tests": {test: result}, "holds": bool or None (no test applies), "text": one line}}.
    Logs the line."""
    rows = {m: {} for m in settings.models}
    for t in tests:
        rate = comparison_rate(t.sample_rate, settings.data.fit_rate_hz)
        if rate is None:
            continue
        # the velocity accurate over the compared band (stroke_band_hz at the comparison rate)
        s = prepared_signals([t], settings.data, rate)[1][0]
        sigma = noise_std(t.force, t.sample_rate)
        for model in settings.models:
            rows[model][t.name] = full_rate_check(model, params[model]["values"], s, settings.data.fit_rate_hz,
                                                  t.sample_rate, sigma)
    out = {}
    for model, r in rows.items():
        if not r:
            out[model] = {"tests": {}, "holds": None, "text": (
                f"full-rate check: not applicable (no test recorded at {MIN_RATE_RATIO:g} x the fit rate or faster)")}
        else:
            holds = all(x["holds"] for x in r.values())
            name, w = max(r.items(), key=lambda kv: kv[1]["rmse_increase_n"] - kv[1]["noise_in_fit_band_n"])
            out[model] = {"tests": r, "holds": holds, "text": (
                "full-rate check: " + ("the fit holds at the files' own rate" if holds else
                                       "the fit does NOT hold at the files' own rate (fit at a higher --fit-rate)")
                + f"; worst {name}: {w['fit_band_hz']:g}-{w['upper_hz']:.0f} Hz hides {w['hidden_n']:.3g} N rms "
                  f"beyond the noise, adding {w['rmse_increase_n']:.2g} N to the RMSE (noise in the fit band "
                  f"{w['noise_in_fit_band_n']:.3g} N)")}
        log(f"[{model}] {out[model]['text']}")
    return out


def quality_gate(tests: dict, models) -> dict:
    """Per model: does it describe the data? The worst AME [% of that test's peak force] over the
    validation tests (the identification tests when there is none) against ``QUALITY_AME_PCT``.
    ``tests``: the per-test metrics of :func:`fit` (name -> {"role", "models": {model: metrics}})."""
    out = {}
    for model in models:
        rows = [(n, t["models"][model]) for n, t in tests.items() if t["role"] == "validation"] or \
               [(n, t["models"][model]) for n, t in tests.items()]
        worst_name, worst = max(((n, 100 * m["ame"] / m["peak_measured"]) for n, m in rows), key=lambda r: r[1])
        ok = worst <= QUALITY_AME_PCT
        kind = "held-out" if any(t["role"] == "validation" for t in tests.values()) else "identification (no held-out test)"
        text = (f"worst {kind} AME {worst:.3g} % of peak force ({worst_name}): "
                + (f"the model describes this data (gate {QUALITY_AME_PCT:g} %)" if ok else
                   f"the model does NOT describe this data (gate {QUALITY_AME_PCT:g} %): its parameters are "
                   f"not a characterisation of this damper"))
        out[model] = {"worst_ame_pct_of_peak": worst, "worst_test": worst_name, "gate_pct": QUALITY_AME_PCT,
                      "describes_data": ok, "text": text}
    return out


@dataclass
class FitResult:
    """What :func:`fit` found, in memory (SI units). ``write(out)`` stores it as the output folder's
    data files (module docstring); ``tuner.job`` adds the FMUs, the diagnosis and the report.

    params: {model: {"values", "units", "bounds", "parametrization", "intervals" (and "intervals_note" when
    they are None)}}; histories: {model: Firefly and
    refinement history}; metrics: {"settings", "tests": {name: {role, scenario, models: {model:
    metrics}}}, "table3", "quality"} (``full_rate`` added by the job); simulations: name -> array of
    simulations.npz (``<test>__time`` [s], ``__stroke`` [m], ``__force`` [N], ``__<model>`` [N]);
    problem: the prepared tests it was fitted on."""

    params: dict
    histories: dict
    metrics: dict
    simulations: dict
    problem: Problem

    def identification_rmse_n(self, model: str) -> float:
        """Identification RMSE [N] of ``model`` in the fit band."""
        return self.histories[model]["identification_rmse_n"]

    def write(self, out: Path) -> None:
        """parameters.json, history_<model>.json, simulations.npz and metrics.json into ``out``."""
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        for model, hist in self.histories.items():
            (out / f"history_{model}.json").write_text(strict_json.dumps(hist, indent=1))
        (out / "parameters.json").write_text(strict_json.dumps(self.params, indent=2, sort_keys=True))
        np.savez_compressed(out / "simulations.npz", **self.simulations)
        self.write_metrics(out)

    def write_metrics(self, out: Path) -> None:
        """metrics.json into ``out`` (again after a later stage added to ``metrics``)."""
        (Path(out) / "metrics.json").write_text(strict_json.dumps(self.metrics, indent=2, sort_keys=True))


def model_intervals(eng: Engine, model: str, signals: list[Signals], par: Parametrization, best: dict, log) -> dict:
    """{"intervals": the ``tuner.identification.intervals.ModelIntervals`` of the fitted model as a dict}, or
    {"intervals": None, "intervals_note": why} when the fitted model cannot be simulated around its point
    (the fit itself is kept); through ``eng``, the identification engine of ``model`` on ``signals``. Logs the
    one-line summary."""
    try:
        iv = parameter_intervals(eng, par, best, reached=reached_ranges(model, best, signals))
    except (SimulationError, ConvergenceError, ValueError) as err:
        log(f"[{model}] parameter intervals not computed: {err}")
        return {"intervals": None, "intervals_note": f"not computed: {err}"}
    log(f"[{model}] {iv.summary_text()}")
    return {"intervals": iv.to_dict()}


def fit(identification: list[RigTest], validation: list[RigTest], settings: FitSettings, *,
        checkpoints: Path | None = None, provenance: dict | None = None, problem: Problem | None = None,
        log=print) -> FitResult:
    """Identify every model in ``settings.models`` and validate it through the FMU the user gets.

    Returns a :class:`FitResult` and writes nothing but the Firefly checkpoints: into
    ``checkpoints`` (a folder; resumed when they are there), none when it is None. ``problem``: the
    tests already prepared (``Problem.build(identification, validation, settings.data)``), so
    that a diagnosis after the fit works on the same problem; built here when not given.
    """
    if not identification:
        raise ValueError("no identification test given")
    if problem is None:
        problem = Problem.build(identification, validation, settings.data)
    elif problem.settings != settings.data:
        raise ValueError(f"fit: the problem was built with {problem.settings}, the fit settings ask for "
                         f"{settings.data}")
    scratch = None
    if checkpoints is None:
        scratch = tempfile.TemporaryDirectory(prefix="tuner-fit-")
        checkpoints = Path(scratch.name)
    checkpoints = Path(checkpoints)
    checkpoints.mkdir(parents=True, exist_ok=True)
    prep_id, axes, force_limit = problem.prep_id, problem.axes, problem.force_limit_n
    floor = problem.residual_floor(settings.engine)
    _log_problem(problem, log)
    params, histories = {}, {}
    try:
        for model in fit_order(settings.models, problem, settings.engine):
            stage(log, f"fit {model}")
            one = _fit_model(model, problem, settings, checkpoints, histories, floor, log)
            params[model], histories[model] = one.params, one.history
    finally:
        if scratch is not None:
            scratch.cleanup()
    params, histories = ({m: d[m] for m in settings.models if m in d} for d in (params, histories))

    # every result is checked through the FMU the user gets, whatever engine identified it
    stage(log, "validate and export")
    log(f"validating through the FMU (forces compared in the {settings.data.fit_rate_hz / 2:g} Hz fit band) ...")
    checked = validated_metrics(problem, params, settings.models)
    for model, q in checked.quality.items():
        log(f"[{model}] {q['text']}")
    settings_out = settings.to_dict()
    settings_out.update({
        "force_limit_n_used": force_limit,
        "table_abscissae": axes,
        "preprocessing": [p.describe() for p in prep_id],
        "evaluations": {m: histories[m]["evaluation_count"] for m in settings.models},
        "elapsed_s": {m: histories[m]["elapsed_s"] for m in settings.models},
        "stop_reason": {m: histories[m]["stop_reason"] for m in settings.models},
        "parametrization_text": {m: histories[m]["parametrization"] for m in settings.models},
        "fit_internal_step_s": settings.data.sim_step_s,
        "identification_tests": [t.name for t in identification],
        "validation_tests": [t.name for t in validation],
        **(provenance or {}),
    })
    metrics = {"settings": settings_out, "tests": checked.tests, "table3": checked.table3, "quality": checked.quality}
    return FitResult(params=params, histories=histories, metrics=metrics, simulations=checked.arrays, problem=problem)


@dataclass(frozen=True)
class Validated:
    """Every model checked through the FMU on every test (``validated_metrics``): ``tests`` (metrics.json's
    "tests"), ``arrays`` (simulations.npz), ``table3`` (the paper's Table 3 when lumped and Maxwell were fitted,
    else {}) and ``quality`` (``quality_gate``)."""

    tests: dict
    arrays: dict
    table3: dict
    quality: dict


def validated_metrics(problem: Problem, params: dict, models) -> Validated:
    """Every one of ``models`` at its values in ``params`` simulated through the FMU on every test of
    ``problem`` (``validation_run``) and its figures: the one place ``fit`` and a continued fit
    (``tuner.identification.best_point``) take them."""
    tests_out, arrays = _validated(problem.identification, problem.validation, problem, params, models)
    table3 = _table3(tests_out, problem.validation) if "lumped" in models and "maxwell" in models else {}
    return Validated(tests_out, arrays, table3, quality_gate(tests_out, models))


def revalidate(result: FitResult) -> None:
    """``result``'s validation figures (metrics' tests, Table 3, quality gate; the simulations) taken again at its
    current values, after a model's values changed (``tuner.identification.best_point.continue_fit``)."""
    checked = validated_metrics(result.problem, result.params, list(result.params))
    result.metrics.update({"tests": checked.tests, "table3": checked.table3, "quality": checked.quality})
    result.simulations = checked.arrays


@dataclass(frozen=True)
class ModelFit:
    """One model's identification in ``fit``: its ``FitResult.params`` entry (values [SI], units, bounds,
    parametrization, intervals) and its ``FitResult.histories`` entry."""

    params: dict
    history: dict


def _fit_model(model: str, problem: Problem, settings: FitSettings, checkpoints: Path, histories: dict,
               floor: ResidualFloor, log) -> ModelFit:
    """The ``ModelFit`` of ``model`` identified on ``problem``, raced against the best
    base form among those already fitted (``histories``); the identification RMSE [N] logged beside the
    measurement noise in the fit band, what a fit of a model that can represent the data reaches."""
    par, noise = problem.parametrization(model), problem.noise_n
    fitted_bases = [(m, histories[m]["identification_rmse_n"]) for m in histories if m in EFFECT_MODELS]
    rival = min(fitted_bases, key=lambda r: r[1]) if model in EFFECT_MODELS and fitted_bases else None
    found = identify(model, problem.sig_id, settings, par, checkpoints / f"{model}.json", problem.digest, log,
                     options=IdentifyOptions(rival=rival, intervals=True, floor=floor,
                                             rival_at_floor=rival is not None
                                             and histories[rival[0]]["floor_stop"] is not None))
    hist = found.history
    entry = {"values": found.values, "units": dict(par.units), "bounds": {n: list(par.bounds[n]) for n in par.names},
             "parametrization": settings.data.parametrization, **found.intervals}
    rmse_id = 1.0 / math.sqrt(hist["best_fitness_final"]) if hist["best_fitness_final"] > 0 else math.inf
    hist["noise_floor_n"] = noise
    hist["noise_credible"] = bool(problem.noise.get("credible", True))
    hist["identification_rmse_n"] = rmse_id
    against = (f"= {rmse_id / noise:.1f} x the measurement noise in the fit band ({noise:.1f} N)"
               if hist["noise_credible"] else f"({problem.noise.get('text')})")
    log(f"[{model}] identification RMSE {rmse_id:.1f} N {against}; local refinement "
        + (f"converged ({hist['converged_by']})" if hist["converged"] else "NOT converged"))
    return ModelFit(entry, hist)


def _log_problem(problem: Problem, log) -> None:
    """What the fit works on: tests, samples, rate, peak force and the tables' abscissae."""
    signals, axes = problem.sig_id, problem.axes
    log(f"identification: {len(signals)} tests, {sum(int(s.mask.sum()) for s in signals)} samples at "
        f"{problem.settings.fit_rate_hz:g} Hz; peak force {problem.peak_n:.0f} N -> Fc,O limit "
        f"{problem.force_limit_n:.3g} N")
    log(problem.scale.describe())
    log(f"table abscissae: Fc,O rates up to {1e3 * axes['Fc_v14']:.4g} mm/s, Fk,O elongations up to "
        f"{1e3 * axes['Fk_x10']:.4g} mm (identification data: peak stroke velocity "
        f"{1e3 * max(float(np.max(np.abs(s.stroke_velocity[s.mask]))) for s in signals):.4g} mm/s)")


def _validated(identification: list[RigTest], validation: list[RigTest], problem: Problem, params: dict,
               models) -> tuple[dict, dict]:
    """({test: role, scenario, per-model metrics (``validation_run``: through the FMU), rates, damper class},
    the arrays of ``simulations.npz``: each test's time [s], stroke [m], force [N] and every model's force)."""
    tests_out, arrays = {}, {}
    for t, p, s in zip([*identification, *validation], [*problem.prep_id, *problem.prep_val],
                       [*problem.sig_id, *problem.sig_val]):
        arrays[f"{t.name}__time"], arrays[f"{t.name}__stroke"] = p.time, p.stroke
        arrays[f"{t.name}__force"] = p.force
        models_m = {}
        for model in models:
            arrays[f"{t.name}__{model}"], models_m[model] = validation_run(model, params[model]["values"], s)
        tests_out[t.name] = {"role": t.role, "scenario": t.scenario, "models": models_m,
                             "sample_rate_hz": p.sample_rate, "source_rate_hz": t.sample_rate,
                             # the damper class the data was read as (None: not read from a file): the
                             # report's railway wording depends on it
                             "damper_class": (t.metadata.get("read") or {}).get("damper_class")}
    return tests_out, arrays


def _table3(tests_out: dict, validation: list[RigTest]) -> dict:
    """The paper's Table 3 per validation test: MSE [N^2] and AME [N] of Maxwell and lumped, their variation
    [%], and the lumped AME as a share of the peak measured force [%]."""
    table3 = {}
    for t in validation:
        m = tests_out[t.name]["models"]
        mx, lp = m["maxwell"], m["lumped"]
        table3[t.name] = {"mse_maxwell": mx["mse"], "mse_lumped": lp["mse"],
                          "mse_variation_pct": 100 * (lp["mse"] - mx["mse"]) / mx["mse"],
                          "ame_maxwell": mx["ame"], "ame_lumped": lp["ame"],
                          "ame_variation_pct": 100 * (lp["ame"] - mx["ame"]) / mx["ame"],
                          "ame_lumped_pct_of_peak": 100 * lp["ame"] / lp["peak_measured"]}
    return table3
