"""The record the steps of a diagnosis on one base form share (``SearchState``), a refitted model (``Fit``), and
the services every step uses: the stage and the progress display's time left, the residual floor's judgments
(``above_floor``, ``floor_of``), whether a refit settled and a quiet polish. SI units; forces in N."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from damper_fmu.effect_catalogue import EFFECT_PARAMETERS
from damper_fmu.parameters import defaults

from tuner.diagnosis.bases import Base, CoarserGrid
from tuner.diagnosis.cost_model import EXTENDED_COST, DiagnosisCost
from tuner.diagnosis.effect_sizes import DamperSize
from tuner.diagnosis.held_profiles import sweep_gain
from tuner.diagnosis.residual_tests import TestResidual
from tuner.diagnosis.rules import UNEXPLAINED_RATIO
from tuner.diagnosis.settings import DiagnosisSettings
from tuner.identification.engine import Engine
from tuner.identification.fit import initial_guess
from tuner.identification.parametrization import Parametrization
from tuner.identification.polish import PolishResult, polish
from tuner.identification.problem import Problem
from tuner.progress import advance, expect
from tuner.time_budget import section

__all__ = ["PRIOR_EVALUATIONS", "Fit", "SearchState", "base_point"]

#: the fit's cost per simulation counts as this many simulations of the diagnosis's own (``forecast``): the first
#: batches also start the engines' workers (2-5 s), which would otherwise read as a slow model
PRIOR_EVALUATIONS = 200


def base_point(kind: str, values: dict) -> dict:
    """The base model's full parameter point (SI): the preset of ``kind`` with ``values`` (the identified
    base, keys of other models ignored) and every effect element off."""
    point = defaults(kind)
    point.update({k: v for k, v in values.items() if k in point})
    point.update({p.name: p.default for p in EFFECT_PARAMETERS})
    return point


@dataclass
class Fit:
    """One refitted model: its parametrization (the base extended by its effects), scaled coordinates ``z``
    and the evaluations its refit took."""

    ext: object
    z: np.ndarray
    evaluations: int

    def params(self) -> dict:
        return self.ext.to_params(self.z)


@dataclass
class SearchState:
    """What the steps of the diagnosis on one base form share (``tuner.diagnosis.search``): its inputs, the
    engines, the residual floor and evidence, the base refitted alike ('none', the reference of every score), the
    ranking and the refits so far, and the forecast's bookkeeping. Each step is a function of it in a module of
    its own; the fields are set by the step named beside them. ``record`` (as ``tuner.diagnosis.diagnose``)
    follows the stages: 'stage' names the one running, 'partial' holds the live ranking, selection steps, causes
    and forms tried so far. Units SI; forces in N."""

    # the inputs (``start``)
    kind: str
    par: Parametrization
    data: Problem
    settings: DiagnosisSettings
    log: object
    record: dict
    figures_folder: str  # where the job draws the figures, relative to the output folder
    settled_by: str | None  # how the refinement of the base on these tests ended (``Base.settled``)
    coarser: CoarserGrid | None  # what a diagnosis on a coarser grid found (``Base.coarser``)
    found_elsewhere: dict  # {effect: parameters [SI]} the diagnosis on another base form named (``Base.found_elsewhere``)
    rate_prior: float | None  # [s per simulation] the diagnosis's expected, from the fit's
    peak: float  # [N]
    stroke_range: float  # [m]
    noise: float  # [N rms] the force noise
    size: DamperSize  # typical effect sizes scale with it
    stroke_limits: tuple  # [m] the identification tests' stroke range
    base: dict  # the base model's point, every effect off (``base_point``)
    guess: dict  # the data-driven guess, every effect off
    lengths: list  # samples of each held-out test
    # what grows (the steps)
    ranking: list = field(default_factory=list)
    refits: dict = field(default_factory=dict)  # {causes key: Fit}
    #: {causes key: (stroke noise through that model [N rms], its residual floor [N])} (``floor_of``)
    floors: dict = field(default_factory=dict)
    #: {causes key ('' for none): whether its last refit settled (``settled``)}
    converged: dict = field(default_factory=dict)
    cost: DiagnosisCost | None = None  # the steps still to come (``forecast``)
    t_engines: float = field(default_factory=time.perf_counter)  # when the engines opened: the live cost per simulation
    eid: Engine | None = None  # the identification tests' engine (``run``)
    ev: Engine | None = None  # the held-out tests' engine (``run``)
    #: the search's windows of the identification tests (``run``; ``tuner.identification.search_window``; ``eid``
    #: itself when they cut nothing): where the free-play ladder's coarse passes run (``nonsmooth.series_ladder``)
    ew: Engine | None = None
    # the residual floor and evidence (``reference.residual_floor``, ``reference.residual_evidence``)
    stroke_noise_n: float = math.nan  # [N rms] the stroke channel's noise through the base model
    floor: float = math.nan  # [N] the residual floor
    credible: bool = True  # whether the noise estimate may judge the residual
    not_credible: str | None = None  # why not
    residuals: list[TestResidual] = field(default_factory=list)
    evidence: dict = field(default_factory=dict)
    figures: list = field(default_factory=list)
    # the base refitted alike (``reference.refit_none``, ``reference.set_none``)
    z_none: np.ndarray | None = None
    g_none: float = math.nan  # its identification fitness N / SSE
    mse_none: float = math.nan  # [N^2] its held-out MSE
    mse_base: float = math.nan  # [N^2] the fitted base's held-out MSE
    none_row: dict | None = None  # its ranking row
    jac_base: object = None  # the fitted base's residual Jacobian SVD
    starts: list = field(default_factory=list)  # the refits' starts: (point, SSE [N^2], Jacobian SVD or None)
    share: int = 1  # the Jacobian budget of a start
    one_start: bool = False  # a settled base: one start for every refit
    z_settled: np.ndarray | None = None  # the base refit's point when it settled
    resolvable_n: float = 0.0  # one standard error of the base's identification RMSE [N]
    fit_base_rmse_n: float = math.nan  # the fitted base's identification RMSE [N]

    @classmethod
    def start(cls, kind: str, base: Base, data: Problem, settings: DiagnosisSettings, figures: str, log,
              record: dict | None = None) -> "SearchState":
        """The state before the first step: the diagnosis of ``base`` (form ``kind``) on ``data``, its figures
        named in the folder ``figures``."""
        rate = base.refinement.seconds_per_evaluation  # [s per simulation], the fit's
        record = record if record is not None else {}
        record.setdefault("partial", {})
        guess = {**defaults(kind), **initial_guess(kind, data.sig_id, base.par)}
        for p in EFFECT_PARAMETERS:
            guess[p.name] = p.default
        return cls(kind=kind, par=base.par, data=data, settings=settings, log=log, record=record,
                   figures_folder=figures, settled_by=base.refinement.settled, coarser=base.coarser,
                   found_elsewhere=dict(base.found_elsewhere),
                   rate_prior=None if rate is None else rate * EXTENDED_COST,
                   peak=data.peak_n, stroke_range=data.stroke_range_m, noise=data.noise_n,
                   size=DamperSize(data.peak_n, data.stroke_range_m),
                   stroke_limits=(min(float(s.stroke[s.mask].min()) for s in data.sig_id),
                                  max(float(s.stroke[s.mask].max()) for s in data.sig_id)),
                   base=base_point(kind, base.values), guess=guess,
                   lengths=[int(s.mask.sum()) for s in data.sig_val])

    # -- the progress display --------------------------------------------------------------------------------
    def forecast(self) -> None:
        """The seconds this diagnosis still expects (``tuner.diagnosis.cost_model``: the simulations of the steps
        to come, at the wall time per simulation measured so far, or the fit's before any) to the progress
        display."""
        if self.cost is None:
            return
        share = sum(self.lengths) / self.eid.n_samples
        evaluations = self.eid.evaluations + share * self.ev.evaluations
        if self.ew is not None and self.ew is not self.eid:  # the windows' simulations, as shares of the tests'
            evaluations += self.ew.n_samples / self.eid.n_samples * self.ew.evaluations
        spent = time.perf_counter() - self.t_engines
        if self.rate_prior is not None:  # the fit's, worth PRIOR_EVALUATIONS (the first batch starts the workers)
            evaluations, spent = evaluations + PRIOR_EVALUATIONS, spent + PRIOR_EVALUATIONS * self.rate_prior
        if evaluations > 0:
            expect(self.log, self.cost.total * spent / evaluations)

    def step_done(self, step: str) -> None:
        """Step ``step`` of the cost model (a ``DiagnosisCost`` field) is finished: the time left said again."""
        self.cost.done(step)
        self.forecast()

    def tick(self) -> None:
        """After every batch of simulations: the progress display may say the time left again (counting down
        from the last forecast), so a long step (a ladder, a refit) is not a silence."""
        advance(self.log, 0.0)

    def at(self, stage: str, fraction: float | None = None) -> None:
        """Stage ``stage`` runs (``record['stage']``); the progress display at ``fraction`` of the diagnosis."""
        self.record["stage"] = f"{stage} on the {self.kind} base"
        section(self.log, f"{self.kind} base: {stage}")
        if fraction is not None:
            advance(self.log, fraction)

    # -- the residual floor's judgments ---------------------------------------------------------------------
    def above_floor(self, rmse: float, floor: float | None = None) -> bool:
        """An identification RMSE [N] above UNEXPLAINED_RATIO x a credible floor (``floor`` [N], the base's when
        None): a structured residual."""
        return self.credible and rmse > UNEXPLAINED_RATIO * (self.floor if floor is None else floor)

    def floor_of(self, causes: list[str]) -> tuple[float, float]:
        """(stroke noise through the model [N rms], its residual floor [N]) of the base with ``causes``: each model
        is judged against what the stroke channel's noise makes through it. A free play's contact is a stiffer
        path from the stroke to the force than the soft table the base absorbed the gap into (a 0.057 mm gap
        between 9e7 N/m silent blocks: 297 N rms through the true model, 16 N through the base); its residual
        left at that level is measurement noise, not a model-form error."""
        if not causes:
            return self.stroke_noise_n, self.floor
        key = "+".join(causes)
        if key not in self.floors:
            sn = self.data.residual_floor(self.settings.engine).stroke_noise_n(self.kind, self.refits[key].params())
            self.floors[key] = (sn, math.hypot(self.noise, sn))
            if abs(sn - self.stroke_noise_n) > 0.1 * self.floor:
                self.log(f"diagnosis: stroke noise through the model with {key} {sn:.1f} N rms (the base's "
                         f"{self.stroke_noise_n:.1f} N); its residual floor {self.floors[key][1]:.1f} N")
        return self.floors[key]

    # -- refits ------------------------------------------------------------------------------------------------
    def settled(self, pol: PolishResult, g: float) -> bool:
        """A refit settled: it met its first-order test, or stalled (no damped step helps) where the gain its
        Gauss-Newton step still predicts cannot bring it within UNEXPLAINED_RATIO x the floor; a spent
        budget never settles (``pol`` of ``polish``, ``g`` its fitness N / SSE)."""
        reachable = math.sqrt(max(0.0, 1.0 - pol.predicted) / g) if g > 0 else math.inf
        return bool(pol.converged or (self.credible and not pol.budget_spent
                                          and reachable > UNEXPLAINED_RATIO * self.floor))

    @property
    def sweep_gain_n(self) -> float:
        """The fall of the identification RMSE [N] a held profile's swept value must show to count as progress
        (``tuner.diagnosis.held_profiles.sweep_gain`` of ``resolvable_n``)."""
        return sweep_gain(self.resolvable_n)

    def polish_quietly(self, par, z: np.ndarray, jacobians: int, beat: float | None = None) -> PolishResult:
        """``polish`` of ``par`` from ``z`` on the identification tests, at most ``jacobians`` Jacobians, unlogged
        (``beat`` [N^2]: the SSE it matters only below, ``polish``'s)."""
        return polish(self.eid, par, z, max_jacobians=jacobians, log=lambda m: None, beat=beat)
