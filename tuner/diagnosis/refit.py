"""Refits of a base model extended by effect elements (the diagnosis's workhorse).

``refit``: a profile line search on the effect parameter(s) with the base re-balanced, then a joint least-squares
polish (a ``RefitResult``); a nonsmooth effect's magnitude (a free play, ``Effect.nonsmooth``) is profiled with the
model re-fitted at each grid value (``tuner.diagnosis.held_profiles``); ``effect_intervals``: 95 % intervals of the
effect parameters (block sandwich: residuals are correlated in time). The extended model's coordinates, the grid
and the base Jacobian are in ``tuner.diagnosis.extended_parametrization``. Units: SI; residuals in N.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tuner.diagnosis.extended_parametrization import ExtendedParametrization, grid
from tuner.diagnosis.held_profiles import PROBE_JACOBIANS, nonsmooth_profiles
from tuner.diagnosis.significance import block_sandwich, correlation_time, interval
from tuner.identification.engine import Engine
from tuner.identification.polish import polish

__all__ = ["refit", "RefitProfile", "RefitResult", "effect_intervals", "MIN_BLOCKS", "PROFILE_SHARE"]

#: fewest independent residual blocks for a confidence interval to be trusted
MIN_BLOCKS = 10
#: the least share of the SSE the profile line search (the base re-balanced) must win for the joint polish
#: to follow (as ``tuner.diagnosis.screen.SCREEN_SHARE``: a cause needs about 7 % of the held-out MSE)
PROFILE_SHARE = 0.02


@dataclass(frozen=True)
class RefitResult:
    """The best point of one ``refit`` of an extended model."""

    #: the point, in the search coordinates of the ``ExtendedParametrization`` refitted (each in [0, 1])
    z: np.ndarray
    #: its fitness G = N / SSE [1/N^2] on the identification data (N samples, SSE [N^2])
    fitness: float
    #: simulations run (line search, profile steps and joint polish)
    evaluations: int


@dataclass(frozen=True)
class RefitProfile:
    """What ``refit`` profiles: the extra parameters of ``ext.extra`` at the indices ``indices`` (None: all; the
    others, e.g. effects already selected or a form's shape, are kept at their values in the start), and ``fresh``:
    a second start (search coordinates) for the held profiles of the nonsmooth effects (``nonsmooth_profiles``), one
    that has absorbed nothing (the data-driven guess; None: none); ``sweep_gain_n`` [N]: the fall of the RMSE a held
    profile's swept value must show to count as progress (``tuner.diagnosis.held_profiles.sweep_gain``; 0: any)."""

    indices: object = None
    fresh: np.ndarray | None = None
    sweep_gain_n: float = 0.0


def refit(eid: Engine, ext: ExtendedParametrization, z0: np.ndarray, sse0: float, jac_svd,
          settings, jacobians: int, *, profile: RefitProfile = RefitProfile()) -> RefitResult:
    """Profile line search on the effect parameters of ``ext.extra`` at the indices ``profile.indices``
    (default all; the others, e.g. effects already selected or a form's shape, are kept at their
    values in z0) from z0 (identification SSE sse0 [N^2]),
    then a joint polish of at most ``jacobians`` Jacobians; returns the best point as a ``RefitResult``.

    Line search: for each grid value, the effect parameter is set with the base fixed, then the
    current model is re-balanced (what it had absorbed of the effect) by Levenberg-Marquardt steps
    with its Jacobian ``jac_svd`` at z0 kept fixed (at most ``profile_steps`` batches, while the fit
    improves by more than 1 %; none when ``jac_svd`` is None); the best point seen starts the
    polish. The Jacobian covers the first coordinates of ``ext`` that the current model has: the base
    alone, or the base and the effects already selected (a form tried on top of named causes), as
    many as its columns. From a start of known SSE, when the profile does not win ``PROFILE_SHARE`` of it,
    the joint polish stops after ``PROBE_JACOBIANS`` unless they win it (most refits of effects the data
    do not carry end there, at a quarter of the cost). ``profile.fresh``: a second start for the held profiles of
    the nonsmooth effects (``nonsmooth_profiles``), one that has absorbed nothing (the data-driven guess).
    """
    fresh, indices = profile.fresh, profile.indices
    dim = ext.base.dimension
    if jac_svd is not None and not dim <= jac_svd[2].shape[1] <= ext.dimension:
        raise ValueError(f"refit: a Jacobian of {jac_svd[2].shape[1]} columns for a model of {dim} base and "
                         f"{ext.dimension - dim} effect coordinates")
    balanced = jac_svd[2].shape[1] if jac_svd is not None else dim  # the coordinates the LM steps move
    pts = []
    for i, (lo, hi) in enumerate(ext.extra_bounds):
        if indices is not None and i not in indices:  # kept at its value in z0 during the profile
            continue
        for val in grid(lo, hi, settings.grid_points, ext.floors[i]):
            z = z0.copy()
            z[dim + i] = (val - lo) / (hi - lo)
            pts.append(z)
    res = eid.residuals_batch([ext.to_params(z) for z in pts])
    evals = len(pts)
    if jac_svd is not None:
        u, sv, vt = jac_svd
        # Levenberg-Marquardt with the fixed base Jacobian, per grid value: a step that does not
        # lower the SSE is retried with 10x the damping, a successful one relaxes it 3x
        active = [[z, r, float(r @ r), (1e-3 * sv[0]) ** 2] for z, r in zip(pts, res) if r is not None]
        for _ in range(settings.profile_steps):
            trial = []
            for z, r, _, lam in active:
                zc = z.copy()
                zc[:balanced] = np.clip(z[:balanced] - vt.T @ ((sv / (sv * sv + lam)) * (u.T @ r)), 0.0, 1.0)
                trial.append(zc)
            res_t = eid.residuals_batch([ext.to_params(z) for z in trial])
            evals += len(trial)
            pts += trial
            res += res_t
            still = []
            for a, zc, rc in zip(active, trial, res_t):
                sse_c = float(rc @ rc) if rc is not None else math.inf
                if sse_c < a[2]:
                    if sse_c > 0.99 * a[2]:
                        continue  # converged: less than 1 % gain
                    still.append([zc, rc, sse_c, a[3] / 3.0])
                elif a[3] < 1e3 * sv[0] ** 2:
                    still.append([a[0], a[1], a[2], a[3] * 10.0])
            active = still
            if not active:
                break
    sse = [float(r @ r) if r is not None else math.inf for r in res]
    held = nonsmooth_profiles(eid, ext, [z0] if fresh is None else [z0, fresh], pts, sse, indices,
                              sse0 if math.isfinite(sse0) else math.inf, profile.sweep_gain_n)
    evals += held.evaluations
    pts, sse = pts + held.points, sse + held.sse
    k = int(np.argmin(sse))
    z_start = pts[k] if sse[k] < sse0 else z0
    if jac_svd is not None and math.isfinite(sse0) and not sse[k] < (1.0 - PROFILE_SHARE) * sse0:
        # the profile, the base re-balanced, did not win PROFILE_SHARE of the SSE: the joint polish (most of
        # the refit's cost) goes on only if its first PROBE_JACOBIANS win it (a joint move the profile's
        # fixed Jacobian cannot make, e.g. a preload between two grid values with the tables shifted back)
        probe = polish(eid, ext, z_start, max_jacobians=min(PROBE_JACOBIANS, jacobians), log=lambda m: None)
        evals += probe.evaluations
        if jacobians <= PROBE_JACOBIANS or not eid.n_samples / probe.fitness < (1.0 - PROFILE_SHARE) * sse0:
            return RefitResult(probe.z, probe.fitness, evals)
        z_start, jacobians = probe.z, jacobians - PROBE_JACOBIANS
    joint = polish(eid, ext, z_start, max_jacobians=jacobians, log=lambda m: None)
    return RefitResult(joint.z, joint.fitness, evals + joint.evaluations)


def effect_intervals(eid: Engine, ext: ExtendedParametrization, z: np.ndarray, step: float = 1e-4) -> dict:
    """95 % confidence interval of each effect parameter of the extended model fitted at ``z`` (SI
    units), from the identification residual's Jacobian by the block sandwich
    (``tuner.diagnosis.significance``: valid for correlated residuals). Base coordinates at a bound are held
    there. Returns {name: {value, std, low, high, excludes_zero}} plus '_blocks' and
    '_correlation_time_s' (the residual's, which sets the block length: 3 correlation times). When the point or
    one of its steps cannot be simulated, every interval is unbounded (not significant: no magnitude is named on
    it), '_blocks' is 0, '_correlation_time_s' NaN and '_not_computed' says why (blind seed 1396: a two-chamber
    refit whose steps the stage's Newton could not solve had ended the whole diagnosis with a KeyError)."""
    z = np.clip(np.asarray(z, dtype=float), 0.0, 1.0)
    dim = ext.base.dimension
    free = [i for i in range(ext.dimension) if i >= dim or 1e-9 < z[i] < 1 - 1e-9]
    steps = {i: (step if z[i] + step <= 1.0 else -step) for i in free}
    pts = [z] + [z + np.eye(ext.dimension)[i] * steps[i] for i in free]
    res = eid.residuals_batch([ext.to_params(p) for p in pts])
    r0 = res[0]
    out: dict = {}
    if r0 is None or any(r is None for r in res[1:]):
        why = ("the fitted point" if r0 is None else "a step of it") + " could not be simulated (" + (
            eid.last_failure or "no reason given") + ")"
        return {**{n: {"value": ext.to_params(z)[n], "std": math.inf, "low": -math.inf, "high": math.inf,
                       "excludes_zero": False} for n in ext.extra},
                "_blocks": 0, "_correlation_time_s": math.nan, "_not_computed": why}
    jac = np.column_stack([(r - r0) / steps[i] for r, i in zip(res[1:], free)])
    lengths = [int(s.mask.sum()) for s in eid.tests]
    tau = correlation_time(r0)
    cov, blocks = block_sandwich(jac, r0, lengths, math.ceil(3 * tau))
    rate = (len(eid.tests[0].time) - 1) / (eid.tests[0].time[-1] - eid.tests[0].time[0])
    params = ext.to_params(z)
    for k, (n, (lo, hi)) in enumerate(zip(ext.extra, ext.extra_bounds)):
        j = free.index(dim + k)
        std = math.sqrt(max(cov[j, j], 0.0)) * (hi - lo)
        low, high = interval(params[n], std)
        out[n] = {"value": params[n], "std": std, "low": low, "high": high,
                  "excludes_zero": bool(blocks >= MIN_BLOCKS and (low > 0.0 or high < 0.0))}
    out["_blocks"], out["_correlation_time_s"] = blocks, tau / rate
    return out
