"""The held profiles of a nonsmooth effect's magnitude (a free play, ``Effect.nonsmooth``): the model re-fitted
at each value with the magnitude held (``held_profile``), swept from the refit's start or coarse then fine from a
start that has absorbed nothing (``nonsmooth_profiles``), and with the element in series with it held too
(``series_profiles``). Points in the search coordinates of an ``ExtendedParametrization``; SSE in N^2.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from damper_fmu.effect_catalogue import effect_of

from tuner.diagnosis.extended_parametrization import ExtendedParametrization
from tuner.identification.engine import Engine
from tuner.identification.polish import RESOLUTION_FRACTION, polish

__all__ = ["HeldProfile", "HeldSweep", "sweep_gain", "SeriesProfile", "SeriesTargets", "held_profile",
           "nonsmooth_profiles", "series_profiles", "PROBE_JACOBIANS",
           "HELD_PROFILE_JACOBIANS", "COARSE_HELD_JACOBIANS", "HELD_PATIENCE", "FAR_WORSE", "SERIES_HELD_JACOBIANS"]

#: Jacobians of the joint polish that must win ``tuner.diagnosis.refit.PROFILE_SHARE`` when the profile did not, for
#: the rest to follow (``refit``); the short joint polish from a released point (``_probe``)
PROBE_JACOBIANS = 2
#: Jacobians of the re-fit at each grid value of a nonsmooth effect's magnitude (``held_profile``; measured on a
#: 0.52 mm free play with soft contact, where the re-balance on the base's Jacobian picked 0.15 mm: at the grid
#: values 0.15, 0.28, 0.55, 1.05 mm the RMSE after 2 Jacobians 604, 568, 404, 2139 N; after 3: 589, 546, 221,
#: 1477 N, as after 4 (588, 543, 210, 1456 N))
HELD_PROFILE_JACOBIANS = 3
#: ... and at each value of the coarse pass from a start that has absorbed nothing (``_grid_profile``)
COARSE_HELD_JACOBIANS = 1
#: values in a row that fit no better than the best so far (at first: the model without the effect; better: by the
#: data's resolution, ``sweep_gain``) after which the
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


@dataclass(frozen=True)
class HeldSweep:
    """How ``held_profile`` sweeps its values: ``jacobians`` of the local refinement at each value; it stops once
    ``patience`` values in a row (None: never) fit no better than the best so far, where better is an RMSE lower by
    more than ``gain_n`` [N] (``sweep_gain``: the data's resolution); ``chained``: each value re-fitted from the
    best value's point so far; ``far``: while no value has beaten the model without the effect, one that fits
    ``far`` x its SSE or worse ends it (None: never)."""

    patience: int | None = HELD_PATIENCE
    jacobians: int = HELD_PROFILE_JACOBIANS
    chained: bool = False
    far: float | None = None
    gain_n: float = 0.0


def sweep_gain(standard_error_n: float) -> float:
    """The fall of the identification RMSE [N] a swept held value must show over the best so far to count as
    progress: ``RESOLUTION_FRACTION`` of the RMSE's standard error ``standard_error_n`` [N], the change below which
    a refinement has converged to the data's resolution (``tuner.identification.polish``). On the real MR damper at
    0.75 A (two-chamber base, one standard error 2.6 N) the chained sweep of a free play crept through ten values
    at 37.48-37.50 N, 0.01 N apart, 44 s to a 0.33 N dip the data cannot show, and its best started the joint
    polish of a refit whose held-out tests could then not be simulated."""
    return RESOLUTION_FRACTION * standard_error_n


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


@dataclass(frozen=True)
class SeriesTargets:
    """What ``series_profiles`` measures against: ``sse_off`` [N^2] on the identification tests (the model without
    the effect: what the released and swept profiles must beat), ``enough`` [N^2] (a profile that reaches it ends
    the ladder; 0: never), and where the coarse passes with the element held run: ``coarse``, an engine of the
    search's windows of the tests (``tuner.identification.search_window``; None: the tests themselves), on which a
    coarse pass must fit below ``coarse_sse_off`` [N^2] for its held value to be released; ``sweep_gain_n`` [N]: the
    fall of the RMSE that counts as progress in the sweeps after a release (``sweep_gain``)."""

    sse_off: float
    enough: float = 0.0
    coarse: Engine | None = None
    coarse_sse_off: float = math.inf
    sweep_gain_n: float = 0.0


@dataclass(frozen=True)
class SeriesProfile:
    """``series_profiles``' result: the ``points`` (search coordinates) and their identification ``sse`` [N^2] on
    every sample (the released and swept profiles, and the coarse passes when they ran on the tests themselves),
    the simulations of all, the coarse passes' best SSE [N^2] on their own engine (``coarse_best``) and whether a
    held value was ``released``."""

    points: list
    sse: list
    evaluations: int
    coarse_best: float
    released: bool


def nonsmooth_profiles(eid: Engine, ext: ExtendedParametrization, starts: list, pts: list, sse: list,
                       profile=None, sse_off: float = math.inf, gain_n: float = 0.0) -> HeldProfile:
    """The ``held_profile`` of every nonsmooth effect's magnitude among the extra parameters profiled (``profile``:
    their indices, default all) of the refit whose profile points ``pts`` (search coordinates) have the SSE
    ``sse`` [N^2], from each of ``starts`` (search coordinates): the refit's start (``_swept_profile``) and
    possibly one that has absorbed nothing (``_grid_profile``). ``sse_off`` [N^2]: the refit's start, the model
    without the effect; ``gain_n`` [N]: the fall of the RMSE that counts as progress (``sweep_gain``).

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
        sweep = HeldSweep(chained=True, far=FAR_WORSE if len(starts) > 1 else None, gain_n=gain_n)
        out = out.joined(_swept_profile(eid, ext, starts[0], i, values, best, sse_off, sweep))
        for z0 in starts[1:]:
            out = out.joined(_grid_profile(eid, ext, z0, i, values, sse_off, gain_n))
    return out


