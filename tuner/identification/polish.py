"""Local refinement after the Firefly search: projected Levenberg-Marquardt until a first-order test holds.

The paper's Firefly algorithm finds a region, not the optimum (with rho = 0.9^(k-1) and a brightest
firefly that never moves it stalls in narrow valleys). The objective is a sum of squares, so a
Gauss-Newton method finishes the job. Why this one (measured on random dampers of the lumped and
two-chamber classes, ``benchmarks/convergence.py``, docs/identification.md, "Convergence over the model's class"):

* scipy's bounded solvers crawl: ``least_squares`` with method 'trf' (which this module used until
  2026-11-24) or 'dogbox' from the same Firefly best took 0.3-2 N per Jacobian and stopped at a
  100-Jacobian cap 2.5-9x above the floor, though the scaled Jacobian is well conditioned near the
  optimum (condition ~70) and accurate (finite differences agree to 1e-3 between steps of 1e-7 and
  1e-4). Their bound handling (Coleman-Li scaling) shrinks the steps; unbounded Levenberg-Marquardt
  from the same start took 10 Jacobians. So: Levenberg-Marquardt with the bounds handled by an
  active set (variables on a bound whose gradient points outward are held) and steps projected
  into the box.
* it works in ``par.local_space()`` (``LocalSpace``: table ordinate increments, linear): the force
  is nearly linear in the ordinates, not in the search's log-slopes; 30 % fewer Jacobians.
* converged means a first-order test: the Gauss-Newton step on the free variables predicts less
  than ``RTOL`` of the sum of squares (for a quadratic model that is the whole remaining gain), or
  no step along the gradient lowers the sum at any damping while that prediction is below
  ``STALL_RTOL`` (stationary to the accuracy of the finite differences). A spent budget is reported
  as not converged.
* converged to the data's resolution (a rule of its own, reported as such): over the last
  ``RESOLUTION_WINDOW`` Jacobians the achieved decrease is below ``FTOL`` of the SSE *and* the RMSE
  moved by less than ``RESOLUTION_FRACTION`` of its own standard error (``tuner.metrics.
  rmse_standard_error``: RMSE / sqrt(2 N_eff), the residual's correlation counted). scipy's ``ftol``
  made statistical: where no model reaches the noise (real rig data) and the objective is rough, the
  Gauss-Newton step keeps predicting ~1 % of the SSE while each Jacobian achieves ~0.1 % of it
  (measured on a real damper: 16.68 -> 16.46 N over 18 Jacobians of 45 s each), so the first-order
  test is never met and only the cap ended it; a change the data cannot show is no progress. But only where
  the Gauss-Newton step, too, predicts less than the data can show (``resolvable_gain``: one standard error of
  the RMSE): a step that predicts 13-41 % of the SSE and achieves 0.3 % is stalled, not converged (the
  two-chamber fit of a real MR damper at 0.25 A ended there at 18.15 N; switched to the coarse differences,
  the same start reaches 14.10 N). A stall switches to the coarse differences; stalled with them, the
  refinement ends as 'stalled' (not converged) and the fit's restart check
  (``tuner.identification.restart_check``) decides.
* finite differences of ``STEP`` first, ``COARSE_STEP`` once no damped step lowers the sum. The
  two-chamber model's force is not smooth on the scale of ``STEP``: its stage equations (air
  stiffness that falls with the chamber force) can switch between roots at a valve opening, so any
  perturbation of a table ordinate by 1e-7 of its range moves the SSE by ~0.5 % and the gradient
  grows as 1/step (measured on a random two-chamber damper, seed 12 of ``benchmarks/convergence.py``,
  at the point where the fine step stalled at 46.6 N: from there the coarse step reached 37.1 N, the
  truth scoring 37.2 N, in 11 Jacobians). A secant over 1e-3 of each range sees through that
  roughness; the fine step is kept where it works (it is more accurate on smooth objectives).
* a refinement that only matters if it ends below an SSE (``beat``: a restart against the fit's point) stops,
  as 'cannot beat' (not converged), when ``BEAT_PATIENCE`` Jacobians running its Gauss-Newton step predicts an
  end above it and that prediction has settled (``cannot_beat``: it moved by less than one standard error of the
  RMSE between them): the step is the local model's whole reachable gain where the model holds. Not while the
  prediction still moves: from a start far off, the linear model promises far less than the valley gives (a
  random lumped damper's data-driven start at 1141 N rms: 639 N predicted after two Jacobians, 8.8 N reached; a
  rule on the prediction alone stopped it there and the fit ended at 2.4 x the truth's RMSE). On the real MR
  currents the restarts of the two-chamber fit's check took 38-61 s of 220-277 s jobs and none ended lower
  (docs/measurements.md).

Each Jacobian is one batch of d simulations (forward differences) through the engine, i.e. in
parallel through the FMU; each damping trial evaluates two damping values at once. The best point
seen is returned; the start is never lost.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from tuner.metrics import rmse_standard_error
from tuner.progress import advance

__all__ = ["polish", "PolishResult", "resolution_stop", "resolvable_gain", "stalled_text", "small_progress",
           "cannot_beat", "BEAT_PATIENCE", "RTOL", "STALL_RTOL", "STEP", "COARSE_STEP", "FTOL", "RESOLUTION_WINDOW",
           "RESOLUTION_FRACTION"]

#: Converged when the Gauss-Newton step predicts less than this share of the SSE.
RTOL = 1e-4
#: ... or when no damped step lowers the SSE and the prediction is below this share (FD accuracy).
STALL_RTOL = 1e-2
#: Converged to the data's resolution when, over the last RESOLUTION_WINDOW Jacobians, the SSE fell by less
#: than FTOL of itself and the RMSE by less than RESOLUTION_FRACTION of its standard error (module docstring)
FTOL = 1e-2
RESOLUTION_WINDOW = 3
RESOLUTION_FRACTION = 0.25
#: Jacobians a refinement typically takes to converge (for the progress display only): 3-7 on the bundled data,
#: median 7-13 on the benchmarks' random dampers (docs/measurements.md)
TYPICAL_JACOBIANS = 10
#: Jacobians running whose Gauss-Newton step predicts an end above ``beat``, settled, before a refinement stops
#: (module docstring, ``cannot_beat``)
BEAT_PATIENCE = 2
#: forward-difference step in the local coordinates (each spans its parameter's bounds)
STEP = 1e-5
#: ... and the step once the fine one stalls (module docstring)
COARSE_STEP = 1e-3


@dataclass(frozen=True)
class PolishResult:
    """What one refinement (``polish``) reached and why it stopped."""

    #: the best point seen, in the search coordinates of the ``par`` refined (each in [0, 1])
    z: np.ndarray
    #: its fitness G = N / SSE [1/N^2] (N: residual samples, SSE [N^2]); 0 when the start cannot be simulated
    fitness: float
    #: simulations run (the start, finite differences and damping trials)
    evaluations: int
    #: why it stopped, for people
    stop: str
    #: whether it met a convergence rule (module docstring)
    converged: bool
    #: what ended it: 'first-order', 'data resolution', 'stationary' (no damped step helps), 'stalled' (the
    #: steps achieve far less than the Gauss-Newton step predicts: not converged), 'cannot beat' (its step
    #: predicted an end above ``beat``, settled, BEAT_PATIENCE times running: not converged), 'budget', 'not started'
    rule: str
    #: Jacobians computed
    jacobians: int
    #: share (0-1) of the SSE the last Gauss-Newton step predicted it would remove (the locally reachable
    #: gain; 1.0 before any Jacobian)
    predicted: float
    #: stopped by ``max_jacobians`` while still improving
    budget_spent: bool
    #: fitness G = N / SSE [1/N^2] at the start and after every accepted step
    history: list = field(default_factory=list)


def polish(engine, par, z0: np.ndarray, *, max_jacobians: int = 60, log=print,
           beat: float | None = None) -> PolishResult:
    """Refine the search-space point z0 of ``par``: a ``PolishResult`` (the best point seen, its fitness
    G = N / SSE [1/N^2], the simulations used, why it stopped).

    engine: tuner.identification.engine.Engine; par: a tuner.identification.parametrization.Parametrization
    (or the diagnosis' extension of one), refined in the coordinates of its ``local_space()``; beat: an SSE
    [N^2] the refinement matters only below (None: none; module docstring)."""
    space = par.local_space()
    n = engine.n_samples
    used = {"evals": 0}

    def residuals(points):
        used["evals"] += len(points)
        return engine.residuals_batch([space.to_params(p) for p in points])

    u = space.from_params(par.to_params(z0))
    r = residuals([u])[0]
    if r is None:
        return PolishResult(np.asarray(z0, float), 0.0, used["evals"], stop="start point cannot be simulated",
                            converged=False, rule="not started", jacobians=0, predicted=1.0, budget_spent=False)
    cost = float(r @ r)
    fitness = [n / cost]
    lam, jacobians, step, predicted, since = 1e-3, 0, STEP, 1.0, 0  # since: the resolution window's first step
    ends = []  # the RMSE [N] each Jacobian's Gauss-Newton step predicts at its end
    stop, converged, rule = f"budget of {max_jacobians} Jacobians spent while still improving", False, "budget"
    while jacobians < max_jacobians:
        lin = _linearised(residuals, u, r, step, log)
        jacobians, free, Jf, gf = jacobians + 1, lin.free, lin.Jf, lin.gf
        predicted = float(cost - np.sum((r + Jf @ np.linalg.lstsq(Jf, -r, rcond=1e-10)[0]) ** 2)) / cost
        log(f"    polish: Jacobian {jacobians}/{max_jacobians}, RMSE {math.sqrt(cost / n):.2f} N, "
            f"Gauss-Newton step predicts {100 * predicted:.2g} % of the SSE")
        advance(log, 0.85 + 0.15 * min(1.0, jacobians / TYPICAL_JACOBIANS))
        if predicted < RTOL:
            stop, converged, rule = f"converged: the Gauss-Newton step predicts {predicted:.1e} of the SSE", True, \
                "first-order"
            break
        ends.append(math.sqrt(max(cost * (1.0 - predicted), 0.0) / n))
        if beat is not None and cannot_beat(ends, math.sqrt(beat / n), rmse_standard_error(r)):
            stop, rule = beat_text(ends, math.sqrt(beat / n)), "cannot beat"
            break
        accepted = _damped_step(residuals, u, free, Jf, gf, cost, lam)
        if accepted is None and step < COARSE_STEP:
            log(f"    polish: no damped step lowers the SSE with finite differences of {step:g}; "
                f"differences of {COARSE_STEP:g} from here (the objective is rough on the fine scale)")
            step, lam, since = COARSE_STEP, 1e-3, len(fitness) - 1
            continue
        if accepted is None:
            converged, rule = predicted < STALL_RTOL, "stationary"
            stop = (f"{'converged' if converged else 'stalled'}: no damped step lowers the SSE "
                    f"(the Gauss-Newton step predicts {predicted:.1e} of it, differences of {step:g})")
            break
        cost, lam, u, r = accepted
        lam = max(lam / 5.0, 1e-9)
        fitness.append(n / cost)
        resolved = resolution_stop(fitness[since:], r)
        if resolved and resolvable_gain(predicted, r):  # the step promises what the data can show: a stall
            if step < COARSE_STEP:
                log(f"    polish: the last {RESOLUTION_WINDOW} Jacobians achieved little while the Gauss-Newton step "
                    f"predicts {100 * predicted:.2g} % of the SSE; differences of {COARSE_STEP:g} from here")
                step, lam, since = COARSE_STEP, 1e-3, len(fitness) - 1
                continue
            stop, converged, rule = stalled_text(fitness, predicted, r), False, "stalled"
            break
        if resolved:
            stop, converged, rule = resolved, True, "data resolution"
            break
    z = par.from_params(space.to_params(u))
    return PolishResult(z, n / cost, used["evals"], stop=stop, converged=converged, rule=rule, jacobians=jacobians,
                        predicted=predicted, budget_spent=stop.startswith("budget"), history=fitness)


@dataclass(frozen=True)
class _Linearisation:
    """The residual's forward-difference Jacobian at a point, on the variables left free (``_free``): the free mask,
    their columns ``Jf`` [N per unit of the local coordinate] and gradient ``gf`` = Jf^T r [N^2]."""

    free: np.ndarray
    Jf: np.ndarray
    gf: np.ndarray


def _linearised(residuals, u: np.ndarray, r: np.ndarray, step: float, log) -> _Linearisation:
    """One Jacobian of ``polish`` at the local point ``u`` (residual ``r`` [N]) by forward differences of ``step``
    (backward at the upper bound); a neighbour that cannot be simulated holds its variable for this step."""
    h = np.where(u + step <= 1.0, step, -step)
    cols = residuals([u + np.eye(u.size)[i] * h[i] for i in range(u.size)])
    failed = sum(c is None for c in cols)
    if failed:
        cols = [r if c is None else c for c in cols]
        log(f"    polish: {failed} finite-difference neighbours could not be simulated; held this step")
    J = np.column_stack([(c - r) / hi for c, hi in zip(cols, h)])
    g = J.T @ r
    free = _free(u, g)
    return _Linearisation(free, J[:, free], g[free])


def cannot_beat(ends: list[float], target: float, se: float) -> bool:
    """Whether a refinement cannot end below the RMSE ``target`` [N]: the ends its Gauss-Newton steps predicted
    (``ends`` [N], one per Jacobian) are above it for the last ``BEAT_PATIENCE`` Jacobians, each within ``se`` [N]
    (the RMSE's standard error) of the one before: the local model's prediction has settled."""
    last = ends[-BEAT_PATIENCE:]
    return (len(last) == BEAT_PATIENCE and min(last) > target
            and all(abs(a - b) <= se for a, b in zip(last, last[1:])))


def beat_text(ends: list[float], target: float) -> str:
    """Why a refinement stopped short of the RMSE ``target`` [N] (``polish``), its predicted ``ends`` [N]."""
    return (f"cannot end below {target:.2f} N: its Gauss-Newton step predicts "
            + ", ".join(f"{e:.2f}" for e in ends[-BEAT_PATIENCE:]) + " N at best, settled")


def _free(u: np.ndarray, g: np.ndarray) -> np.ndarray:
    """The active set: the variables not held on a bound (local coordinates in [0, 1]) by a gradient ``g`` of the
    SSE that points out of the box there."""
    return ~(((u <= 0.0) & (g > 0.0)) | ((u >= 1.0) & (g < 0.0)))


def _damped_step(residuals, u: np.ndarray, free: np.ndarray, Jf: np.ndarray, gf: np.ndarray, cost: float,
                 lam: float):
    """The Levenberg-Marquardt step of ``polish`` from ``u`` (local coordinates) on its ``free`` variables:
    two damping values per batch (lam and 10 lam, lam raised 100x after a batch that lowers nothing, at
    most 10 batches), steps projected into the box. Returns (SSE [N^2], damping, point, residual) of the
    best trial that lowers ``cost``, or None."""
    JtJ = Jf.T @ Jf
    scale = np.diag(np.maximum(np.diag(JtJ), 1e-30))
    accepted = None
    for _ in range(10):
        trials = []
        for damping in (lam, 10.0 * lam):
            un = u.copy()
            un[free] = np.clip(u[free] + np.linalg.solve(JtJ + damping * scale, -gf), 0.0, 1.0)
            trials.append((damping, un))
        for (damping, un), rn in zip(trials, residuals([t[1] for t in trials])):
            if rn is not None and float(rn @ rn) < cost and (accepted is None or float(rn @ rn) < accepted[0]):
                accepted = (float(rn @ rn), damping, un, rn)
        if accepted:
            return accepted
        lam *= 100.0
    return None


def small_progress(fitness: list[float], window: int = RESOLUTION_WINDOW) -> bool:
    """Whether the SSE fell by less than ``FTOL`` of itself over the last ``window`` steps of ``fitness``
    (G = N / SSE [1/N^2]); the cheap half of ``resolution_stop``, which needs a residual."""
    if len(fitness) <= window or not all(g > 0 for g in fitness[-1 - window:]):
        return False
    return fitness[-1] / fitness[-1 - window] - 1.0 < FTOL


def resolution_stop(fitness: list[float], r: np.ndarray, window: int = RESOLUTION_WINDOW,
                    steps: str = "Jacobians") -> str | None:
    """The stop text when an iterative stage has converged to the data's resolution (module docstring),
    else None: over the last ``window`` ``steps`` of ``fitness`` (G = N / SSE [1/N^2], one value per step,
    the start first) the SSE fell by less than FTOL and the RMSE by less than RESOLUTION_FRACTION of its
    standard error, taken from ``r``, the residual [N] now. Serves the refinement (Jacobians) and the
    Firefly search (iterations, ``tuner.identification.fit``)."""
    if not small_progress(fitness, window):
        return None
    rmse_then, rmse_now = fitness[-1 - window] ** -0.5, fitness[-1] ** -0.5
    share = (rmse_then ** 2 - rmse_now ** 2) / rmse_now ** 2
    se = rmse_standard_error(r)
    if rmse_then - rmse_now >= RESOLUTION_FRACTION * se:
        return None
    return (f"converged to the data's resolution: the last {window} {steps} took the RMSE from "
            f"{rmse_then:.4g} to {rmse_now:.4g} N ({100 * share:.2g} % of the SSE), less than "
            f"{RESOLUTION_FRACTION:g} x its standard error of {se:.3g} N")



def resolvable_gain(predicted: float, r: np.ndarray) -> bool:
    """Whether a Gauss-Newton step that ``predicted`` (0-1) a share of the SSE would lower the RMSE of the residual
    ``r`` [N] by at least one standard error (``tuner.metrics.rmse_standard_error``): a gain the data can show. A
    refinement whose steps achieve far less than that is stalled (a rough objective, a variable held at a bound),
    not converged: on a real MR damper its last three Jacobians moved the two-chamber fit by 0.06 N while each
    predicted 13-41 % of the SSE, and the same start with coarse differences ended 22 % lower."""
    rmse = math.sqrt(float(r @ r) / r.size)
    return rmse * (1.0 - math.sqrt(max(0.0, 1.0 - predicted))) >= rmse_standard_error(r)


def stalled_text(fitness: list[float], predicted: float, r: np.ndarray) -> str:
    """The stop text of a stalled refinement: the last RESOLUTION_WINDOW steps of ``fitness`` (G = N / SSE
    [1/N^2]) achieved less than the data resolve while the Gauss-Newton step predicted ``predicted`` of the SSE."""
    then, now = fitness[-1 - RESOLUTION_WINDOW] ** -0.5, fitness[-1] ** -0.5
    return (f"stalled: the last {RESOLUTION_WINDOW} Jacobians took the RMSE from {then:.4g} to {now:.4g} N while "
            f"the Gauss-Newton step predicts {100 * predicted:.2g} % of the SSE, more than one standard error "
            f"({rmse_standard_error(r):.3g} N) of the RMSE: not a minimum (differences of {COARSE_STEP:g})")
