"""Design variables: map scaled vectors z in [0, 1]^d to model parameters (SI) and back.

Two schemes:

* ``paper``: every tunable parameter is scaled linearly between its bounds (paper section 2.3).
  Bounds: masses 1-20 kg, k_B 1e2-1e9 N/m, c_B 1e2-1e7 N s/m, Fc,O ordinates of the sign of their
  abscissa up to the force limit, Fk,O ordinates within 0.2-3 times a reference linear spring.
  Weak points: k_B and c_B span seven decades linearly, so 99.99 % of the scaled range sits above
  1e5 and small values are unreachable in practice; independent ordinates allow non-monotonic
  tables (a dashpot whose force falls with speed, an elastic element that softens to negative
  stiffness), which are unphysical and make the model's implicit solve ill-posed.
* ``improved`` (default): the same bounds, but parameters flagged ``log_scale`` are searched in
  log space, and the tables are monotone by construction, parametrised by the slope of each
  piece, going outward from zero on each side: F_k = F_{k-1} + s_k (x_k - x_{k-1}).
  Fc,O: damping slopes s_k log-uniform in [1e-4, 1] x F_max / |v_1| (v_1: the abscissa nearest
  to zero; the upper end reaches the limit within the first piece), ordinates capped at F_max.
  (The floor was 1e-3 until 2026-11-24: a blow-off plateau flatter than that, 0.08 % of the top
  slope on a random damper of the class, was out of reach and cost the truth 10 N of RMSE.)
  Fk,O: stiffnesses s_k log-uniform within 0.2-3 times the reference spring.
  Random tables are then diverse shapes (blow-off knees anywhere) rather than tables that hit the
  limit within two pieces, which is what independent fractions of the headroom produce.

``LocalSpace`` maps the same design space for the local solver (``tuner.identification.polish``):
table ordinates by their increments (linear), the rest as above. The force is nearly linear in
the ordinates, and far from linear in log-slopes, so Gauss-Newton steps go much further there.

The force limit F_max [N], the reference spring k_ref [N/m] and the damper's scale (``DamperScale``: the
other bounds and the fixed constants, ``tuner.identification.damper_scale``) come from the caller (the tuner
derives them from the measured forces, strokes and velocities; the paper used 3e4 N and 1.5e7 N/m for its yaw
damper, and the bounds of ``damper_fmu.parameters``, the default scale ``REFERENCE_SCALE``).
"""
from __future__ import annotations

import copy
import math

import numpy as np

from damper_fmu.parameters import MODEL_PARAMETERS, check_values

from tuner.identification.damper_scale import REFERENCE_SCALE, DamperScale, scaled_bounds, scaled_preset, widened

__all__ = ["Parametrization", "LocalSpace", "SCHEMES"]

SCHEMES = ("paper", "improved")
_K_LOW, _K_HIGH = 0.2, 3.0


