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
  log space, and the tables are monotone by construction. Fc,O: on each side, going outward from
  zero, F_k = F_{k-1} + z_k (F_max - F_{k-1}) (every monotone table within the limit has one
  representation). Fk,O: each piece's stiffness s_k is searched log-uniformly within 0.2-3 times
  the reference spring, and F_k = F_{k-1} + s_k (x_k - x_{k-1}) outward from zero.

The force limit F_max [N] and the reference spring k_ref [N/m] come from the caller (the tuner
derives F_max from the measured forces; the paper used 3e4 N and 1.5e7 N/m for its yaw damper).
"""
from __future__ import annotations

import math

import numpy as np

from damper_fmu.parameters import MODEL_PARAMETERS, check_values, defaults

__all__ = ["Parametrization", "SCHEMES"]

SCHEMES = ("paper", "improved")
_K_LOW, _K_HIGH = 0.2, 3.0


class Parametrization:
    """Scaled design vector <-> parameters of ``model`` ('lumped', 'maxwell', 'maxwell_table').

    fixed: parameter values kept constant (abscissae and anything not identified), SI units.
    """

    def __init__(self, model: str, scheme: str = "improved", *, force_limit: float = 3.0e4,
                 spring_reference: float = 1.5e7, fixed: dict | None = None):
        if scheme not in SCHEMES:
            raise ValueError(f"unknown parametrization '{scheme}', expected one of {SCHEMES}")
        if model not in MODEL_PARAMETERS:
            raise ValueError(f"unknown model '{model}'")
        if not (force_limit > 0 and spring_reference > 0):
            raise ValueError("force_limit [N] and spring_reference [N/m] must be positive")
        self.model, self.scheme = model, scheme
        self.force_limit, self.spring_reference = float(force_limit), float(spring_reference)
        self.fixed = check_values(model, fixed or {})
        specs = [p for p in MODEL_PARAMETERS[model] if p.tunable]
        self.names = [p.name for p in specs]
        self.units = {p.name: p.unit for p in MODEL_PARAMETERS[model]}
        self.bounds = {}
        for p in specs:
            lo, hi = p.low, p.high
            if p.name.startswith("Fc_"):
                lo, hi = (0.0, self.force_limit) if hi > 0 else (-self.force_limit, 0.0)
            elif p.name.startswith("Fk_"):
                x = self.fixed[p.name.replace("Fk_", "Fk_x")]
                a, b = _K_LOW * self.spring_reference * x, _K_HIGH * self.spring_reference * x
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
            for side in self._sides("Fc", "v"):
                f = 0.0
                for _, n in side:
                    f = f + zi[n] * (self.force_limit - f)
                    out[n] = f if self.bounds[n][1] > 0 else -f
            for side in self._sides("Fk", "x"):
                f, x0 = 0.0, 0.0
                lo, hi = math.log(_K_LOW * self.spring_reference), math.log(_K_HIGH * self.spring_reference)
                for x, n in side:
                    f += math.exp(lo + zi[n] * (hi - lo)) * (x - x0)
                    out[n], x0 = f, x
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
            for side in self._sides("Fc", "v"):
                f = 0.0
                for _, n in side:
                    target = min(max(abs(p[n]), f), self.force_limit)
                    room = self.force_limit - f
                    z[n] = (target - f) / room if room > 0 else 0.0
                    f = f + z[n] * room
            lo, hi = math.log(_K_LOW * self.spring_reference), math.log(_K_HIGH * self.spring_reference)
            for side in self._sides("Fk", "x"):
                f, x0 = 0.0, 0.0
                for x, n in side:
                    s = (p[n] - f) / (x - x0)
                    s = min(max(s, math.exp(lo)), math.exp(hi))
                    z[n] = (math.log(s) - lo) / (hi - lo)
                    f += s * (x - x0)
                    x0 = x
        return np.clip(np.array([z[n] for n in self.names]), 0.0, 1.0)

    def describe(self) -> str:
        if self.scheme == "paper":
            return ("paper: every parameter scaled linearly between its bounds "
                    f"(Fc,O limit {self.force_limit:.3g} N, Fk,O around {self.spring_reference:.3g} N/m)")
        return ("improved: log-scaled stiffness/damping, monotone Fc,O (outward fractions of the "
                f"remaining headroom to {self.force_limit:.3g} N) and monotone Fk,O (piece stiffness "
                f"log-uniform in {_K_LOW:g}-{_K_HIGH:g} x {self.spring_reference:.3g} N/m)")


def preset(model: str) -> dict[str, float]:
    """The reference preset of ``model`` (paper Table 2 for the lumped model)."""
    return defaults(model)
