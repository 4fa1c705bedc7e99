"""The restart check: a fit is called converged only when restarts from elsewhere end no lower.

A refinement that met its rule has found a minimum of the basin it started in, not the fit's minimum. On a
real MR damper the two-chamber fit ended at 18.2 N with its series stiffness k_M on its lower bound (1e5 N/m),
"converged to the data's resolution", while the same model with k_M held at 3e8 N/m (the middle of its
decades) and then released ended at 14.3 N: a basin the Firefly swarm, drawn to its seeded start, never
visited. Which decade a log-scaled element sits in decides the basin (the lumped fit's restart ladder,
``tuner.identification.fit.RESTART_LADDER``, says the same of k_B and c_B), and a coordinate on a bound is
where the local solver cannot leave.

So the check restarts the refinement from (``restart_starts``):

* the best point with each scalar coordinate that sits on a bound held at the middle of its search range
  (the geometric middle of a log-scaled one), refined with it held, then released and refined again: held,
  the other coordinates settle around the new decade instead of pulling it straight back. Not a coordinate on a
  lower bound of zero (the entrained air, the gas spring): there the element is absent, a value the model can
  take exactly, not a limit of the search that may cut the true value off (the Firefly's swarm spans the range).
  On the MR currents the air fraction held at 25 % and released took 14-21 s of the check and ended 0.4-1.8 N
  higher each time;
* the series element's stiffness (``damper_fmu.parameters.SERIES_ELEMENT``: the lumped silent blocks, the
  two-chamber mount) on a bound is held not at the middle but at the two stiffer decades of ``series_decades``
  (the data-driven guess's stiffness one and two decades up), the values the diagnosis's free-play ladder holds
  first (``tuner.diagnosis.search.nonsmooth.series_ladder``): one rule for the element, in the fit and the
  diagnosis. On an MR current held back from development the mount held at the middle (1e8 N/m) came back to
  14.80 N, while the diagnosis's ladder, holding it at 3e8 and 3e9 N/m, found 14.16 N (issue 74);
* the brightest firefly of the last generation that lies elsewhere (scaled distance above ``DISTINCT``).

A restart that ends lower by more than one standard error of the RMSE (``tuner.metrics.rmse_standard_error``:
a difference the data can show) replaces the fit's point and the check runs again from there (at most
``ROUNDS`` times); the fit is converged only when a round finds nothing lower by that much. A released restart
stops once its Gauss-Newton step, twice running and settled, predicts no end that low (``polish``'s ``beat``: it
could not replace the point; the log says 'cannot beat'). The record
(``RestartCheck.to_dict``) goes into ``history_<model>.json`` as ``restart_check``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from tuner.identification.parametrization import Parametrization
from tuner.identification.polish import PolishResult, polish
from tuner.metrics import rmse_of_fitness, rmse_standard_error

__all__ = ["RestartCheck", "restart_check", "restart_starts", "series_decades", "SeriesHold", "DISTINCT", "ROUNDS",
           "AT_BOUND", "TYPICAL_RESTARTS", "SERIES_DECADES", "SOFTEST_SERIES"]

#: a firefly this far (Euclidean, scaled coordinates in [0, 1]) from the best lies in another region
DISTINCT = 0.25
#: rounds of the check at most (a round that finds a lower point moves the fit there and checks again)
ROUNDS = 2
#: a scaled coordinate within this of 0 or 1 is on its bound
AT_BOUND = 1e-6
#: refinements a check typically runs, for the progress display's forecast: one coordinate on a bound (held, then
#: released: two) and the firefly elsewhere (measured on the real MR damper: 1-3 coordinates on a bound)
TYPICAL_RESTARTS = 3


#: the softest series stiffness held, as a multiple of the damper's peak force over its stroke range (a series element
#: that alone would deflect a tenth of the stroke range at the peak force); softer is no mount
SOFTEST_SERIES = 10.0
#: the decades [powers of ten of the data-driven guess's series stiffness] held, in order (``series_decades``): one,
#: two and three above, then the guess's own and one below
SERIES_DECADES = (1, 2, 3, 0, -1)


def series_decades(bounds: tuple[float, float], guess: float, softest: float) -> list[float]:
    """The series stiffness values [N/m] to hold, in order: ``guess`` [N/m] ``SERIES_DECADES`` decades up and down,
    each capped at the upper of ``bounds`` (the bound itself once, values closer than 10 % in the logarithm are one)
    and none softer than ``softest`` [N/m] (``SOFTEST_SERIES`` x peak force / stroke range) or the lower bound.
    Stiffer first: a base absorbs a gap, or settles in the wrong basin, by softening the element. Decades apart
    across the element's plausible range, never one value where the range allows more (a ladder of one and two
    decades up, both capped at the 1e9 N/m bound, held one value where the data's mounts were four times softer)."""
    lo, hi = bounds
    soft = max(lo, softest)
    values: list[float] = []
    for j in SERIES_DECADES:
        v = min(guess * 10.0 ** j, hi)
        if v >= soft and all(abs(math.log(v / w)) > 0.1 for w in values):
            values.append(v)
    return values or [hi]


@dataclass(frozen=True)
class SeriesHold:
    """The series element's stiffness ``name`` and the ``values`` [N/m] the check holds it at when it ended on a bound
    (the first two of ``series_decades``)."""

    name: str
    values: tuple


