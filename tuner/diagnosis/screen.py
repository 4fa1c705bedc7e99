"""The candidates' screen: which effects can pay for a refit, from one batch of simulations.

A refit of a candidate (``tuner.diagnosis.refit.refit``) costs tens of Jacobians of the extended
model (on the two-chamber form, 38 parameters, a minute or more each on real tests); most candidates
carry no force the residual shows. The screen predicts, for every candidate at once, what its refit
could win on the identification tests, linearised in the base only:

* the effect's force at each point of its profile, ``d(m)`` = simulated force with the effect at
  magnitude ``m`` minus without it [N], for the magnitudes of its line-search grid (the refit's own
  ``grid``: the search range, geometric from its meaningful floor or 2 % of the range). The effect is
  not linearised: a free play, whose force has no gradient at zero gap, is seen at the gaps of the grid;
* the base re-balanced (what its tables can absorb of that force): the residual ``r`` and ``d`` are
  projected off the span of the base Jacobian (``U`` of its SVD, ``tuner.diagnosis.
  extended_parametrization.base_jacobian``), so the predicted identification SSE with the effect at ``m`` and the base
  re-balanced is ``|P(r - d(m))|^2 + |r|^2 - |P r|^2`` (``P`` the projector off the span: the part of
  ``r`` in the span is what the base refit removes with or without the effect);
* the predicted gain is ``|P r|^2 - |P (r - a d(m))|^2`` at the best grid magnitude, the force scaled by
  the best ``a`` in [0, 1] (the magnitudes between zero and the grid point's: exact for a force linear in
  its magnitude, a preload, whose two-sided grid is coarse; to first order for the others), and its
  ``share`` of the current SSE ``|r|^2``. The linear re-balance knows neither the base's bounds nor its tables'
  monotonicity and may credit the base with absorbing what it cannot (a constant force looks like every
  elastic ordinate shifted), so the gain with the base held as it is, ``|r|^2 - |r - d(m)|^2``, counts
  too: the larger of the two.
* the diagnosis screens at the base refitted alike ('none', the reference of every score, with its own
  Jacobian) and at the fitted base the refits start from, and keeps the larger share: on a base far from
  its optimum the two differ (the refit of 'none' may have absorbed an effect into the tables that a
  refit from the fitted base would find as itself).

A candidate is refitted when its share is at least ``SCREEN_SHARE``: a cause is named only on a
held-out MSE reduction of about 7 % (``ACCEPT_SCORE`` plus the penalty of one parameter), so a
candidate predicted to take less than 2 % of the identification SSE cannot be one, with a margin of
3.5 for the linearisation and the difference between identification and held-out tests. Forms beyond
the catalogue are screened on their shape grid (``tuner.diagnosis.forms.screen``, the same
projection). Units SI; forces in N.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from damper_fmu.effect_catalogue import ALL_EFFECTS

from tuner.diagnosis.extended_parametrization import ExtendedParametrization, grid
from tuner.identification.engine import Engine

__all__ = ["SCREEN_SHARE", "ScreenRow", "off_span", "profile_screen"]

#: the least share of the current identification SSE a candidate's refit must be predicted to win
SCREEN_SHARE = 0.02


@dataclass
class ScreenRow:
    """A candidate's screen: its best point and what the refit is predicted to win there."""

    effect: str
    #: the effect's identified parameters at the best point [SI]
    values: dict
    #: the predicted identification SSE gain there with the base re-balanced (linear) [N^2]
    gain_n2: float
    #: gain_n2 as a share of the current model's identification SSE
    share: float
    #: rms of the effect's force there, off the base's span [N] (what the base cannot absorb)
    force_rms_n: float
    #: the identification SSE there with the base as it is (not re-balanced) [N^2]
    sse_n2: float
    #: the profile: (magnitude [SI], predicted share) per grid point, in grid order
    profile: list = field(default_factory=list)

    @property
    def passes(self) -> bool:
        """Worth a refit: predicted to win at least SCREEN_SHARE of the identification SSE."""
        return self.share >= SCREEN_SHARE

    def to_dict(self) -> dict:
        return {"values": self.values, "predicted_gain_n2": self.gain_n2, "predicted_share": self.share,
                "force_rms_n": self.force_rms_n, "refitted": self.passes,
                "profile": [[m, s] for m, s in self.profile]}


def off_span(jac_svd):
    """The projector off the span of the base Jacobian (``(U, s, Vt)`` or None: the identity) as a function
    of a residual-length vector: what remains after a linear re-balance of the base absorbs what it can."""
    if jac_svd is None:
        return lambda v: v
    u, sv, _ = jac_svd
    basis = u[:, sv > 1e-9 * sv[0]]
    return lambda v: v - basis @ (basis.T @ v)


def _scaled_gain(d: np.ndarray, r: np.ndarray) -> tuple[float, float]:
    """(the SSE removed from the residual ``r`` [N^2] by the force ``d`` [N] scaled by a in [0, 1], that a):
    the scale stands for the magnitudes between zero and the grid point's (exact for a force linear in its
    magnitude, a preload; to first order for the others), so a coarse grid does not hide an optimum."""
    dd = float(d @ d)
    if dd <= 0.0:
        return 0.0, 0.0
    a = min(max(float(d @ r) / dd, 0.0), 1.0)
    return a * (2.0 * float(d @ r) - a * dd), a


def profile_screen(eid: Engine, exts: dict[str, ExtendedParametrization], current: dict, jac_svd,
                   grid_points: int) -> dict[str, ScreenRow]:
    """The screen of catalogue effects (one identified parameter each) on top of the model ``current`` (its
    parameter values, every candidate off), in one batch of the identification engine ``eid``.

    exts: {effect: the current model extended by it} (search bounds, meaningful floors); jac_svd: the current
    model's residual Jacobian SVD (``tuner.diagnosis.extended_parametrization.base_jacobian``) or None; grid_points: as the
    refit's line search. Returns {effect: ScreenRow}; an effect none of whose points can be simulated is left
    out, and so are all when the current model cannot be simulated."""
    points, owners = [current], []
    for effect, ext in exts.items():
        (name,) = ALL_EFFECTS[effect].identified
        k = ext.extra.index(name)
        lo, hi = ext.extra_bounds[k]
        for m in grid(lo, hi, grid_points, ext.floors[k]):
            points.append({**current, name: float(m)})
            owners.append((effect, name, float(m)))
    runs = eid.residuals_batch(points)
    r0 = runs[0]
    if r0 is None:
        return {}
    project = off_span(jac_svd)
    r_p = project(r0)
    sse0 = float(r0 @ r0)
    rows: dict[str, ScreenRow] = {}
    for (effect, name, m), r in zip(owners, runs[1:]):
        if r is None:
            continue
        d = r0 - r  # the force the effect adds at m
        # with the base re-balanced (projected) and with the base held; the larger gain counts
        (gain, scale), held = _scaled_gain(project(d), r_p), _scaled_gain(d, r0)
        if held[0] > gain:
            gain, scale = held
        share = gain / sse0 if sse0 > 0 else 0.0
        row = rows.get(effect)
        if row is None or gain > row.gain_n2:
            rows[effect] = ScreenRow(effect, {name: scale * m}, gain, share,
                                     float(np.sqrt(np.mean(project(scale * d) ** 2))), float(r @ r),
                                     row.profile if row is not None else [])
        rows[effect].profile.append((m, share))
    return rows