def _swept_profile(eid: Engine, ext: ExtendedParametrization, z0: np.ndarray, i: int, values: list, best: float,
                   sse_off: float, sweep: HeldSweep) -> HeldProfile:
    """The held profile from the refit's start ``z0``: the profile's grid ``values`` (search coordinates) from the
    value below ``best`` (the grid profile's best point) up (the base absorbs a nonsmooth effect as a smaller
    one; the value below brackets the best) with the geometric mean of each two neighbours between them (the
    profile's minimum is narrow: a 0.40 mm gap between the grid values 0.28 and 0.54 mm was missed), swept
    upward until ``HELD_PATIENCE`` values in a row fit no better than the best so far by ``sweep.gain_n``, the model
    without the effect (SSE ``sse_off`` [N^2]) counting as the first; each value re-fitted from the best value's
    point so far (``sweep.chained``: a continuation in the magnitude); then ``_with_vertex``. ``sweep.far`` (set when
    a start that has absorbed nothing follows): a value ``FAR_WORSE`` x ``sse_off`` or worse before any beat it ends
    the sweep."""
    k = max(0, max((j for j, v in enumerate(values) if v <= best), default=0) - 1)
    swept = []
    for lo, hi in zip(values[k:], values[k + 1:]):
        swept += [lo, math.sqrt(lo * hi)]
    held = held_profile(eid, ext, z0, i, swept + values[-1:], sse_off, sweep=sweep)
    return _with_vertex(eid, ext, i, held, sse_off, sweep.gain_n)