@dataclass
class RestartCheck:
    """What the restart check found: the point it ends on (scaled ``z``, fitness ``g`` = N / SSE [1/N^2], the
    ``polished`` refinement that reached it, or None when the fit's own point stands), every restart run
    (``runs``: label, RMSE [N], rule, Jacobians), the RMSE's standard error at the fit's point
    (``standard_error_n`` [N]), the simulations used and whether the fit's point ``survived`` (no restart ended
    lower by more than one standard error in the last round)."""

    z: np.ndarray
    g: float
    standard_error_n: float
    polished: PolishResult | None = None
    runs: list = field(default_factory=list)
    evaluations: int = 0
    survived: bool = True
    rounds: int = 0

    def to_dict(self) -> dict:
        return {"survived": self.survived, "rounds": self.rounds, "standard_error_n": self.standard_error_n,
                "rmse_n": rmse_of_fitness(self.g), "restarts": self.runs, "evaluations": self.evaluations}



def restart_starts(par: Parametrization, z: np.ndarray, population: np.ndarray | None,
                   series: SeriesHold | None = None) -> list[tuple]:
    """The check's starts from the fit's point ``z`` (scaled): (label, scaled start, name of the coordinate held
    first or None) per scalar coordinate on a bound (moved to the middle of its range; the series element's
    stiffness ``series`` to each of its values instead), then the brightest firefly of ``population`` ((P, d)
    scaled, brightest first; None: none) farther than DISTINCT from ``z``."""
    starts = []
    for i, name in enumerate(par.names):
        if name.startswith(("Fc_", "Fk_")) or AT_BOUND < z[i] < 1.0 - AT_BOUND:
            continue
        if z[i] <= AT_BOUND and par.bounds[name][0] == 0.0:  # the element absent: an answer, not a search limit
            continue
        if series is not None and name == series.name:
            for value in series.values:
                moved = par.from_params({**par.to_params(z), name: value})
                starts.append((f"{name} held at {value:.3g} (a decade above the data-driven guess's or more; it "
                               f"ended on its bound), then released", moved, name))
            continue
        moved = np.array(z, dtype=float)
        moved[i] = 0.5
        value = par.to_params(moved)[name]
        starts.append((f"{name} held at {value:.3g} (mid-range; it ended on its bound), then released", moved, name))
    if population is not None:
        far = [x for x in population if np.linalg.norm(np.asarray(x) - z) > DISTINCT]
        if far:
            starts.append(("the brightest firefly elsewhere", np.asarray(far[0], dtype=float), None))
    return starts


def _run(eng, par: Parametrization, start: tuple, jacobians: int, beat: float) -> tuple[PolishResult, int]:
    """One restart: held first when ``start`` names a coordinate, then free, stopped once it cannot end below the
    SSE ``beat`` [N^2] (``polish``'s rule; the held refinement is not stopped: its release can still go lower).
    Returns the last refinement (its ``z`` in ``par``'s coordinates) and the simulations of both."""
    label, z0, held_name = start
    evaluations = 0
    if held_name is not None:
        held = par.holding({held_name: par.to_params(z0)[held_name]})
        first = polish(eng, held, held.from_params(par.to_params(z0)), max_jacobians=jacobians, log=lambda m: None)
        evaluations += first.evaluations
        z0 = par.from_params(held.to_params(first.z))
    pol = polish(eng, par, z0, max_jacobians=jacobians, log=lambda m: None, beat=beat)
    return pol, evaluations + pol.evaluations


def restart_check(eng, par: Parametrization, z: np.ndarray, g: float, population: np.ndarray | None,
                  jacobians: int, log, series: SeriesHold | None = None) -> RestartCheck:
    """The restart check (module docstring) of the fit at scaled ``z`` (fitness ``g``) of ``par`` on the engine
    ``eng``; ``population``: the Firefly's last generation (scaled, brightest first) or None; ``jacobians``: each
    refinement's cap; ``series``: the series element's values (``SeriesHold``; None: held at mid-range like the
    others). Logs each restart."""
    r = eng.residuals_batch([par.to_params(z)])[0]
    se = rmse_standard_error(r) if r is not None else 0.0
    check = RestartCheck(np.asarray(z, dtype=float), g, se)
    for round_ in range(1, ROUNDS + 1):
        check.rounds = round_
        starts = restart_starts(par, check.z, population if round_ == 1 else None, series)
        best = None
        beat = eng.n_samples * max(rmse_of_fitness(check.g) - se, 0.0) ** 2  # lower by one standard error
        for start in starts:
            pol, evaluations = _run(eng, par, start, jacobians, beat)
            check.evaluations += evaluations
            row = {"round": round_, "start": start[0], "rmse_n": rmse_of_fitness(pol.fitness), "rule": pol.rule,
                   "jacobians": pol.jacobians}
            check.runs.append(row)
            log(f"    restart check: from {start[0]}: RMSE {row['rmse_n']:.2f} N ({pol.rule}) against "
                f"{rmse_of_fitness(check.g):.2f} N")
            gained = rmse_of_fitness(check.g) - rmse_of_fitness(pol.fitness)
            if gained > se and (best is None or pol.fitness > best.fitness):
                best = pol
        if best is None:
            check.survived = True
            return check
        check.z, check.g, check.polished, check.survived = best.z, best.fitness, best, False
    return check
