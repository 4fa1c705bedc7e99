"""The base design vector extended by effect parameters (``ExtendedParametrization``: linear within their search
bounds, ``damper_fmu.effect_catalogue.search_bounds``: each effect's rule), the line search's grid of an effect
parameter (``grid``) and the SVD of the residual's Jacobian that re-balances the base (``base_jacobian``). Units:
SI; residuals in N.
"""
from __future__ import annotations

import copy

import numpy as np

from damper_fmu.effect_catalogue import ALL_EFFECTS, EFFECT_PARAMETERS, effect_of, search_bounds

from tuner.diagnosis.effect_sizes import REFERENCE, DamperSize, meaningful_floor
from tuner.identification.engine import Engine
from tuner.identification.parametrization import Parametrization

__all__ = ["ExtendedParametrization", "grid", "base_jacobian"]

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
