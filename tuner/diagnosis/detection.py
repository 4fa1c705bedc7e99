"""Detection limits: the smallest magnitude of each catalogue effect that the given tests could tell
apart from the base model, and the test that would show it.

Some effects are almost a change of the base model's own parameters on given strokes (a friction
acting at the valve looks like a steeper first piece of Fc,O): the base refit absorbs them, and the
verdict ``none`` then means "nothing above this size", not "nothing". Linearised at the fitted base
(SI units; forces [N], magnitudes in the effect parameter's unit):

* the effect's force signature per unit magnitude, ``j`` [N per unit], on the identification and the
  held-out tests: the model with the effect at a reference magnitude minus the model without it,
  divided by that magnitude;
* the base refit absorbs the least-squares projection of ``j_id`` onto the columns of the base
  Jacobian on the identification tests (``J_id``, the same parameter steps as ``J_val``) and carries
  that change to the held-out tests, leaving per unit magnitude ``u = j_val - J_val pinv(J_id) j_id``;
* a hidden effect of magnitude ``m`` then leaves the refitted base a held-out MSE larger by
  ``a m^2`` (``a = |u|^2 / N_val``), which the extension wins back: its score is
  ``ln(1 + a m^2 / mse_ref) - penalty``, named above ``accept``. With the force rule (the effect's
  force on the identification tests, ``m rms(j_id)``, at least the noise) the limit is
  ``m* = max(sqrt(mse_ref (exp(accept + penalty) - 1) / a), noise / rms(j_id))``;
* a magnitude below the effect's physical range is never named (the diagnosis's meaningful
  fraction of the low end of its typical range): the limit is at least that (``by_range``);
* per held-out test the same with that test alone: the test with the smallest limit is the one that
  would show the effect.

Effects whose force is not proportional to their magnitude (free play, delays, lags) are linearised
at the limit itself: the signature is taken again at the first estimate (``refine``), so the limit is
the magnitude at which the linear model says the effect would be named.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["absorbed_signature", "absorption", "limit_from_signature", "detection_limits", "EffectMagnitude",
           "NamingRule"]

#: singular values of the identification Jacobian below this fraction of the largest are directions
#: the data do not determine (the refit moves freely along them): not used to absorb a signature
RCOND = 1e-9


@dataclass(frozen=True)
class EffectMagnitude:
    """One effect's magnitude in ``detection_limits``: its ``parameter`` (name), the ``reference`` magnitude to
    linearise at first (the low end of its typical range), its search ``bounds``, the ``smallest`` magnitude the
    diagnosis names and the ``largest`` a damper of this size plausibly has (its physical range,
    ``tuner.diagnosis.effect_sizes.plausible_range``), all in the parameter's unit."""

    parameter: str
    reference: float
    bounds: tuple[float, float]
    smallest: float
    largest: float = math.inf


@dataclass(frozen=True)
class NamingRule:
    """What a hidden effect must do to be named, as ``limit_from_signature`` reads it: ``mse_ref`` [N^2], the
    held-out MSE of the refitted base; ``noise_n`` [N rms], the force an effect must reach on the identification
    tests; ``accept``, the acceptance score; ``penalty``, the score's penalty for the effect's parameters."""

    mse_ref: float
    noise_n: float
    accept: float
    penalty: float


def absorbed_signature(j_id: np.ndarray, j_val: np.ndarray, J_id: np.ndarray, J_val: np.ndarray) -> np.ndarray:
    """``u = j_val - J_val pinv(J_id) j_id``: what the base refit on the identification tests leaves of the
    effect's held-out signature (all per unit magnitude [N per unit]; J columns: the same base steps)."""
    delta, *_ = np.linalg.lstsq(J_id, j_id, rcond=RCOND)
    return j_val - J_val @ delta


