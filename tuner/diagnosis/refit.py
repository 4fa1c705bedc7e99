"""Refits of a base model extended by effect elements (the diagnosis's workhorse).

``ExtendedParametrization``: the base design vector plus effect parameters, linear within their
search bounds (``damper_fmu.effect_catalogue.search_bounds``: each effect's rule); ``refit``: a profile
line search on the effect parameter(s) with the base re-balanced, then a joint least-squares polish
(a ``RefitResult``); a nonsmooth effect's magnitude (a free play, ``Effect.nonsmooth``) is profiled with the
model re-fitted at each grid value (``held_profile``); ``base_jacobian``: the SVD of the
residual's Jacobian that re-balances the base; ``effect_intervals``: 95 % intervals of the effect
parameters (block sandwich: residuals are correlated in time). Units: SI; residuals in N.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np

from damper_fmu.effect_catalogue import ALL_EFFECTS, EFFECT_PARAMETERS, effect_of, search_bounds

from tuner.diagnosis.effect_sizes import REFERENCE, DamperSize, meaningful_floor
from tuner.diagnosis.significance import block_sandwich, correlation_time, interval
from tuner.identification.engine import Engine
from tuner.identification.parametrization import Parametrization
from tuner.identification.polish import polish

__all__ = ["ExtendedParametrization", "grid", "base_jacobian", "refit", "RefitResult", "HeldProfile",
           "held_profile", "nonsmooth_profiles", "effect_intervals", "MIN_BLOCKS", "HELD_PROFILE_JACOBIANS",
           "HELD_PATIENCE"]

#: fewest independent residual blocks for a confidence interval to be trusted
MIN_BLOCKS = 10
#: the least share of the SSE the profile line search (the base re-balanced) must win for the joint polish
#: to follow (as ``tuner.diagnosis.screen.SCREEN_SHARE``: a cause needs about 7 % of the held-out MSE)
PROFILE_SHARE = 0.02
#: Jacobians of the joint polish that must win PROFILE_SHARE when the profile did not, for the rest to follow
PROBE_JACOBIANS = 2
#: Jacobians of the re-fit at each grid value of a nonsmooth effect's magnitude (``held_profile``; measured on a
#: 0.52 mm free play with soft contact, where the re-balance on the base's Jacobian picked 0.15 mm: at the grid
#: values 0.15, 0.28, 0.55, 1.05 mm the RMSE after 2 Jacobians 604, 568, 404, 2139 N; after 3: 589, 546, 221,
#: 1477 N, as after 4 (588, 543, 210, 1456 N))
HELD_PROFILE_JACOBIANS = 3
#: ... and at each value of the coarse pass from a start that has absorbed nothing (``_grid_profile``)
COARSE_HELD_JACOBIANS = 1
#: values in a row that fit worse than the best so far (at first: the model without the effect) after which the
#: held profile's upward sweep stops
HELD_PATIENCE = 3
#: a held value re-fitted from the refit's start that leaves this many times the SSE of the model without the
#: effect (RMSE 2x) ends that start's sweep at once when a start that has absorbed nothing follows
#: (``_swept_profile``): the start has absorbed the effect where a few Jacobians cannot undo it. A two-chamber
#: base that had absorbed a 0.52 mm gap: 2443, 2291 and 2464 N rms at the first three values against 847 N
#: without it (8.3x, 7.3x, 8.5x the SSE), 407 simulations and 27 s for nothing; the guess's profile found it
FAR_WORSE = 4.0
#: Jacobians per value of a held profile with the series element held too (``series_profiles``)
SERIES_HELD_JACOBIANS = 2
DEFAULTS = {p.name: p.default for p in EFFECT_PARAMETERS}


class ExtendedParametrization:
    """The base design vector followed by the identified parameters of one or more effects
    (``effect``: a name, or names joined by '+'; linear within their search bounds); ``fixed``: effect
    settings that are not identified but chosen for this model (a groove's direction) [SI]."""

    def __init__(self, base: Parametrization, effect: str, peak_force: float, stroke_range_m: float | None = None,
                 stroke_limits: tuple[float, float] | None = None, fixed: dict | None = None):
        self.base, self.effect, self.stroke_range_m = base, effect, stroke_range_m
        self.fixed = dict(fixed or {})
        self.peak_force, self.stroke_limits = peak_force, stroke_limits
        self.effects = effect.split("+")
        self.extra = [n for e in self.effects for n in ALL_EFFECTS[e].identified]
        self.extra_bounds = [search_bounds(n, peak_force, stroke_range_m, stroke_limits) for n in self.extra]
        size = DamperSize(peak_force, stroke_range_m or REFERENCE.stroke_range_m)
        #: the smallest magnitude of each extra parameter that is a cause on this damper (None: a shape)
        self.floors = [meaningful_floor(n, size) if n in effect_of(n).typical else None for n in self.extra]
        self.dimension = base.dimension + len(self.extra)
        self.names = base.names + self.extra

    def to_params(self, z) -> dict:
        z = np.clip(np.asarray(z, dtype=float), 0.0, 1.0)
        p = self.base.to_params(z[: self.base.dimension])
        for i, (n, (lo, hi)) in enumerate(zip(self.extra, self.extra_bounds)):
            p[n] = lo + z[self.base.dimension + i] * (hi - lo)
        p.update(self.fixed)
        return p

    def from_params(self, params: dict) -> np.ndarray:
        zb = self.base.from_params(params)
        ze = [(params.get(n, DEFAULTS[n]) - lo) / (hi - lo) for n, (lo, hi) in zip(self.extra, self.extra_bounds)]
        return np.concatenate([zb, np.clip(ze, 0.0, 1.0)])

    def holding(self, values: dict) -> "ExtendedParametrization":
        """The same with the extra parameters of ``values`` (SI) held at them: moved to ``fixed``, no longer
        coordinates (a profile point re-fits the rest)."""
        held = copy.copy(self)
        keep = [k for k, n in enumerate(self.extra) if n not in values]
        held.extra = [self.extra[k] for k in keep]
        held.extra_bounds = [self.extra_bounds[k] for k in keep]
        held.floors = [self.floors[k] for k in keep]
        held.fixed = {**self.fixed, **{n: float(v) for n, v in values.items()}}
        held.dimension = self.base.dimension + len(held.extra)
        held.names = self.base.names + held.extra
        return held

    def holding_base(self, values: dict) -> "ExtendedParametrization":
        """The same with the base parameters of ``values`` (SI, scalars) held at them (``Parametrization.holding``)."""
        held = copy.copy(self)
        held.base = self.base.holding(values)
        held.dimension = held.base.dimension + len(self.extra)
        held.names = held.base.names + self.extra
        return held

    def local_space(self) -> "ExtendedParametrization":
        """The same with the base in its local solver's coordinates (``Parametrization.local_space``)."""
        local = copy.copy(self)
        local.base = self.base.local_space()
        local.names = local.base.names + self.extra
        return local

    def describe(self) -> str:
        return f"{self.base.describe()}; plus {', '.join(self.extra)} (linear within the search bounds)"


def grid(lo: float, hi: float, n: int, floor: float | None = None) -> list[float]:
    """Candidate values for the line search: both signs when the range straddles zero; else geometric from
    2 % of the range, or from ``floor`` (the smallest magnitude that would be a cause on this damper,
    ``tuner.diagnosis.effect_sizes.meaningful_floor``) when that lies lower (a small damper's causes)."""
    if lo < 0.0 < hi:
        return list(np.linspace(lo, hi, 2 * (n // 2) + 1))
    if lo == 0.0 and floor is not None and 0.0 < floor < 0.02 * hi:
        return list(np.geomspace(floor, hi, n))
    return [lo + (hi - lo) * f for f in np.geomspace(0.02, 1.0, n)]


def base_jacobian(eid: Engine, par, z0: np.ndarray, step: float = 1e-4, dims: int | None = None):
    """SVD (U, s, Vt) of the identification residual's Jacobian [N per scaled unit] with respect
    to the first ``dims`` scaled coordinates (default all) of ``par`` (a Parametrization or an
    ExtendedParametrization) at z0 (forward differences, one parallel batch of dims + 1 runs);
    None when z0 cannot be simulated."""
    dims = len(z0) if dims is None else dims
    steps = np.where(z0[:dims] + step <= 1.0, step, -step)
    pts = [z0] + [z0 + np.eye(len(z0))[i] * steps[i] for i in range(dims)]
    res = eid.residuals_batch([par.to_params(p) for p in pts])
    if res[0] is None:
        return None
    cols = [(r - res[0]) / h if r is not None else np.zeros_like(res[0]) for r, h in zip(res[1:], steps)]
    return np.linalg.svd(np.column_stack(cols), full_matrices=False)


@dataclass(frozen=True)
class RefitResult:
    """The best point of one ``refit`` of an extended model."""

    #: the point, in the search coordinates of the ``ExtendedParametrization`` refitted (each in [0, 1])
    z: np.ndarray
    #: its fitness G = N / SSE [1/N^2] on the identification data (N samples, SSE [N^2])
    fitness: float
    #: simulations run (line search, profile steps and joint polish)
    evaluations: int


def refit(eid: Engine, ext: ExtendedParametrization, z0: np.ndarray, sse0: float, jac_svd,
           settings, jacobians: int, profile=None, fresh: np.ndarray | None = None) -> RefitResult:
    """Profile line search on the effect parameters of ``ext.extra`` at the indices ``profile``
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
    do not carry end there, at a quarter of the cost). ``fresh``: a second start for the held profiles of the
    nonsmooth effects (``nonsmooth_profiles``), one that has absorbed nothing (the data-driven guess).
    """
    dim = ext.base.dimension
    if jac_svd is not None and not dim <= jac_svd[2].shape[1] <= ext.dimension:
        raise ValueError(f"refit: a Jacobian of {jac_svd[2].shape[1]} columns for a model of {dim} base and "
                         f"{ext.dimension - dim} effect coordinates")
    balanced = jac_svd[2].shape[1] if jac_svd is not None else dim  # the coordinates the LM steps move
    pts = []
    for i, (lo, hi) in enumerate(ext.extra_bounds):
        if profile is not None and i not in profile:  # kept at its value in z0 during the profile
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
    held = nonsmooth_profiles(eid, ext, [z0] if fresh is None else [z0, fresh], pts, sse, profile,
                              sse0 if math.isfinite(sse0) else math.inf)
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


@dataclass(frozen=True)
class HeldProfile:
    """The points of a ``held_profile``: each in the search coordinates of the ``ExtendedParametrization``, its
    identification SSE [N^2] (inf: could not be simulated), and the simulations run."""

    points: list
    sse: list
    evaluations: int

    def joined(self, other: "HeldProfile") -> "HeldProfile":
        """This profile's points followed by ``other``'s, the simulations of both."""
        return HeldProfile(self.points + other.points, self.sse + other.sse, self.evaluations + other.evaluations)


def nonsmooth_profiles(eid: Engine, ext: ExtendedParametrization, starts: list, pts: list, sse: list,
                       profile=None, sse_off: float = math.inf) -> HeldProfile:
    """The ``held_profile`` of every nonsmooth effect's magnitude among the extra parameters profiled (``profile``:
    their indices, default all) of the refit whose profile points ``pts`` (search coordinates) have the SSE
    ``sse`` [N^2], from each of ``starts`` (search coordinates): the refit's start (``_swept_profile``) and
    possibly one that has absorbed nothing (``_grid_profile``). ``sse_off`` [N^2]: the refit's start, the model
    without the effect.

    Why a second start: a base fitted without the effect may have absorbed it where a few Jacobians cannot
    undo it. A two-chamber damper with a 0.52 mm gap in its mounts (soft contact) was fitted as 24 entrained
    air (truth 2.8), a 4x softer area ratio and chamber: 847 N rms against 26 N for the truth. With the gap
    held at its true value, 30 Jacobians from that base end at 1472 N; from the data-driven guess, at 27 N
    (5 Jacobians: 284 N, against 696 and 1050 N at 0.2 and 0.8 mm)."""
    dim, out = ext.base.dimension, HeldProfile([], [], 0)
    for i in (profile if profile is not None else range(len(ext.extra))):
        effect = effect_of(ext.extra[i])
        if not (effect.nonsmooth and ext.extra[i] == effect.magnitude):
            continue
        values = sorted({float(z[dim + i]) for z in pts if float(z[dim + i]) > 0.0})
        if not values:
            continue
        best = float(pts[int(np.argmin(sse))][dim + i])
        out = out.joined(_swept_profile(eid, ext, starts[0], i, values, best, sse_off, far_stop=len(starts) > 1))
        for z0 in starts[1:]:
            out = out.joined(_grid_profile(eid, ext, z0, i, values, sse_off))
    return out


def _swept_profile(eid: Engine, ext: ExtendedParametrization, z0: np.ndarray, i: int, values: list, best: float,
                   sse_off: float, far_stop: bool = False) -> HeldProfile:
    """The held profile from the refit's start ``z0``: the profile's grid ``values`` (search coordinates) from the
    value below ``best`` (the grid profile's best point) up (the base absorbs a nonsmooth effect as a smaller
    one; the value below brackets the best) with the geometric mean of each two neighbours between them (the
    profile's minimum is narrow: a 0.40 mm gap between the grid values 0.28 and 0.54 mm was missed), swept
    upward until ``HELD_PATIENCE`` values in a row fit worse than the best so far, the model without the effect
    (SSE ``sse_off`` [N^2]) counting as the first; each value re-fitted from the best value's point so far
    (``held_profile``'s ``chained``: a continuation in the magnitude); then ``_with_vertex``. ``far_stop`` (a start
    that has absorbed nothing follows): a value ``FAR_WORSE`` x ``sse_off`` or worse before any beat it ends the
    sweep."""
    k = max(0, max((j for j, v in enumerate(values) if v <= best), default=0) - 1)
    sweep = []
    for lo, hi in zip(values[k:], values[k + 1:]):
        sweep += [lo, math.sqrt(lo * hi)]
    held = held_profile(eid, ext, z0, i, sweep + values[-1:], sse_off, chained=True,
                        far=FAR_WORSE if far_stop else None)
    return _with_vertex(eid, ext, i, held, sse_off)


def series_profiles(eid: Engine, ext: ExtendedParametrization, z0: np.ndarray, i: int, values: list,
                    sse_off: float, held: list[dict], enough: float = 0.0) -> HeldProfile:
    """The held profile of the nonsmooth magnitude ``i`` of ``ext`` (a free play) from ``z0`` (search coordinates)
    with the element in series with it held at each of ``held`` (``{stiffness: N/m, damping: N s/m}``,
    ``damper_fmu.parameters.SERIES_ELEMENT``): at every value of ``values`` (search coordinates, ascending) the
    rest re-fitted with ``SERIES_HELD_JACOBIANS`` (stopping ``HELD_PATIENCE`` values past its best), then the
    series element released at the best value (``HELD_PROFILE_JACOBIANS``) and the chained profile swept from
    there (``_swept_profile``; ``sse_off`` [N^2]: the model without the effect); the held values after one whose
    profile reaches ``enough`` [N^2] are not tried; with ``enough`` given, a short joint polish from each release
    (``_probe``) that reaches it ends the profile there. A held value whose coarse profile fits no better than the
    model without the effect (``sse_off``) anywhere shows no gap the element hid: it is not released nor swept (on
    a real MR damper, whose fit wants a soft mount, the release and sweeps of two held values took three of a
    diagnosis's four minutes to end 0.2 N above the base). Points in ``ext``'s coordinates.

    Why: a base fitted without the gap may have made its mount a dashpot, which carries a gap's lost motion as
    well as a gap can, and a refit with the gap from there keeps it. A two-chamber damper with a 0.114 mm gap in
    stiff mounts (7.4e8 N/m, 8e4 N s/m) was fitted at 126 N rms with the mount at 3.2e5 N/m and 1.6e7 N s/m;
    every profile from that base or from the data-driven guess (the mount at the preset's 3e7 N/m) stayed at
    125-242 N. With the mount held at 3e8 N/m and 5.1e4 N s/m, two Jacobians per gap value: 121, 87, 161 and
    576 N at 0.03, 0.06, 0.12 and 0.24 mm; released at 0.06 mm, 74 N with the mount at 1.8e8 N/m; at 3e9 N/m the
    best was 0.12 mm (77 N, released 63 N); at the preset's 3e7 N/m, 408 N and more."""
    out = HeldProfile([], [], 0)
    for values_held in held:
        space = ext.holding_base(values_held)
        coarse = held_profile(eid, space, space.from_params(ext.to_params(z0)), i, values,
                              jacobians=SERIES_HELD_JACOBIANS)
        points = [ext.from_params(space.to_params(z)) for z in coarse.points]
        out = out.joined(HeldProfile(points, coarse.sse, coarse.evaluations))
        b = int(np.argmin(coarse.sse))
        if not (coarse.sse[b] < sse_off):  # no gap fits better than none with the element held: nothing to release
            continue
        released = held_profile(eid, ext, points[b], i, [values[b]])
        out = out.joined(released)
        if enough > 0.0 and math.isfinite(released.sse[0]):
            out = out.joined(_probe(eid, ext, released.points[0]))
            if min(out.sse) <= enough:
                break
        out = out.joined(_swept_profile(eid, ext, released.points[0], i, values, values[b], sse_off))
        if min(out.sse) <= enough:
            break
    return out


def _probe(eid: Engine, ext: ExtendedParametrization, z0: np.ndarray) -> HeldProfile:
    """``PROBE_JACOBIANS`` of the joint polish (every coordinate free, the magnitude too) from a released point
    ``z0`` (search coordinates), as a one-point profile: inside the gap's basin its force has a gradient, and the
    polish can take the rest of the way that a swept profile would take value by value. A 0.54 mm gap in stiff
    two-chamber mounts (1.8e8 N/m): released at the grid's 0.54 mm with the mount held at 3e8 N/m, 52 N rms; the
    chained sweep from there (59 s) and the next held value (92 s) ended no lower, the joint polish from the
    released point at 21 N, the truth's own."""
    pol = polish(eid, ext, z0, max_jacobians=PROBE_JACOBIANS, log=lambda m: None)
    return HeldProfile([pol.z], [eid.n_samples / pol.fitness if pol.fitness > 0 else math.inf], pol.evaluations)


def _grid_profile(eid: Engine, ext: ExtendedParametrization, z0: np.ndarray, i: int, values: list,
                  sse_off: float) -> HeldProfile:
    """The held profile from a start that has absorbed nothing (``z0``, the data-driven guess): coarse at every
    value of the profile's grid ``values`` (search coordinates; ``COARSE_HELD_JACOBIANS`` each, no early stop),
    then fine (``HELD_PROFILE_JACOBIANS``) at the coarse best and the geometric means with its neighbours, then
    ``_with_vertex`` through the fine values (coarse and fine values are not compared: unequal effort). No sweep
    from the grid profile's best, as from the refit's start: from such a start the profile can be flat over the
    small values and fall only near the magnitude the data hold (a 0.52 mm gap in a two-chamber damper: 818-838 N
    rms at 0.04-0.15 mm, against 819 N without it; 577, 419 and 492 N at 0.28, 0.39 and 0.54 mm), where a sweep
    that stops after a few values that fit no better never arrives. The coarse pass is a fifth of the cost and
    points the same way (there, after one Jacobian: 587 N at 0.54 mm, 625 at 0.28, 832-1065 below, 2116 at 1.04;
    after two: 170, 559, 813-929, 1982 N)."""
    coarse = held_profile(eid, ext, z0, i, values, patience=None, jacobians=COARSE_HELD_JACOBIANS)
    b = int(np.argmin(coarse.sse))
    fine = [math.sqrt(values[b - 1] * values[b])] if b > 0 else []
    fine += [values[b]] + ([math.sqrt(values[b] * values[b + 1])] if b + 1 < len(values) else [])
    held = held_profile(eid, ext, z0, i, fine, patience=None)
    return coarse.joined(_with_vertex(eid, ext, i, held, sse_off))


def _with_vertex(eid: Engine, ext: ExtendedParametrization, i: int, held: "HeldProfile",
                 sse_off: float) -> "HeldProfile":
    """``held`` and, when one of its values beat the model without the effect (SSE ``sse_off`` [N^2]), the held
    value at the vertex of the parabola through its best value and their neighbours (``_vertex_value``),
    re-fitted from the best value's point (closer to the vertex than the profile's start)."""
    vertex = _vertex_value(held, ext.base.dimension + i) if min(held.sse, default=math.inf) < sse_off else None
    if vertex is None:
        return held
    start = held.points[int(np.argmin(held.sse))]
    return held.joined(held_profile(eid, ext, start, i, [vertex]))


def _vertex_value(held: HeldProfile, k: int) -> float | None:
    """The search coordinate ``k``'s value at the vertex of the parabola through the held profile's best point and
    its two neighbours (in the logarithm of the magnitude: the values are geometric), or None when the best is
    at an end of the profile or the parabola opens downward."""
    order = sorted(range(len(held.points)), key=lambda j: float(held.points[j][k]))
    b = min(range(len(order)), key=lambda j: held.sse[order[j]])
    if not 0 < b < len(order) - 1:
        return None
    js = order[b - 1:b + 2]
    x = [float(held.points[j][k]) for j in js]
    y = [held.sse[j] for j in js]
    if min(x) <= 0.0 or not all(math.isfinite(v) for v in y):
        return None
    a, bb, _ = np.polyfit(np.log(x), y, 2)
    return float(np.clip(math.exp(-bb / (2.0 * a)), x[0], x[2])) if a > 0.0 else None


def held_profile(eid: Engine, ext: ExtendedParametrization, z0: np.ndarray, i: int, values: list,
                 sse_off: float = math.inf, patience: int | None = HELD_PATIENCE,
                 jacobians: int = HELD_PROFILE_JACOBIANS, chained: bool = False,
                 far: float | None = None) -> HeldProfile:
    """The profile of the extra parameter ``i`` of ``ext`` (a nonsmooth effect's magnitude) at ``values`` (its
    search coordinate, swept in their order): ``z0`` with each value re-fitted with it held
    (``jacobians`` Jacobians of the local refinement over every other coordinate), so that what the
    base absorbed of the effect (a soft elastic table in place of a dead band) is given back at each value;
    the sweep stops once ``patience`` values in a row (None: never) fit worse than the best so far, where the model
    without the effect (identification SSE ``sse_off`` [N^2]) is the first best: a start from which holding the
    effect only makes the fit worse is left after HELD_PATIENCE values (a two-chamber base that had absorbed a
    0.52 mm gap: 2389-3017 N rms at 0.15-0.54 mm against 847 N without it, 96 s of 284 for the refit).

    ``chained``: each value re-fitted from the point of the best value so far when that fits better than the
    model without the effect (else from ``z0``): a continuation in the magnitude, along which the base gives back
    step by step what it absorbed. A two-chamber damper with a 0.114 mm gap in stiff mounts (7.4e8 N/m) was
    fitted without it at 123 N rms with the mount's damping 30x the truth's; held at the true gap, 3 Jacobians
    from that base end at 384 N (8 from the guess at 208 N); chained through 0.03, 0.045, 0.06, 0.085 and
    0.114 mm at 3 Jacobians each: 123, 98, 67, 40 and 39 N, the truth's own 39 N.

    ``far``: while no value has beaten the model without the effect, one that fits ``far`` x ``sse_off`` or worse
    ends the sweep at once (None: never)."""
    name, dim = ext.extra[i], ext.base.dimension
    points, sse, evals, worse = [], [], 0, 0
    for v in values:
        better = chained and sse and min(sse) < sse_off
        z = np.array(points[int(np.argmin(sse))] if better else z0, dtype=float)
        z[dim + i] = v
        held = ext.holding({name: ext.to_params(z)[name]})
        pol = polish(eid, held, held.from_params(ext.to_params(z)), max_jacobians=jacobians, log=lambda m: None)
        evals += pol.evaluations
        point = ext.from_params(held.to_params(pol.z))
        point[dim + i] = v  # exactly the value held
        e = eid.n_samples / pol.fitness if pol.fitness > 0 else math.inf
        worse = worse + 1 if e >= min([sse_off, *sse]) else 0
        points.append(point)
        sse.append(e)
        if patience is not None and worse >= patience:
            break
        if far is not None and min(sse) >= sse_off and e >= far * sse_off:
            break
    return HeldProfile(points, sse, evals)


def effect_intervals(eid: Engine, ext: ExtendedParametrization, z: np.ndarray, step: float = 1e-4) -> dict:
    """95 % confidence interval of each effect parameter of the extended model fitted at ``z`` (SI
    units), from the identification residual's Jacobian by the block sandwich
    (``tuner.diagnosis.significance``: valid for correlated residuals). Base coordinates at a bound are held
    there. Returns {name: {value, std, low, high, excludes_zero}} plus '_blocks' and
    '_correlation_time_s' (the residual's, which sets the block length: 3 correlation times)."""
    z = np.clip(np.asarray(z, dtype=float), 0.0, 1.0)
    dim = ext.base.dimension
    free = [i for i in range(ext.dimension) if i >= dim or 1e-9 < z[i] < 1 - 1e-9]
    steps = {i: (step if z[i] + step <= 1.0 else -step) for i in free}
    pts = [z] + [z + np.eye(ext.dimension)[i] * steps[i] for i in free]
    res = eid.residuals_batch([ext.to_params(p) for p in pts])
    r0 = res[0]
    out: dict = {}
    if r0 is None or any(r is None for r in res[1:]):
        return {n: {"value": ext.to_params(z)[n], "std": math.inf, "low": -math.inf, "high": math.inf,
                    "excludes_zero": False} for n in ext.extra}
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