def series_profiles(eid: Engine, ext: ExtendedParametrization, z0: np.ndarray, i: int, values: list,
                    held: list[dict], targets: SeriesTargets) -> SeriesProfile:
    """The held profile of the nonsmooth magnitude ``i`` of ``ext`` (a free play) from ``z0`` (search coordinates)
    with the element in series with it held at each of ``held`` (``{stiffness: N/m, damping: N s/m}``,
    ``damper_fmu.parameters.SERIES_ELEMENT``): at every value of ``values`` (search coordinates, ascending) the
    rest re-fitted with ``SERIES_HELD_JACOBIANS`` (stopping ``HELD_PATIENCE`` values past its best), then the
    series element released at the best value (``HELD_PROFILE_JACOBIANS``) and the chained profile swept from
    there (``_swept_profile``; ``targets.sse_off`` [N^2]: the model without the effect); the held values after one
    whose profile reaches ``targets.enough`` [N^2] are not tried; with it given, a short joint polish from each
    release (``_probe``) that reaches it ends the profile there. A held value whose coarse profile fits no better
    than the model without the effect anywhere shows no gap the element hid: it is not released nor swept (on a real
    MR damper, whose fit wants a soft mount, the release and sweeps of two held values took three of a diagnosis's
    four minutes to end 0.2 N above the base). The coarse passes run on ``targets.coarse`` when given (the search's
    windows: they only say which held value to release, and a periodic rig test repeats what its window holds),
    judged against ``targets.coarse_sse_off``; the releases and sweeps on every sample. Points in ``ext``'s
    coordinates.

    Why: a base fitted without the gap may have made its mount a dashpot, which carries a gap's lost motion as
    well as a gap can, and a refit with the gap from there keeps it. A two-chamber damper with a 0.114 mm gap in
    stiff mounts (7.4e8 N/m, 8e4 N s/m) was fitted at 126 N rms with the mount at 3.2e5 N/m and 1.6e7 N s/m;
    every profile from that base or from the data-driven guess (the mount at the preset's 3e7 N/m) stayed at
    125-242 N. With the mount held at 3e8 N/m and 5.1e4 N s/m, two Jacobians per gap value: 121, 87, 161 and
    576 N at 0.03, 0.06, 0.12 and 0.24 mm; released at 0.06 mm, 74 N with the mount at 1.8e8 N/m; at 3e9 N/m the
    best was 0.12 mm (77 N, released 63 N); at the preset's 3e7 N/m, 408 N and more."""
    sse_off, enough = targets.sse_off, targets.enough
    coarse_eng, coarse_off = (targets.coarse, targets.coarse_sse_off) if targets.coarse is not None else (eid, sse_off)
    out, coarse_best, any_released = HeldProfile([], [], 0), math.inf, False
    for values_held in held:
        space = ext.holding_base(values_held)
        coarse = held_profile(coarse_eng, space, space.from_params(ext.to_params(z0)), i, values,
                              sweep=HeldSweep(jacobians=SERIES_HELD_JACOBIANS))
        points = [ext.from_params(space.to_params(z)) for z in coarse.points]
        on_tests = targets.coarse is None  # its SSE comparable with the releases'
        out = out.joined(HeldProfile(points if on_tests else [], coarse.sse if on_tests else [], coarse.evaluations))
        b = int(np.argmin(coarse.sse))
        coarse_best = min(coarse_best, coarse.sse[b])
        if not (coarse.sse[b] < coarse_off):  # no gap fits better than none with the element held: nothing to release
            continue
        any_released = True
        released = held_profile(eid, ext, points[b], i, [values[b]])
        out = out.joined(released)
        if enough > 0.0 and math.isfinite(released.sse[0]):
            out = out.joined(_probe(eid, ext, released.points[0]))
            if min(out.sse) <= enough:
                break
        out = out.joined(_swept_profile(eid, ext, released.points[0], i, values, values[b], sse_off,
                                        HeldSweep(chained=True, gain_n=targets.sweep_gain_n)))
        if min(out.sse) <= enough:
            break
    return SeriesProfile(out.points, out.sse, out.evaluations, coarse_best, any_released)


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
                  sse_off: float, gain_n: float = 0.0) -> HeldProfile:
    """The held profile from a start that has absorbed nothing (``z0``, the data-driven guess): coarse at every
    value of the profile's grid ``values`` (search coordinates; ``COARSE_HELD_JACOBIANS`` each, no early stop),
    then fine (``HELD_PROFILE_JACOBIANS``) at the coarse best and the geometric means with its neighbours, then
    ``_with_vertex`` through the fine values (``gain_n`` [N]: ``sweep_gain``) (coarse and fine values are not compared: unequal effort). No sweep
    from the grid profile's best, as from the refit's start: from such a start the profile can be flat over the
    small values and fall only near the magnitude the data hold (a 0.52 mm gap in a two-chamber damper: 818-838 N
    rms at 0.04-0.15 mm, against 819 N without it; 577, 419 and 492 N at 0.28, 0.39 and 0.54 mm), where a sweep
    that stops after a few values that fit no better never arrives. The coarse pass is a fifth of the cost and
    points the same way (there, after one Jacobian: 587 N at 0.54 mm, 625 at 0.28, 832-1065 below, 2116 at 1.04;
    after two: 170, 559, 813-929, 1982 N)."""
    coarse = held_profile(eid, ext, z0, i, values, sweep=HeldSweep(patience=None, jacobians=COARSE_HELD_JACOBIANS))
    b = int(np.argmin(coarse.sse))
    fine = [math.sqrt(values[b - 1] * values[b])] if b > 0 else []
    fine += [values[b]] + ([math.sqrt(values[b] * values[b + 1])] if b + 1 < len(values) else [])
    held = held_profile(eid, ext, z0, i, fine, sweep=HeldSweep(patience=None))
    return coarse.joined(_with_vertex(eid, ext, i, held, sse_off, gain_n))