def absorption(j_id: np.ndarray, J_id: np.ndarray) -> tuple[float, np.ndarray]:
    """(the share of the effect's identification signature ``j_id`` that the base refit absorbs, in [0, 1]; each
    base coordinate's part of that absorbed force, summing to 1): the least-squares step ``delta`` of the base
    (``J_id`` columns) reproduces ``J_id delta`` of the signature; coordinate k's part is ``(J_k delta_k) .
    (J_id delta) / |J_id delta|^2``. An effect whose signature is absorbed almost whole cannot be told apart
    from the base parameters that absorb it on these tests."""
    delta, *_ = np.linalg.lstsq(J_id, j_id, rcond=RCOND)
    absorbed = J_id @ delta
    aa, jj = float(absorbed @ absorbed), float(j_id @ j_id)
    if aa <= 0.0 or jj <= 0.0:
        return 0.0, np.zeros(J_id.shape[1])
    return min(aa / jj, 1.0), (J_id * delta).T @ absorbed / aa


def limit_from_signature(u: np.ndarray, j_id: np.ndarray, mse_ref: float, noise_n: float, accept: float,
                         penalty: float) -> dict:
    """The limit [unit of the effect] from the unabsorbed held-out signature ``u`` and the identification
    signature ``j_id`` (per unit magnitude, N per unit); ``mse_ref`` [N^2]: held-out MSE of the refitted
    base; ``noise_n`` [N rms]; ``accept``, ``penalty``: the diagnosis's acceptance score and the penalty of
    the effect's parameters. Returns {"limit", "by_score", "by_noise"} (inf where nothing can reveal it)."""
    a = float(u @ u) / max(len(u), 1)
    rms_id = math.sqrt(float(j_id @ j_id) / max(len(j_id), 1))
    by_score = math.sqrt(mse_ref * math.expm1(accept + penalty) / a) if a > 0 else math.inf
    by_noise = noise_n / rms_id if rms_id > 0 else math.inf
    return {"limit": max(by_score, by_noise), "by_score": by_score, "by_noise": by_noise}


def _columns(r0: np.ndarray, res: list, steps: np.ndarray) -> np.ndarray:
    """Forward-difference Jacobian of the simulated force [N per scaled unit] from the residuals ``res`` at the
    points stepped by ``steps`` (signed, one per coordinate) and ``r0`` at the point itself; a column whose point
    failed is zero (no direction to absorb along). The residual is measured - simulated: the simulated force's
    derivative is minus the residual's."""
    return np.column_stack([(r0 - r) / h if r is not None else np.zeros_like(r0) for r, h in zip(res, steps)])


@dataclass
class _Linearisation:
    """One engine's tests at the fitted base: its Jacobian [N per scaled unit] and, per effect, the residual [N]
    with the effect's magnitude at zero."""

    jacobian: np.ndarray
    off: dict


def _linearise(engine, par, z0: np.ndarray, steps: np.ndarray, parameters: dict[str, str]) -> _Linearisation | None:
    """The base Jacobian on ``engine``'s tests (forward steps ``steps``) and each effect switched off, in one
    parallel batch; None when the base cannot be simulated."""
    base = par.to_params(z0)
    stepped = [par.to_params(z0 + np.eye(len(z0))[i] * steps[i]) for i in range(len(z0))]
    res = engine.residuals_batch([base, *stepped, *({**base, name: 0.0} for name in parameters.values())])
    if res[0] is None:
        return None
    return _Linearisation(_columns(res[0], res[1:1 + len(z0)], steps), dict(zip(parameters, res[1 + len(z0):])))


def _row(u: np.ndarray, j_id: np.ndarray, m: float, edges: np.ndarray, test_names: list[str],
         rule: NamingRule) -> dict:
    """``limit_from_signature`` pooled and per held-out test (``edges``: the tests' sample offsets), linearised
    at the magnitude ``m``."""
    mse_ref, noise_n, accept, penalty = rule.mse_ref, rule.noise_n, rule.accept, rule.penalty
    row = limit_from_signature(u, j_id, mse_ref, noise_n, accept, penalty)
    # per test against the pooled reference (a per-test reference would reward a noisy test)
    row["per_test"] = {test: max(limit_from_signature(u[edges[k]:edges[k + 1]], j_id, mse_ref, noise_n, accept,
                                                      penalty)["by_score"], row["by_noise"])
                       for k, test in enumerate(test_names)}
    row["linearised_at"] = m
    return row


