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

import numpy as np

__all__ = ["absorbed_signature", "limit_from_signature", "jacobian_columns", "detection_limits"]

#: singular values of the identification Jacobian below this fraction of the largest are directions
#: the data do not determine (the refit moves freely along them): not used to absorb a signature
RCOND = 1e-9


def absorbed_signature(j_id: np.ndarray, j_val: np.ndarray, J_id: np.ndarray, J_val: np.ndarray) -> np.ndarray:
    """``u = j_val - J_val pinv(J_id) j_id``: what the base refit on the identification tests leaves of the
    effect's held-out signature (all per unit magnitude [N per unit]; J columns: the same base steps)."""
    delta, *_ = np.linalg.lstsq(J_id, j_id, rcond=RCOND)
    return j_val - J_val @ delta


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


def jacobian_columns(engine, par, z0: np.ndarray, steps: np.ndarray) -> np.ndarray | None:
    """Forward-difference Jacobian of ``engine``'s simulated force [N per scaled unit] with respect to the
    scaled coordinates of ``par`` at ``z0`` (``steps``: one per coordinate, signed); one parallel batch.
    None when z0 cannot be simulated; a column whose point fails is zero (no direction to absorb along)."""
    pts = [z0] + [z0 + np.eye(len(z0))[i] * steps[i] for i in range(len(z0))]
    res = engine.residuals_batch([par.to_params(p) for p in pts])
    if res[0] is None:
        return None
    # residual = measured - simulated: the simulated force's derivative is minus the residual's
    return np.column_stack([(res[0] - r) / h if r is not None else np.zeros_like(res[0])
                            for r, h in zip(res[1:], steps)])


def _signature(engine, params: dict, name: str, magnitude: float) -> np.ndarray | None:
    """Simulated force with ``name`` at ``magnitude`` minus without it, per unit magnitude [N per unit]."""
    r_off, r_on = engine.residuals_batch([{**params, name: 0.0}, {**params, name: magnitude}])
    if r_off is None or r_on is None:
        return None
    return (r_off - r_on) / magnitude


def detection_limits(eid, ev, par, z0: np.ndarray, parameters: dict[str, str], reference: dict[str, float],
                     bounds: dict[str, tuple[float, float]], smallest: dict[str, float], mse_ref: float,
                     noise_n: float, accept: float, penalty: float, lengths_val: list[int], test_names: list[str],
                     refine: int = 2, step: float = 1e-4) -> dict:
    """Detection limit of every effect: {effect: {"parameter", "limit", "by_score", "by_noise",
    "by_range", "limited_by", "best_test", "per_test": {test: limit}, "reachable": limit within the search
    bounds, "linearised_at"}}.

    eid, ev: engines of the base model on the identification and held-out tests (``residuals_batch``);
    par: the base parametrization, z0: the fitted base (scaled); parameters: effect -> its magnitude
    parameter; reference: parameter -> first magnitude to linearise at (the low end of its typical
    range); bounds: parameter -> search bounds; smallest: parameter -> the smallest magnitude the diagnosis
    names (its physical range); mse_ref [N^2], noise_n [N], accept, penalty: as in
    ``limit_from_signature``; lengths_val: held-out samples per test, in ``ev``'s order; test_names: their
    names; refine: times the signature is taken again at the current limit."""
    steps = np.where(z0 + step <= 1.0, step, -step)
    J_id, J_val = jacobian_columns(eid, par, z0, steps), jacobian_columns(ev, par, z0, steps)
    if J_id is None or J_val is None:
        return {}
    base = par.to_params(z0)
    edges = np.cumsum([0, *lengths_val])
    out = {}
    for effect, name in parameters.items():
        lo, hi = bounds[name]
        top = max(abs(lo), abs(hi))
        m = min(reference[name], top)
        row = None
        for _ in range(1 + refine):
            j_id, j_val = _signature(eid, base, name, m), _signature(ev, base, name, m)
            if j_id is None or j_val is None:
                break
            u = absorbed_signature(j_id, j_val, J_id, J_val)
            row = limit_from_signature(u, j_id, mse_ref, noise_n, accept, penalty)
            # per test against the pooled reference (a per-test reference would reward a noisy test)
            row["per_test"] = {test: max(limit_from_signature(u[edges[k]:edges[k + 1]], j_id, mse_ref, noise_n, accept,
                                                              penalty)["by_score"], row["by_noise"])
                               for k, test in enumerate(test_names)}
            row["linearised_at"] = m
            if not math.isfinite(row["limit"]) or row["limit"] >= top:
                break
            m = max(row["limit"], 1e-6 * top)
        if row is None:
            continue
        row["parameter"] = name
        row["by_range"] = smallest[name]
        row["limited_by"] = max(("score", row["by_score"]), ("noise", row["by_noise"]), ("range", smallest[name]),
                                key=lambda kv: kv[1])[0]
        row["limit"] = max(row["limit"], smallest[name])
        row["per_test"] = {t: max(v, smallest[name]) for t, v in row["per_test"].items()}
        row["best_test"] = min(row["per_test"], key=row["per_test"].get) if row["per_test"] else None
        row["reachable"] = bool(row["limit"] <= top)
        out[effect] = row
    return out