def _with_vertex(eid: Engine, ext: ExtendedParametrization, i: int, held: "HeldProfile",
                 sse_off: float, gain_n: float = 0.0) -> "HeldProfile":
    """``held`` and, when one of its values beat the model without the effect (SSE ``sse_off`` [N^2]) by more than
    ``gain_n`` [N] of RMSE (``sweep_gain``), the held value at the vertex of the parabola through its best value and
    their neighbours (``_vertex_value``), re-fitted from the best value's point (closer to the vertex than the
    profile's start)."""
    beats = _lower(min(held.sse, default=math.inf), sse_off, eid.n_samples, gain_n)
    vertex = _vertex_value(held, ext.base.dimension + i) if beats else None
    if vertex is None:
        return held
    start = held.points[int(np.argmin(held.sse))]
    return held.joined(held_profile(eid, ext, start, i, [vertex]))


def _lower(sse: float, than: float, n_samples: int, gain_n: float) -> bool:
    """Whether the SSE ``sse`` [N^2] on ``n_samples`` is an RMSE lower than that of ``than`` by more than ``gain_n``
    [N] (``than`` infinite: any finite ``sse``)."""
    if not math.isfinite(than):
        return math.isfinite(sse)
    return math.sqrt(sse / n_samples) < math.sqrt(than / n_samples) - gain_n


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
                 sse_off: float = math.inf, *, sweep: HeldSweep = HeldSweep()) -> HeldProfile:
    """The profile of the extra parameter ``i`` of ``ext`` (a nonsmooth effect's magnitude) at ``values`` (its
    search coordinate, swept in their order; ``sweep``: ``HeldSweep``): ``z0`` with each value re-fitted with it held
    (``jacobians`` Jacobians of the local refinement over every other coordinate), so that what the
    base absorbed of the effect (a soft elastic table in place of a dead band) is given back at each value;
    the sweep stops once ``patience`` values in a row (None: never) fit no better than the best so far (by more than
    ``gain_n`` [N] of RMSE), where the model without the effect (identification SSE ``sse_off`` [N^2]) is the first
    best: a start from which holding the
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
    patience, jacobians, chained, far = sweep.patience, sweep.jacobians, sweep.chained, sweep.far
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
        worse = 0 if _lower(e, min([sse_off, *sse]), eid.n_samples, sweep.gain_n) else worse + 1
        points.append(point)
        sse.append(e)
        if patience is not None and worse >= patience:
            break
        if far is not None and min(sse) >= sse_off and e >= far * sse_off:
            break
    return HeldProfile(points, sse, evals)