class Parametrization:
    """Scaled design vector <-> parameters of ``model`` (a kind of ``damper_fmu.parameters.MODEL_KINDS``).

    fixed: parameter values kept constant (abscissae and anything not identified), SI units; scale: the damper's
    (``DamperScale``): the bounds of the parameters that are no table ordinate and the Fk,O stiffnesses are the
    reference's mapped to it and widened to hold the reference's, the fixed constants the reference's mapped to it
    (``damper_scale.scaled_bounds``, ``scaled_preset``); ``preset``: the model's preset mapped to it with
    ``fixed`` (the search's start; ``fixed`` holds it too, completed as every parameter set).
    """

    def __init__(self, model: str, scheme: str = "improved", *, force_limit: float = 3.0e4,
                 spring_reference: float = 1.5e7, fixed: dict | None = None, scale: DamperScale = REFERENCE_SCALE):
        if scheme not in SCHEMES:
            raise ValueError(f"unknown parametrization '{scheme}', expected one of {SCHEMES}")
        if model not in MODEL_PARAMETERS:
            raise ValueError(f"unknown model '{model}'")
        if not (force_limit > 0 and spring_reference > 0):
            raise ValueError("force_limit [N] and spring_reference [N/m] must be positive")
        self.model, self.scheme = model, scheme
        self.force_limit, self.spring_reference = float(force_limit), float(spring_reference)
        self.scale = scale
        self.fixed = check_values(model, {**scaled_preset(model, scale), **(fixed or {})})
        self.preset = dict(self.fixed)
        specs = [p for p in MODEL_PARAMETERS[model] if p.tunable]
        self.names = [p.name for p in specs]
        self.units = {p.name: p.unit for p in MODEL_PARAMETERS[model]}
        self.bounds = {}
        scaled = scaled_bounds(model, scale)
        for p in specs:
            lo, hi = scaled.get(p.name, (p.low, p.high))
            if p.name.startswith("Fc_"):
                lo, hi = (0.0, self.force_limit) if hi > 0 else (-self.force_limit, 0.0)
            elif p.name.startswith("Fk_"):
                x = self.fixed[p.name.replace("Fk_", "Fk_x")]
                k_low, k_high = self._fk_stiffness()
                a, b = k_low * x, k_high * x
                lo, hi = min(a, b), max(a, b)
            self.bounds[p.name] = (lo, hi)
        self.log_scale = {p.name: p.log_scale for p in specs}
        self.dimension = len(self.names)

    # -- table layout helpers -----------------------------------------------------------------
    def _sides(self, prefix: str, axis: str):
        """Ordinate names of each side of a table, ordered outward from zero, with abscissae."""
        names = [n for n in self.names if n.startswith(prefix + "_")]
        xs = [self.fixed[n.replace(prefix + "_", f"{prefix}_{axis}")] for n in names]
        neg = sorted([(x, n) for x, n in zip(xs, names) if x < 0], reverse=True)
        pos = sorted([(x, n) for x, n in zip(xs, names) if x > 0])
        return neg, pos

    # -- mapping ------------------------------------------------------------------------------
    def to_params(self, z) -> dict[str, float]:
        """Parameters (SI, including the fixed ones) of the scaled vector z in [0, 1]^d."""
        z = np.clip(np.asarray(z, dtype=float), 0.0, 1.0)
        if z.shape != (self.dimension,):
            raise ValueError(f"scaled vector of shape {z.shape}, expected ({self.dimension},)")
        zi = dict(zip(self.names, z.tolist()))
        out = dict(self.fixed)
        for n in self.names:
            lo, hi = self.bounds[n]
            if self.scheme == "improved" and (n.startswith("Fc_") or n.startswith("Fk_")):
                continue
            if self.scheme == "improved" and self.log_scale[n]:
                out[n] = math.exp(math.log(lo) + zi[n] * (math.log(hi) - math.log(lo)))
            else:
                out[n] = lo + zi[n] * (hi - lo)
        if self.scheme == "improved":
            for prefix, axis, (lo, hi), cap in (("Fc", "v", self._fc_slopes(), self.force_limit),
                                                ("Fk", "x", self._fk_slopes(), math.inf)):
                for side in self._sides(prefix, axis):
                    f, x0 = 0.0, 0.0
                    for x, n in side:
                        f = min(f + math.exp(lo + zi[n] * (hi - lo)) * abs(x - x0), cap)
                        out[n], x0 = math.copysign(f, x), x
        return out

    def from_params(self, params: dict) -> np.ndarray:
        """Scaled vector of ``params`` (clipped into the design space), e.g. to seed a population."""
        p = dict(self.fixed)
        p.update(params)
        z = {}
        for n in self.names:
            lo, hi = self.bounds[n]
            if self.scheme == "improved" and (n.startswith("Fc_") or n.startswith("Fk_")):
                continue
            if self.scheme == "improved" and self.log_scale[n]:
                v = min(max(p[n], lo), hi)
                z[n] = (math.log(v) - math.log(lo)) / (math.log(hi) - math.log(lo))
            else:
                z[n] = (p[n] - lo) / (hi - lo)
        if self.scheme == "improved":
            for prefix, axis, (lo, hi), cap in (("Fc", "v", self._fc_slopes(), self.force_limit),
                                                ("Fk", "x", self._fk_slopes(), math.inf)):
                for side in self._sides(prefix, axis):
                    f, x0 = 0.0, 0.0
                    for x, n in side:
                        slope = (min(abs(p[n]), cap) - f) / abs(x - x0)
                        slope = min(max(slope, math.exp(lo)), math.exp(hi))
                        z[n] = (math.log(slope) - lo) / (hi - lo)
                        f, x0 = min(f + slope * abs(x - x0), cap), x
        return np.clip(np.array([z[n] for n in self.names]), 0.0, 1.0)

    def holding(self, values: dict) -> "Parametrization":
        """The same space with the scalar parameters of ``values`` (SI; not table ordinates) held at them: no
        longer coordinates, moved to ``fixed`` (a refit with a series stiffness held at a chosen decade)."""
        tables = [n for n in values if n.startswith(("Fc_", "Fk_"))]
        unknown = [n for n in values if n not in self.names]
        if tables or unknown:
            raise ValueError(f"holding: {', '.join(tables + unknown)} cannot be held (table ordinates or not "
                             f"coordinates of the {self.model} space)")
        held = copy.copy(self)
        held.fixed = {**self.fixed, **{n: float(v) for n, v in values.items()}}
        held.names = [n for n in self.names if n not in values]
        held.bounds = {n: b for n, b in self.bounds.items() if n not in values}
        held.log_scale = {n: s for n, s in self.log_scale.items() if n not in values}
        held.dimension = len(held.names)
        return held

    def local_space(self):
        """Coordinates for the local solver: ``LocalSpace`` of the 'improved' scheme; the 'paper' scheme's own."""
        return LocalSpace(self) if self.scheme == "improved" else self

    def _fc_slopes(self) -> tuple[float, float]:
        """log bounds of the Fc,O piece slopes [N s/m] (improved scheme)."""
        v1 = min(abs(self.fixed[n.replace("Fc_", "Fc_v")]) for n in self.names if n.startswith("Fc_")) \
            if any(n.startswith("Fc_") for n in self.names) else 1.0
        top = self.force_limit / v1
        return math.log(1e-4 * top), math.log(top)

    def _fk_stiffness(self) -> tuple[float, float]:
        """Bounds [N/m] of the Fk,O piece stiffnesses: 0.2-3 x the reference spring, widened to the reference
        damper's (the spring divided by the scale's stiffness factor, ``damper_scale.widened``)."""
        f = self.scale.factor("N/m")
        return widened(_K_LOW * self.spring_reference / f, _K_HIGH * self.spring_reference / f, f)

    def _fk_slopes(self) -> tuple[float, float]:
        """log bounds of the Fk,O piece stiffnesses [N/m] (improved scheme)."""
        return tuple(math.log(k) for k in self._fk_stiffness())

    def describe(self) -> str:
        if self.scheme == "paper":
            return ("paper: every parameter scaled linearly between its bounds "
                    f"(Fc,O limit {self.force_limit:.3g} N, Fk,O around {self.spring_reference:.3g} N/m); "
                    + self.scale.describe())
        lo, hi = self._fc_slopes() if any(n.startswith("Fc_") for n in self.names) else (0.0, 0.0)
        return ("improved: log-scaled stiffness/damping; monotone tables parametrised by piece slopes: "
                f"Fc,O slopes log-uniform in {math.exp(lo):.3g}-{math.exp(hi):.3g} N s/m, capped at "
                f"{self.force_limit:.3g} N; Fk,O stiffnesses log-uniform in "
                + "-".join(f"{k:.3g}" for k in self._fk_stiffness()) + " N/m; " + self.scale.describe())



