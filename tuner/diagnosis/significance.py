"""Confidence intervals of fitted parameters when the residuals are correlated.

A least-squares fit's textbook covariance sigma^2 (J^T J)^-1 assumes white residuals. The residual
of a damper fit is not white: model-form error is smooth in time and repeats at every velocity
reversal, so the textbook interval is far too narrow and would make any effect "significant".
``block_sandwich`` uses the sandwich (heteroscedasticity and autocorrelation consistent) estimate

    Cov = (J^T J)^+ [ sum over blocks b of (J_b^T r_b)(J_b^T r_b)^T ] (J^T J)^+

with contiguous blocks (within one test) several residual correlation times long: the analytic
counterpart of a residual block bootstrap. ``correlation_time`` (``tuner.metrics``, the one definition)
gives that time from the residual's autocorrelation.

Units: J [N per scaled unit], r [N]; covariances in scaled units^2 (the caller converts).
"""
from __future__ import annotations

import math

import numpy as np

from tuner.metrics import correlation_time

__all__ = ["correlation_time", "block_sandwich", "interval", "Z95"]

#: two-sided 95 % normal quantile
Z95 = 1.959963984540054


def block_sandwich(jac: np.ndarray, r: np.ndarray, lengths: list[int], block: int) -> tuple[np.ndarray, int]:
    """(covariance of the parameters [scaled^2], number of blocks) from the residual Jacobian
    ``jac`` (n x p), the residual ``r`` (n) and per-test ``lengths`` (the blocks never straddle
    two tests; a test's last partial block joins the one before it)."""
    jac = np.asarray(jac, dtype=float)
    r = np.asarray(r, dtype=float)
    if jac.shape[0] != r.size or sum(lengths) != r.size:
        raise ValueError(f"Jacobian rows {jac.shape[0]}, residual {r.size} and test lengths "
                         f"{sum(lengths)} must agree")
    block = max(1, int(block))
    scores, start = [], 0
    for n in lengths:
        edges = list(range(start, start + n, block))
        if len(edges) > 1 and start + n - edges[-1] < block:
            edges.pop()  # the short tail joins the previous block
        for a, b in zip(edges, edges[1:] + [start + n]):
            scores.append(jac[a:b].T @ r[a:b])
        start += n
    s = np.array(scores)
    bread = np.linalg.pinv(jac.T @ jac, rcond=1e-12, hermitian=True)
    meat = s.T @ s
    nb, p = len(scores), jac.shape[1]
    if nb > p:
        meat *= nb / (nb - p)  # small-sample correction of the block scores' spread
    return bread @ meat @ bread, nb


def interval(value: float, std: float, low_bound: float | None = None) -> tuple[float, float]:
    """Two-sided 95 % interval value +- Z95 std, clipped at ``low_bound`` (a physical lower bound)."""
    lo, hi = value - Z95 * std, value + Z95 * std
    if low_bound is not None:
        lo = max(lo, low_bound)
    return lo, hi if math.isfinite(hi) else math.inf
