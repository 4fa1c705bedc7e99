"""How well the identification tests determine each identified parameter: 95 % intervals and flags.

At the fitted point of a model (``parameter_intervals``):

* the Jacobian of the identification residual [N] with respect to the coordinates u of the local
  solver (``Parametrization.local_space()``: table ordinates by their increments, log-scaled
  parameters by their logarithm, each coordinate spanning its bounds), by forward differences of
  ``STEP`` (one batch of d + 1 simulations through the identification engine, as the refinement's);
* the covariance of u by the block sandwich (``tuner.metrics.block_sandwich``, as the diagnosis's
  effect intervals): blocks of ``BLOCK_CORRELATION_TIMES`` residual correlation times, so that the
  correlated residual (the fit band's low-pass, model-form error) is not counted as independent
  samples; with fewer than ``MIN_BLOCKS_PER_PARAMETER`` blocks per parameter (or ``MIN_BLOCKS``) the
  sandwich's middle is too poorly estimated, and the textbook covariance scaled by the correlation time is
  used (and said);
* the covariance of the physical parameters by the delta method, Cov_theta = G Cov_u G^T with
  G = d theta / d u (the mapping is linear in the table ordinates: exact there);
* the representation shift (``representation_difference``): the identification simulates the model with
  fixed 1 ms internal steps on a stroke that went through the fit band's resampler, whose passband gain
  departs from 1 by up to 1.6e-4 at 2-8 Hz; the measured force was made from the unfiltered stroke with
  no step error. On known truth this misfit (about 1e-4 of the force) biased k_B and c_B by about 0.9
  and M_P by 0.6 standard errors on multisine strokes, and the masses by 7 under 12-20 Hz strokes (docs/
  identification.md). The fit is simulated once more with internal steps ``REFERENCE_STEP_DIVISOR`` times
  finer and the stroke's resampling undone to first order (``resampling_compensated``); the force
  difference d [N], projected as a Gauss-Newton step, is the shift s each parameter would take with
  the better representation (the fitted value lies about -s from the truth); kept in u as well
  (``LocalCovariance.shift``), where the draws carried to the vehicle add it as a rank-one term
  (``tuner.identification.parameter_draws``) and the test design combines it with a candidate's
  (``tuner.identification.rig_test_design``);
* 95 % intervals value +- Z95 sqrt(std^2 + s^2) (the shift as an error of known size and unknown
  sign: at least 95 % coverage for any shift); for log-scaled parameters (``Parameter.log_scale``)
  symmetric in the logarithm, so they stay positive; correlations from Cov_theta (statistical only).

Directions of u the force does not depend on at all (singular values of the Jacobian below
``NULL_RCOND`` of the largest; e.g. a table segment the tests never enter) have no finite variance: the
parameters they move are "not determined" with no interval (null in the JSON, the reason said), and
the others' covariance is computed without them.

Flags (``ParameterInterval``): ``determined`` (the interval lies inside the bounds and spans at most
``DETERMINED_WIDTH`` of the bound range, measured in decades for log-scaled parameters), ``at a bound``
(the value within ``BOUND_FRACTION`` of the range from a bound, or a narrow interval that reaches past
one: the bound, not the tests, limits it), ``not determined`` (wider, or no finite variance), ``tied to
NAME`` (|correlation| > ``TIE_CORRELATION``), ``extrapolated`` (a table point beyond what the tests make
the element see: a damping abscissa beyond the element's peak rate on that side, an elastic abscissa
beyond its peak elongation, ``reached_ranges``; the peak over the counted samples of the fitted model's
simulation of the identification tests).

The interval is local (linearised at the fit): for a parameter the force hardly depends on, the
linearisation says "wide", which is what the flag needs; its exact width there would need a profile
likelihood (refits with the parameter held), which this module does not do.

Units: SI throughout (each parameter in its unit of ``damper_fmu.parameters``); residuals in N.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from damper_fmu.fmu import ensure_fmu
from damper_fmu.models import ConvergenceError
from damper_fmu.parameters import MODEL_PARAMETERS
from tuner.identification.damper_scale import REFERENCE_SCALE, DamperScale
from tuner.identification.engine import (IDENTIFICATION_STEP, IDENTIFICATION_TOLERANCE, Signals,
                                         simulate_signals)
from tuner.identification.parametrization import Parametrization
from tuner.identification.runner import FmuRunner, SimulationError
from tuner.metrics import Z95, block_sandwich, correlation_time

__all__ = ["ParameterInterval", "ReachedRange", "LocalCovariance", "ModelIntervals", "parameter_intervals",
           "residual_jacobian",
           "reached_ranges", "classify", "STEP", "DETERMINED_WIDTH", "BOUND_FRACTION", "TIE_CORRELATION",
           "NULL_RCOND", "BLOCK_CORRELATION_TIMES", "MIN_BLOCKS_PER_PARAMETER", "MIN_BLOCKS", "CONFIDENCE",
           "REFERENCE_STEP_DIVISOR", "representation_difference", "resampling_compensated", "gauss_newton_step",
           "free_coordinates"]

#: forward-difference step in the local coordinates (each spans its parameter's bounds): the diagnosis's
#: effect intervals' step; the polish's fine step (1e-5) sees the two-chamber model's rough objective
STEP = 1e-4
#: "determined": the 95 % interval spans at most this share of the bound range (decades for log-scaled)
DETERMINED_WIDTH = 0.1
#: "at a bound": the value within this share of the bound range from a bound (the report's bound flag)
BOUND_FRACTION = 0.01
#: "tied to": |correlation| above this
TIE_CORRELATION = 0.95
#: singular values of the Jacobian below this share of the largest: directions the tests do not see
#: (the block sandwich's pseudo-inverse drops the same ones: rcond 1e-12 on J^T J)
NULL_RCOND = 1e-6
#: residual blocks of this many correlation times (``tuner.diagnosis.refit.effect_intervals``'s choice)
BLOCK_CORRELATION_TIMES = 3.0
#: fewer blocks per resolved parameter than this, or fewer than MIN_BLOCKS: the textbook covariance x
#: correlation time instead (the sandwich's middle is a sum of one outer product per block)
MIN_BLOCKS_PER_PARAMETER = 2
MIN_BLOCKS = 10
CONFIDENCE = 0.95
#: the representation shift's reference run: internal steps this many times finer than the identification's
REFERENCE_STEP_DIVISOR = 10

_TABLE_ABSCISSA = {"Fc_": "Fc_v", "Fk_": "Fk_x"}


@dataclass(frozen=True)
class ReachedRange:
    """What the identification tests make one table's element see (fitted model, counted samples):
    ``table`` 'Fc' (damping) or 'Fk' (elastic); ``low``/``high``: the most negative and most positive
    value of ``quantity`` [``unit``: m/s for Fc, m for Fk]."""

    table: str
    quantity: str
    unit: str
    low: float
    high: float

    def covers(self, abscissa: float) -> bool:
        """Whether the tests reach the table point at ``abscissa`` [unit] (on its side of zero)."""
        return self.low <= abscissa <= self.high

    def to_dict(self) -> dict:
        return {"table": self.table, "quantity": self.quantity, "unit": self.unit, "low": self.low,
                "high": self.high}


@dataclass
class LocalCovariance:
    """The fitted covariance in the local solver's coordinates u (``Parametrization.local_space()``), where
    the linearisation is made and the estimate is Gaussian (module docstring): what draws of parameter sets
    need (``tuner.identification.parameter_draws``).

    coordinates: the coordinate names, in the space's order (each named by the parameter it sets: a table
    ordinate's coordinate is its increment from the neighbour nearer zero); u: the fitted point (each
    coordinate in [0, 1] across its bounds); resolved: the coordinates with a finite variance, in
    ``coordinates``' order; matrix: their covariance [coordinate units^2]; scheme, force_limit_n [N],
    spring_reference_n_per_m [N/m], scale (the damper's, ``DamperScale``: the other bounds): the Parametrization
    the coordinates belong to (with the fitted model's fixed values it is rebuilt by ``parametrization``); shift: the representation shift in u
    [coordinate units], one entry per coordinate of ``coordinates`` (0 where held at a bound or without
    finite variance; the parameters' ``systematic`` is G shift, G = d theta / d u), None when it was not
    computed or the file predates it. The draws add it as a rank-one term shift shift^T to ``matrix``, and
    the test design combines it with a candidate's (``tuner.identification.rig_test_design``)."""

    coordinates: list
    u: np.ndarray
    resolved: list
    matrix: np.ndarray
    scheme: str
    force_limit_n: float
    spring_reference_n_per_m: float
    shift: np.ndarray | None = None
    scale: DamperScale = REFERENCE_SCALE

    def parametrization(self, model: str, values: dict) -> Parametrization:
        """The Parametrization of ``model`` these coordinates belong to, its fixed values (the abscissae)
        taken from the fitted ``values`` (SI)."""
        tunable = {p.name for p in MODEL_PARAMETERS[model] if p.tunable}
        return Parametrization(model, self.scheme, force_limit=self.force_limit_n,
                               spring_reference=self.spring_reference_n_per_m, scale=self.scale,
                               fixed={k: v for k, v in values.items() if k not in tunable})

    def to_dict(self) -> dict:
        return {"coordinates": list(self.coordinates), "u": np.asarray(self.u, dtype=float).tolist(),
                "resolved": list(self.resolved), "matrix": np.asarray(self.matrix, dtype=float).tolist(),
                "scheme": self.scheme, "force_limit_n": self.force_limit_n,
                "spring_reference_n_per_m": self.spring_reference_n_per_m,
                "shift": None if self.shift is None else np.asarray(self.shift, dtype=float).tolist(),
                "scale": self.scale.to_dict()}

    @classmethod
    def from_dict(cls, d: dict) -> "LocalCovariance":
        """From ``to_dict``'s form; a file written before the shift was stored has none (shift None), one before the
        damper's scale was stored the reference's (its bounds were the reference damper's)."""
        k = len(d["resolved"])
        shift = d.get("shift")
        return cls(coordinates=list(d["coordinates"]), u=np.asarray(d["u"], dtype=float), resolved=list(d["resolved"]),
                   matrix=np.asarray(d["matrix"], dtype=float).reshape(k, k), scheme=d["scheme"],
                   force_limit_n=float(d["force_limit_n"]),
                   spring_reference_n_per_m=float(d["spring_reference_n_per_m"]),
                   shift=None if shift is None else np.asarray(shift, dtype=float).reshape(len(d["coordinates"])),
                   scale=DamperScale.from_dict(d.get("scale")))


@dataclass(frozen=True)
class ParameterInterval:
    """The 95 % interval and flags of one identified parameter (module docstring), SI units.

    value: identified value [unit]; std: its standard error [unit] (delta method), None when the tests
    do not move the force along it; low/high: the 95 % interval [unit] clipped to the bounds (None with
    std); beyond_bounds: the unclipped interval reaches past a bound; bounds: (lower, upper) of the
    identification [unit]; width_fraction: the clipped interval's share of the bound range (decades for
    log-scaled; 1.0 when not finite); status: 'determined', 'at a bound' or 'not determined';
    at_bound: the value lies at a bound (also with status 'not determined'); tied_to: ((name,
    correlation), ...) with |correlation| > TIE_CORRELATION; extrapolated: a table point beyond what the
    tests reach; abscissa: the table point's abscissa [m/s or m] (None for other parameters); reason: one
    sentence on why; offset: the Gauss-Newton step [unit] from the fit towards the local optimum that the
    Jacobian predicts (coordinates at a bound held; None without finite variance): well under ``std`` when
    the refinement ended at the optimum, and the interval is centred on the fit, not on the optimum;
    systematic: the representation shift [unit] (module docstring; None when not computed), in the
    interval's half-width Z95 sqrt(std^2 + systematic^2)."""

    name: str
    unit: str
    value: float
    std: float | None
    low: float | None
    high: float | None
    beyond_bounds: bool
    bounds: tuple[float, float]
    log_scale: bool
    width_fraction: float
    status: str
    at_bound: bool
    tied_to: tuple = ()
    extrapolated: bool = False
    abscissa: float | None = None
    reason: str = ""
    offset: float | None = None
    systematic: float | None = None

    @property
    def flags(self) -> list[str]:
        """The flags as words: the status, 'at a bound' when not the status already, 'tied to NAME', 'extrapolated'."""
        out = [self.status]
        if self.at_bound and self.status != "at a bound":
            out.append("at a bound")
        out += [f"tied to {n}" for n, _ in self.tied_to]
        return out + (["extrapolated"] if self.extrapolated else [])

    @property
    def determined(self) -> bool:
        return self.status == "determined"

    def range_text(self) -> str:
        """One line for a person or an FMU's description: the determined range and the flags (SI)."""
        u = f" {self.unit}" if self.unit not in ("", "1") else ""
        if self.low is None:
            text = (f"NOT determined by the identification tests (any value in [{self.bounds[0]:.4g}, "
                    f"{self.bounds[1]:.4g}]{u} fits as well)")
        else:
            rng = f"95 % range [{self.low:.4g}, {self.high:.4g}]{u}"
            text = {"determined": f"determined by the identification tests: {rng}",
                    "at a bound": f"held by its identification bound, not by the tests: {rng}",
                    "not determined": f"NOT determined by the identification tests: {rng}"}[self.status]
        extra = [f"tied to {n} (correlation {c:+.2f})" for n, c in self.tied_to]
        if self.extrapolated:
            extra.append("extrapolated beyond what the tests reach")
        return "; ".join([text, *extra])

    def to_dict(self) -> dict:
        return {"value": self.value, "unit": self.unit, "std": self.std, "low": self.low, "high": self.high,
                "beyond_bounds": self.beyond_bounds, "bounds": list(self.bounds), "log_scale": self.log_scale,
                "width_fraction": self.width_fraction, "status": self.status, "at_bound": self.at_bound,
                "tied_to": [{"name": n, "correlation": c} for n, c in self.tied_to],
                "extrapolated": self.extrapolated, "abscissa": self.abscissa, "flags": self.flags,
                "reason": self.reason, "offset": self.offset, "systematic": self.systematic,
                "text": self.range_text()}

    @classmethod
    def from_dict(cls, name: str, d: dict) -> "ParameterInterval":
        return cls(name=name, unit=d["unit"], value=d["value"], std=d["std"], low=d["low"], high=d["high"],
                   beyond_bounds=d["beyond_bounds"], bounds=tuple(d["bounds"]), log_scale=d["log_scale"],
                   width_fraction=d["width_fraction"], status=d["status"], at_bound=d["at_bound"],
                   tied_to=tuple((t["name"], t["correlation"]) for t in d["tied_to"]),
                   extrapolated=d["extrapolated"], abscissa=d["abscissa"], reason=d["reason"],
                   offset=d.get("offset"), systematic=d.get("systematic"))


@dataclass
class ModelIntervals:
    """The intervals of every identified parameter of one fitted model (module docstring).

    parameters: one ``ParameterInterval`` per identified parameter, in the Parametrization's order;
    covariance: of the parameters with a finite variance (``covariance_names``), SI units (unit_i
    unit_j); method: 'block sandwich' or 'textbook x correlation time' (too few blocks); blocks: the
    residual blocks; block_length_s, correlation_time_s [s]: of the residual at the fit rate; samples:
    counted residual samples; residual_rms_n [N]; reached: the ``ReachedRange`` of each table; local: the
    same covariance in the local solver's coordinates (``LocalCovariance``; None in results written before
    it was stored); representation_rms_n [N]: rms of the force difference behind the representation
    shifts (None: not computed, e.g. the reference run failed)."""

    model: str
    parameters: list
    covariance_names: list
    covariance: np.ndarray
    method: str
    blocks: int
    block_length_s: float
    correlation_time_s: float
    samples: int
    residual_rms_n: float
    reached: list = field(default_factory=list)
    local: LocalCovariance | None = None
    representation_rms_n: float | None = None

    def get(self, name: str) -> ParameterInterval:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(f"{self.model}: no identified parameter {name!r}")

    def names_with(self, flag: str) -> list[str]:
        """Names of the parameters whose ``flags`` hold ``flag`` ('tied' matches every 'tied to ...')."""
        return [p.name for p in self.parameters if any(f == flag or f.startswith(flag + " ") for f in p.flags)]

    def summary_text(self) -> str:
        """One line: how many are determined, and the names of the others."""
        n = len(self.parameters)
        parts = [f"{len(self.names_with('determined'))} of {n} parameters determined by the identification tests "
                 f"(95 %, {self.method}, {self.blocks} blocks of {self.block_length_s:.3g} s)"]
        for flag in ("not determined", "at a bound", "extrapolated", "tied"):
            names = self.names_with(flag)
            if names:
                parts.append(f"{flag}: {', '.join(names)}")
        return "; ".join(parts)

    def descriptions(self) -> dict[str, str]:
        """name -> ``ParameterInterval.range_text`` (for the tuned FMU's parameter descriptions)."""
        return {p.name: p.range_text() for p in self.parameters}

    def to_dict(self) -> dict:
        """The parameters.json form (strict JSON: no non-finite number is written; None says 'none')."""
        return {"confidence": CONFIDENCE, "method": self.method, "blocks": self.blocks,
                "block_length_s": self.block_length_s, "correlation_time_s": self.correlation_time_s,
                "samples": self.samples, "residual_rms_n": self.residual_rms_n,
                "representation_rms_n": self.representation_rms_n,
                "determined_width": DETERMINED_WIDTH, "tie_correlation": TIE_CORRELATION,
                "reached": {r.table: r.to_dict() for r in self.reached},
                "order": [p.name for p in self.parameters],  # the JSON object's keys may be sorted
                "parameters": {p.name: p.to_dict() for p in self.parameters},
                "covariance": {"names": list(self.covariance_names), "matrix": np.asarray(self.covariance).tolist()},
                "local_covariance": None if self.local is None else self.local.to_dict(),
                "summary": self.summary_text()}

    @classmethod
    def from_dict(cls, model: str, d: dict) -> "ModelIntervals":
        order = d.get("order") or list(d["parameters"])
        return cls(model=model, parameters=[ParameterInterval.from_dict(n, d["parameters"][n]) for n in order],
                   covariance_names=list(d["covariance"]["names"]),
                   covariance=np.asarray(d["covariance"]["matrix"], dtype=float).reshape(
                       len(d["covariance"]["names"]), len(d["covariance"]["names"])),
                   method=d["method"], blocks=d["blocks"], block_length_s=d["block_length_s"],
                   correlation_time_s=d["correlation_time_s"], samples=d["samples"],
                   residual_rms_n=d["residual_rms_n"],
                   reached=[ReachedRange(**r) for r in d.get("reached", {}).values()],
                   local=LocalCovariance.from_dict(d["local_covariance"]) if d.get("local_covariance") else None,
                   representation_rms_n=d.get("representation_rms_n"))


# -- the statistics ----------------------------------------------------------------------------------

def residual_jacobian(engine, space, u: np.ndarray, names: list[str], step: float = STEP):
    """(residual r [N], J [N per coordinate], G = d theta / d u [unit per coordinate], failed coordinates)
    at u of ``space`` (forward differences; a step that would leave [0, 1] goes the other way). theta: the
    parameters ``names`` (the Parametrization's order)."""
    h = np.where(u + step <= 1.0, step, -step)
    points = [u] + [u + np.eye(u.size)[i] * h[i] for i in range(u.size)]
    params = [space.to_params(p) for p in points]
    res = engine.residuals_batch(params)
    if res[0] is None:
        raise ValueError(f"the fitted point cannot be simulated ({engine.last_failure or 'no reason given'})")
    theta0 = np.array([params[0][n] for n in names])
    failed = [i for i, r in enumerate(res[1:]) if r is None]
    J = np.column_stack([(r - res[0]) / hi if r is not None else np.zeros_like(res[0])
                         for r, hi in zip(res[1:], h)])
    G = np.column_stack([(np.array([p[n] for n in names]) - theta0) / hi for p, hi in zip(params[1:], h)])
    return res[0], J, G, failed


def _unresolved(J: np.ndarray, start: set) -> set:
    """Coordinates the residual does not depend on, alone or in a combination: ``start``, the columns of J
    that are zero, and every coordinate carrying more than 1 % of a direction whose singular value is below
    NULL_RCOND of the largest (columns scaled to unit norm, as ``_covariance_u`` inverts them)."""
    norms = np.linalg.norm(J, axis=0)
    out = set(start) | {i for i in range(J.shape[1]) if not norms[i] > 1e-12 * max(norms.max(), 1e-300)}
    while True:
        keep = [i for i in range(J.shape[1]) if i not in out]
        if not keep:
            return out
        _, s, vt = np.linalg.svd(J[:, keep] / norms[keep], full_matrices=False)
        null = s < NULL_RCOND * s[0]
        if not null.any():
            return out
        weight = np.sum(vt[null] ** 2, axis=0)
        out |= {keep[k] for k in np.nonzero(weight > 0.01)[0]} or {keep[int(np.argmax(weight))]}


def _covariance_u(J: np.ndarray, r: np.ndarray, lengths: list[int], keep: list[int]):
    """(covariance of the coordinates ``keep`` [coordinate units^2], method, blocks, block length and
    correlation time [samples]) from the Jacobian columns ``keep`` and the residual r [N]. The columns are
    scaled to unit norm for the pseudo-inverses (a log-scaled stiffness spanning seven decades moves the
    force a million times more than a mass over its range) and the scaling is undone."""
    tau = correlation_time(r)
    block = max(1, math.ceil(BLOCK_CORRELATION_TIMES * tau))
    if not keep:
        return np.zeros((0, 0)), "block sandwich", 0, block, tau
    norms = np.linalg.norm(J[:, keep], axis=0)
    Jn = J[:, keep] / norms
    unscale = np.outer(1.0 / norms, 1.0 / norms)
    cov, blocks = block_sandwich(Jn, r, lengths, block)
    if blocks >= max(MIN_BLOCKS, MIN_BLOCKS_PER_PARAMETER * len(keep)):
        return cov * unscale, "block sandwich", blocks, block, tau
    # too few blocks for the sandwich's middle: the residual as noise of variance s^2 whose correlation
    # time tau makes every sample worth 1 / tau of an independent one
    s2 = float(r @ r) / max(r.size - len(keep), 1)
    cov = s2 * tau * np.linalg.pinv(Jn.T @ Jn, rcond=1e-12, hermitian=True)
    return cov * unscale, "textbook x correlation time", blocks, block, tau


def classify(name: str, unit: str, value: float, std: float | None, bounds: tuple[float, float],
             log_scale: bool, why_none: str | None = None, systematic: float | None = None) -> ParameterInterval:
    """The interval and status of one parameter from its value and standard error [unit] (module
    docstring); tied_to, extrapolated and abscissa are filled by the caller. why_none: the reason when std
    is None (default: the tests do not move the force along it). systematic: the representation shift
    [unit], combined with std in the half-width Z95 sqrt(std^2 + systematic^2) (None: std alone)."""
    lo_b, hi_b = bounds
    position = _position(value, lo_b, hi_b, log_scale)
    at_bound = position <= BOUND_FRACTION or position >= 1.0 - BOUND_FRACTION
    if std is None or not math.isfinite(std):
        return ParameterInterval(name, unit, value, None, None, None, True, bounds, log_scale, 1.0,
                                 "not determined", at_bound, reason=why_none or (
                                     "the identification tests do not move the force along this parameter (no "
                                     "finite variance): any value within the bounds fits as well"))
    spread = math.hypot(std, systematic) if systematic is not None and math.isfinite(systematic) else std
    if log_scale and value > 0:
        # the half-width in natural-log units; beyond 700 (e^700 ~ 1e304) every end is past the bounds already
        k = min(Z95 * spread / value, 700.0)
        low, high = value * math.exp(-k), value * math.exp(k)
    else:
        low, high = value - Z95 * spread, value + Z95 * spread
    beyond = low < lo_b or high > hi_b
    low_c, high_c = max(low, lo_b), min(high, hi_b)
    width = _position(high_c, lo_b, hi_b, log_scale) - _position(low_c, lo_b, hi_b, log_scale)
    if width > DETERMINED_WIDTH:
        status, reason = "not determined", (f"the 95 % interval spans {100 * width:.3g} % of the bound range "
                                            f"(determined: at most {100 * DETERMINED_WIDTH:g} %)")
    elif at_bound or beyond:
        status, reason = "at a bound", ("the value lies at a bound" if at_bound else
                                        "the 95 % interval reaches past a bound") + ": the bound limits it"
    else:
        status, reason = "determined", (f"the 95 % interval lies inside the bounds and spans {100 * width:.2g} % "
                                        f"of their range")
    return ParameterInterval(name, unit, value, std, low_c, high_c, beyond, bounds, log_scale, width, status,
                             at_bound, reason=reason, systematic=systematic)


def _position(value: float, lo: float, hi: float, log_scale: bool) -> float:
    """Where ``value`` lies between the bounds (0 lower, 1 upper; in decades when log-scaled)."""
    if log_scale and lo > 0 and value > 0:
        return (math.log(value) - math.log(lo)) / (math.log(hi) - math.log(lo))
    return (value - lo) / (hi - lo) if hi > lo else 0.5


# -- the whole model ----------------------------------------------------------------------------------

def parameter_intervals(engine, par: Parametrization, params: dict, *, reached: list | None = None,
                        step: float = STEP) -> ModelIntervals:
    """The ``ModelIntervals`` of the model of ``par`` fitted at ``params`` (SI) on the tests of
    ``engine`` (a ``tuner.identification.engine.Engine`` of that model: its identification residual).
    reached: the ``ReachedRange`` of each table (``reached_ranges``), for the 'extrapolated' flag.
    ValueError when the fitted point cannot be simulated."""
    space = par.local_space()
    names = list(par.names)
    u = space.from_params(params)
    params = space.to_params(u)  # the point the Jacobian is taken at (params itself, within rounding)
    r, J, G, failed = residual_jacobian(engine, space, u, names, step)
    lengths = [int(s.mask.sum()) for s in engine.tests]
    dropped = _unresolved(J, set(failed))
    keep = [i for i in range(J.shape[1]) if i not in dropped]
    cov_u, method, blocks, block, tau = _covariance_u(J, r, lengths, keep)
    offset = G @ gauss_newton_step(J, -r, u, keep)
    d = representation_difference(engine, params)
    shift_u = None if d is None else gauss_newton_step(J, d, u, keep)
    shift = None if shift_u is None else G @ shift_u
    # a parameter moved by a coordinate without finite variance has none either
    scale = np.maximum(np.abs(G).max(axis=1, keepdims=True), 1e-300)

    def moved_by(cols, i):
        return bool(cols) and bool(np.any(np.abs(G[i, sorted(cols)]) > 1e-9 * scale[i, 0]))

    infinite = [moved_by(dropped, i) for i in range(len(names))]
    finite = [i for i in range(len(names)) if not infinite[i]]
    Gk = G[np.ix_(finite, keep)]
    cov = Gk @ cov_u @ Gk.T
    rate = (len(engine.tests[0].time) - 1) / (engine.tests[0].time[-1] - engine.tests[0].time[0])
    spec = {p.name: p for p in MODEL_PARAMETERS[par.model]}
    std = {names[i]: math.sqrt(max(cov[k, k], 0.0)) for k, i in enumerate(finite)}
    out = []
    for i, n in enumerate(names):
        why = ("the model could not be simulated next to the fit along this parameter: no interval"
               if moved_by(failed, i) else None)
        sys_i = None if shift is None or infinite[i] else float(shift[i])
        iv = classify(n, par.units.get(n, ""), float(params[n]), std.get(n), tuple(par.bounds[n]),
                      bool(spec[n].log_scale), why, sys_i)
        iv = _with_context(iv, n, finite, names, cov, params, reached or [])
        out.append(_with_offset(iv, None if infinite[i] else float(offset[i])))
    local = LocalCovariance(coordinates=list(space.names), u=u, resolved=[space.names[i] for i in keep],
                            matrix=cov_u, scheme=par.scheme, force_limit_n=par.force_limit,
                            spring_reference_n_per_m=par.spring_reference, shift=shift_u, scale=par.scale)
    return ModelIntervals(model=par.model, parameters=out, covariance_names=[names[i] for i in finite],
                          covariance=cov, method=method, blocks=blocks, block_length_s=block / rate,
                          correlation_time_s=tau / rate, samples=int(r.size),
                          residual_rms_n=math.sqrt(float(r @ r) / r.size), reached=list(reached or []),
                          local=local, representation_rms_n=None if d is None else math.sqrt(float(d @ d) / d.size))


def free_coordinates(u: np.ndarray, keep) -> list[int]:
    """The coordinates of ``keep`` not at a bound of [0, 1] (within 1e-9): those a Gauss-Newton step moves
    (the refinement holds the others at their bound)."""
    return [i for i in keep if 1e-9 < u[i] < 1.0 - 1e-9]


def gauss_newton_step(J: np.ndarray, rhs: np.ndarray, u: np.ndarray, keep: list[int]) -> np.ndarray:
    """The Gauss-Newton step du [coordinate units, one per coordinate of u] that J du = rhs [N] asks for, on
    the ``free_coordinates`` of ``keep`` (the others 0: held at a bound, as the refinement holds them, or
    without finite variance): with rhs = -r the step from u towards the optimum the Jacobian predicts (the
    offset), with rhs = the representation difference the representation shift. The parameters' step
    [their units] is G du."""
    du = np.zeros(u.size)
    free = free_coordinates(u, keep)
    if not free:
        return du
    norms = np.linalg.norm(J[:, free], axis=0)
    du[free] = np.linalg.lstsq(J[:, free] / norms, rhs, rcond=NULL_RCOND)[0] / norms
    return du


def resampling_compensated(s: Signals) -> Signals:
    """``s`` with its stroke [m] and stroke velocity [m/s] passed once more through the fit band's
    resampler and the difference added back (x + (x - H x), to first order the stroke before the
    resampler: a passband gain 1 + e becomes 1 - e^2), on the samples the resampler covers. The
    identification's resampler (``Signals.low_pass``: the same band edges and attenuation in Hz as the
    data's, ``tuner.data.preprocess.Resampler``) stands for the data's. Unchanged when not oversampled."""
    if s.oversample == 1:
        return s
    _, x_fine, v_fine, _ = s.fine
    k0, n = s.band_limited_span()
    x, v = np.array(s.stroke, dtype=float), np.array(s.stroke_velocity, dtype=float)
    x[k0:k0 + n] += x[k0:k0 + n] - s.low_pass.apply(x_fine)
    v[k0:k0 + n] += v[k0:k0 + n] - s.low_pass.apply(v_fine)
    return replace(s, stroke=x, stroke_velocity=v)


def representation_difference(engine, params: dict) -> np.ndarray | None:
    """Force [N] over the counted samples of ``engine``'s tests: the model at ``params`` (SI) with internal
    steps ``REFERENCE_STEP_DIVISOR`` times finer on the ``resampling_compensated`` stroke, minus the
    identification's own simulation of it (as the residual is measured minus simulated, J du = d moves
    the parameters to what the better representation would fit). None when that run fails."""
    try:
        out = []
        for s in engine.tests:
            used = simulate_signals(engine.model, params, s, engine=engine.engine,
                                    fmu_path=getattr(engine, "fmu_path", None))
            ref = simulate_signals(engine.model, params, resampling_compensated(s), engine=engine.engine,
                                   fmu_path=getattr(engine, "fmu_path", None),
                                   max_internal_step=IDENTIFICATION_STEP / REFERENCE_STEP_DIVISOR)
            out.append((ref - used)[s.mask])
    except (SimulationError, ConvergenceError, ValueError, FloatingPointError):
        return None
    d = np.concatenate(out)
    return d if np.all(np.isfinite(d)) else None


def _with_offset(iv: ParameterInterval, offset: float | None) -> ParameterInterval:
    """``iv`` with its Gauss-Newton offset, said in the reason when it exceeds one standard error."""
    reason = iv.reason
    if offset is not None and iv.std and abs(offset) > iv.std:
        reason += (f"; the refinement ended {abs(offset) / iv.std:.2g} standard errors from the local optimum "
                   f"along it (the interval is centred on the fitted value)")
    return replace(iv, offset=offset, reason=reason)


def _with_context(iv: ParameterInterval, name: str, finite: list[int], names: list[str], cov: np.ndarray,
                  params: dict, reached: list) -> ParameterInterval:
    """``iv`` with its ties (correlations beyond TIE_CORRELATION) and, for a table point, its abscissa and
    whether it lies beyond what the tests reach."""
    tied = []
    k = next((j for j, i in enumerate(finite) if names[i] == name), None)
    if k is not None and cov[k, k] > 0:
        for j, i in enumerate(finite):
            if j != k and cov[j, j] > 0:
                c = float(cov[k, j] / math.sqrt(cov[k, k] * cov[j, j]))
                if abs(c) > TIE_CORRELATION:
                    tied.append((names[i], c))
    abscissa, extrapolated = None, False
    for prefix, axis in _TABLE_ABSCISSA.items():
        if name.startswith(prefix) and name[len(prefix):].isdigit() and name.replace(prefix, axis) in params:
            abscissa = float(params[name.replace(prefix, axis)])
            reach = next((r for r in reached if r.table == prefix[:-1]), None)
            extrapolated = reach is not None and not reach.covers(abscissa)
    reason = iv.reason
    if extrapolated:
        reason += f"; its abscissa {abscissa:.4g} lies beyond what the identification tests reach"
    return replace(iv, tied_to=tuple(sorted(tied, key=lambda t: -abs(t[1]))), extrapolated=extrapolated,
                   abscissa=abscissa, reason=reason)


def reached_ranges(model: str, params: dict, signals: list[Signals], fmu_path=None) -> list[ReachedRange]:
    """The ``ReachedRange`` of each table of ``model`` fitted at ``params`` (SI) on the identification
    ``signals``: its element's outputs simulated through the model's FMU on the identification grid
    (fixed steps of ``IDENTIFICATION_STEP``), over the counted samples. Lumped: damping element rate
    x2' - x3' (Fc), elastic element elongation x3 - x4 (Fk); two-chamber: the piston-valve rate (Fc
    rebound side) and the foot-valve rate over 1 - area_ratio (compression side, as the model maps its
    table); table Maxwell: the stroke velocity; Maxwell: no table."""
    outputs = {"lumped": ("damping_rate", "elastic_elongation"),
               "twochamber": ("piston_valve_rate", "foot_valve_rate")}.get(model)
    if model == "maxwell_table":
        v = np.concatenate([s.stroke_velocity[s.mask] for s in signals])
        return [ReachedRange("Fc", "stroke velocity", "m/s", float(v.min()), float(v.max()))]
    if outputs is None:
        return []
    runner = FmuRunner(fmu_path or ensure_fmu(model), max_internal_step=IDENTIFICATION_STEP,
                       tolerance=IDENTIFICATION_TOLERANCE)
    try:
        runs = [runner.run(s.time, s.stroke, s.stroke_velocity, params, outputs=outputs)[s.mask] for s in signals]
    finally:
        runner.close()
    a, b = (np.concatenate([run[:, k] for run in runs]) for k in (0, 1))
    if model == "lumped":
        return [ReachedRange("Fc", "damping element rate x2' - x3'", "m/s", float(a.min()), float(a.max())),
                ReachedRange("Fk", "elastic element elongation x3 - x4", "m", float(b.min()), float(b.max()))]
    ratio = 1.0 - float(params["area_ratio"])
    return [ReachedRange("Fc", "piston-valve rate (rebound), foot-valve rate / (1 - area_ratio) (compression)",
                         "m/s", -float(max(b.max(), 0.0)) / ratio, float(max(a.max(), 0.0)))]