class LocalSpace:
    """The design space of an ``improved`` Parametrization in coordinates u in [0, 1]^d for a local solver.

    Table ordinates (Fc_, Fk_): the increment F_k - F_(k-1) outward from zero on each side, linear
    between the Parametrization's slope bounds times the piece's width, the cumulative force capped
    as there; log-scaled parameters: their logarithm; the others: linear between their bounds. Every
    point maps into the Parametrization's space, so ``par.from_params(space.to_params(u))`` is exact.
    """

    def __init__(self, par: Parametrization):
        if par.scheme != "improved":
            raise ValueError("LocalSpace needs the 'improved' parametrization (monotone tables)")
        self.par = par
        self._items = []  # (name, kind, lo, hi, previous ordinate or None, sign of the side, cap)
        table = set()
        for prefix, axis, (llo, lhi), cap in (("Fc", "v", par._fc_slopes(), par.force_limit),
                                              ("Fk", "x", par._fk_slopes(), math.inf)):
            for side in par._sides(prefix, axis):
                x0, prev = 0.0, None
                for x, n in side:
                    dx = abs(x - x0)
                    self._items.append((n, "increment", math.exp(llo) * dx, math.exp(lhi) * dx, prev,
                                        math.copysign(1.0, x), cap))
                    table.add(n)
                    x0, prev = x, n
        for n in par.names:
            if n in table:
                continue
            lo, hi = par.bounds[n]
            if par.log_scale[n]:
                self._items.append((n, "log", math.log(lo), math.log(hi), None, 1.0, math.inf))
            else:
                self._items.append((n, "linear", lo, hi, None, 1.0, math.inf))
        self.names = [it[0] for it in self._items]
        self.dimension = len(self._items)

    def to_params(self, u) -> dict[str, float]:
        """Parameters (SI, with the fixed ones) of u (clipped into [0, 1]^d)."""
        u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
        out = dict(self.par.fixed)
        for (n, kind, lo, hi, prev, sign, cap), ui in zip(self._items, u.tolist()):
            v = lo + ui * (hi - lo)
            if kind == "increment":
                out[n] = sign * min((abs(out[prev]) if prev else 0.0) + v, cap)
            else:
                out[n] = math.exp(v) if kind == "log" else v
        return out

    def from_params(self, params: dict) -> np.ndarray:
        """u of ``params`` (completed with the fixed values; clipped into [0, 1]^d)."""
        p = {**self.par.fixed, **params}
        u = []
        for n, kind, lo, hi, prev, sign, cap in self._items:
            if kind == "increment":
                v = min(abs(p[n]), cap) - (min(abs(p[prev]), cap) if prev else 0.0)
            else:
                v = math.log(p[n]) if kind == "log" else p[n]
            u.append((v - lo) / (hi - lo))
        return np.clip(np.array(u), 0.0, 1.0)