def detection_limits(eid, ev, par, z0: np.ndarray, magnitudes: dict[str, EffectMagnitude], rule: NamingRule, *,
                     refine: int = 2, step: float = 1e-4) -> dict:
    """Detection limit of every effect: {effect: {"parameter", "limit", "by_score", "by_noise",
    "by_range", "limited_by", "best_test", "per_test": {test: limit}, "reachable": limit within the search
    bounds, "plausible_top", "within_plausible": limit within the physical range (``EffectMagnitude.largest``),
    "linearised_at", "absorbed_share", "absorbed_by_coordinate" (``absorption`` at that magnitude, per
    coordinate of ``par``)}}.

    eid, ev: engines of the base model on the identification and held-out tests (``residuals_batch``; the
    per-test limits are those of ``ev.tests``, by their masked samples); par: the base parametrization, z0: the
    fitted base (scaled); magnitudes: effect -> its ``EffectMagnitude``; rule: the ``NamingRule``; refine: times
    the signature is taken again at the current limit. Every effect's signature is taken in one parallel batch per
    engine and round."""
    parameters = {e: mag.parameter for e, mag in magnitudes.items()}
    lengths_val, test_names = [int(t.mask.sum()) for t in ev.tests], [t.name for t in ev.tests]
    steps = np.where(z0 + step <= 1.0, step, -step)
    lin_id, lin_val = _linearise(eid, par, z0, steps, parameters), _linearise(ev, par, z0, steps, parameters)
    if lin_id is None or lin_val is None:
        return {}
    base = par.to_params(z0)
    edges = np.cumsum([0, *lengths_val])
    top = {e: max(abs(b) for b in mag.bounds) for e, mag in magnitudes.items()}
    m = {e: min(mag.reference, top[e]) for e, mag in magnitudes.items()}
    active = [e for e in parameters if lin_id.off[e] is not None and lin_val.off[e] is not None]
    rows = {}
    for _ in range(1 + refine):
        on_id, on_val = ([engine.residuals_batch([{**base, parameters[e]: m[e]} for e in active]) if active else []
                         for engine in (eid, ev)])
        still = []
        for e, r_id, r_val in zip(active, on_id, on_val):
            if r_id is None or r_val is None:
                continue
            j_id, j_val = (lin_id.off[e] - r_id) / m[e], (lin_val.off[e] - r_val) / m[e]
            u = absorbed_signature(j_id, j_val, lin_id.jacobian, lin_val.jacobian)
            rows[e] = _row(u, j_id, m[e], edges, test_names, rule)
            share, parts = absorption(j_id, lin_id.jacobian)
            rows[e]["absorbed_share"], rows[e]["absorbed_by_coordinate"] = share, parts.tolist()
            if math.isfinite(rows[e]["limit"]) and rows[e]["limit"] < top[e]:
                m[e] = max(rows[e]["limit"], 1e-6 * top[e])
                still.append(e)
        active = still
    return {e: _finish(rows[e], magnitudes[e], top[e]) for e in parameters if e in rows}


def _finish(row: dict, mag: EffectMagnitude, top: float) -> dict:
    """The limit at least ``mag.smallest`` (the physical range's meaningful floor), what limits it, the test that
    would show it, whether it lies within the search bound ``top`` and within the physical range's top."""
    name, smallest = mag.parameter, mag.smallest
    row["parameter"] = name
    row["by_range"] = smallest
    row["limited_by"] = max(("score", row["by_score"]), ("noise", row["by_noise"]), ("range", smallest),
                            key=lambda kv: kv[1])[0]
    row["limit"] = max(row["limit"], smallest)
    row["per_test"] = {t: max(v, smallest) for t, v in row["per_test"].items()}
    row["best_test"] = min(row["per_test"], key=row["per_test"].get) if row["per_test"] else None
    row["reachable"] = bool(row["limit"] <= top)
    row["plausible_top"] = mag.largest
    row["within_plausible"] = bool(row["limit"] <= min(top, mag.largest))
    return row
