"""Parameter sets drawn from a fitted model's covariance: what its uncertainty means elsewhere (the vehicle).

The identification's intervals (``tuner.identification.intervals``) linearise the residual in the local
solver's coordinates u (``Parametrization.local_space()``: table ordinates by their increments outward
from zero, log-scaled parameters by their logarithm, each coordinate spanning its bounds as [0, 1]); the
estimate is Gaussian there, with the covariance ``LocalCovariance.matrix``. A draw (``draw_parameter_sets``):

* the coordinates with a finite variance: u_fit + L z + s_u z_s, z and z_s standard normal, L L^T the
  covariance (from its eigen-decomposition, so a covariance that is only semi-definite is drawn too) and
  s_u the representation shift in u (``LocalCovariance.shift``: what the fit would move by with the
  model's finer representation, an error of known size and unknown sign) as a rank-one term: the draws'
  covariance is Sigma + s_u s_u^T, so each parameter's marginal spread is std^2 + s^2 (in the logarithm
  for a log-scaled one), the square of its interval's half-width over Z95, and the shift moves every
  parameter together, along the one direction the representation moves the fit. A parameters.json
  written before the shift was stored draws from Sigma alone and says so (``ParameterDraws.describe``);
* bounds: a coordinate that leaves [0, 1] is reflected back into it (u -> -u, 2 - u, repeatedly). For a
  coordinate fitted at a bound this is the half-Gaussian on the inside, i.e. the likelihood restricted to
  the bounds; one whose standard deviation spans the range several times tends to uniform over the
  bounds; one well inside them is untouched. Draws are never clipped (clipping piles them up at the
  bound) and never rejected (a rejection rate grows with every coordinate near a bound);
* the coordinates the tests do not see at all (no finite variance, the intervals' 'not determined' with
  no interval): uniform over [0, 1], i.e. anywhere within their bounds (log-uniform for a log-scaled
  parameter), as "any value within the bounds fits as well" says;
* the parameters: ``space.to_params(u)``. Every point of [0, 1]^d is a valid model of the class (the
  improved parametrization's tables are monotone by construction), so every draw can be simulated.

Draws are a function of (seed, model, index) alone: the first n of a larger set are the same draws, so a
run that adds draws keeps the earlier ones. Units: SI throughout (each parameter in its unit of
``damper_fmu.parameters``).
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass, field

import numpy as np

from tuner.identification.intervals import ModelIntervals

__all__ = ["ParameterDraws", "draw_parameter_sets", "reflect_into_unit_interval"]


@dataclass
class ParameterDraws:
    """Parameter sets of one fitted model drawn from its covariance (module docstring).

    model: the model kind; names: the identified parameters (SI, units ``units``); fitted: their fitted
    values; sets: one dict name -> value per draw; uniform: the coordinates drawn uniformly over their
    bounds (no finite variance); reflected: per coordinate with a finite variance, the share of draws in
    which it was reflected at a bound; seed: the master seed; shift: whether the representation shift was
    drawn (False: parameters.json predates it, the statistical covariance alone)."""

    model: str
    names: list
    units: dict
    fitted: dict
    sets: list = field(default_factory=list)
    uniform: list = field(default_factory=list)
    reflected: dict = field(default_factory=dict)
    seed: int = 0
    shift: bool = True

    def matrix(self) -> np.ndarray:
        """The draws as an array (n, len(names)) [SI units of each parameter]."""
        return np.array([[s[n] for n in self.names] for s in self.sets])

    def describe(self) -> str:
        """One sentence on how the draws were made, naming the coordinates at their bounds or drawn uniformly."""
        text = (f"{len(self.sets)} parameter sets of the {self.model} model drawn from the fitted covariance in the "
                "identification's coordinates (Gaussian there; reflected at the bounds), "
                + ("with the representation shift as a rank-one term" if self.shift else
                   "without the representation shift (parameters.json predates it: refit to include it)"))
        often = [n for n, share in self.reflected.items() if share >= 0.05]
        if often:
            text += f"; reflected at a bound in 5 % of the draws or more: {', '.join(often)}"
        if self.uniform:
            text += (f"; not seen by the identification tests, drawn uniformly within their bounds: "
                     f"{', '.join(self.uniform)}")
        return text

    def to_dict(self) -> dict:
        return {"model": self.model, "seed": self.seed, "draws": len(self.sets), "uniform": list(self.uniform),
                "reflected_share": dict(self.reflected), "representation_shift": self.shift, "text": self.describe()}


def reflect_into_unit_interval(u: np.ndarray) -> np.ndarray:
    """``u`` folded into [0, 1] by reflection at 0 and 1 (as often as needed)."""
    r = np.mod(np.asarray(u, dtype=float), 2.0)
    return np.where(r > 1.0, 2.0 - r, r)


def _draw_rng(seed: int, model: str, index: int) -> np.random.Generator:
    """The generator of draw ``index`` of ``model``: a function of the three alone."""
    return np.random.default_rng([int(seed), zlib.crc32(model.encode()), int(index)])


def draw_parameter_sets(model: str, entry: dict, n: int, seed: int = 0) -> ParameterDraws:
    """``n`` parameter sets of ``model`` drawn from its fitted covariance (module docstring). ``entry``: the
    model's object in ``parameters.json`` (``values``, ``intervals``). ValueError naming the model and the fix
    when the entry carries no covariance in the identification's coordinates."""
    if not isinstance(n, int) or n < 1:
        raise ValueError(f"the number of draws must be a positive integer, got {n!r}")
    if not entry.get("intervals"):
        raise ValueError(f"{model}: no parameter intervals in parameters.json "
                         f"({entry.get('intervals_note', 'not computed')}): nothing to draw from; refit the model")
    iv = ModelIntervals.from_dict(model, entry["intervals"])
    if iv.local is None:
        raise ValueError(f"{model}: parameters.json holds no covariance in the identification's coordinates "
                         "('local_covariance', written since the vehicle intervals were added): refit with this "
                         "version to draw parameter sets")
    local = iv.local
    par = local.parametrization(model, entry["values"])
    space = par.local_space()
    if list(space.names) != list(local.coordinates):
        raise ValueError(f"{model}: the stored coordinates {local.coordinates} do not match the model's "
                         f"{list(space.names)}; refit with this version")
    resolved = [local.coordinates.index(c) for c in local.resolved]
    free = [i for i in range(len(local.coordinates)) if i not in resolved]
    w, V = np.linalg.eigh(0.5 * (local.matrix + local.matrix.T)) if resolved else (np.zeros(0), np.zeros((0, 0)))
    L = V * np.sqrt(np.clip(w, 0.0, None))
    shift = np.zeros(len(local.coordinates)) if local.shift is None else np.asarray(local.shift, dtype=float)
    shift[free] = 0.0  # the fit's shift has none there; drawn uniformly anyway
    raw = np.tile(np.asarray(local.u, dtype=float), (n, 1))
    for i in range(n):
        rng = _draw_rng(seed, model, i)
        raw[i, resolved] += L @ rng.standard_normal(len(resolved))
        raw[i, free] = rng.uniform(0.0, 1.0, len(free))
        raw[i] += shift * rng.standard_normal()
    u = reflect_into_unit_interval(raw)
    names = list(par.names)
    sets = [{k: float(v) for k, v in space.to_params(row).items() if k in names} for row in u]
    reflected = {local.coordinates[i]: float(np.mean((raw[:, i] < 0.0) | (raw[:, i] > 1.0))) for i in resolved}
    fitted = {k: float(entry["values"][k]) for k in names}
    return ParameterDraws(model=model, names=names, units={k: par.units.get(k, "") for k in names}, fitted=fitted,
                          sets=sets, uniform=[local.coordinates[i] for i in free], reflected=reflected, seed=seed,
                          shift=local.shift is not None)
