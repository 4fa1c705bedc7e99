"""Validation metrics of the paper (Isacchi, Ripamonti, Corsi 2023, eq. 5, Table 3, Fig. 11).

Forces are in N. For one test with measured force F_exp and simulated force F_num
(N samples each): MSE = sum (F_exp - F_num)^2 / N [N^2], AME = sum |F_exp - F_num| / N [N],
RMSE [N], NRMSE = RMSE / (max F_exp - min F_exp) [-], R^2 = 1 - SSE / SST [-],
maximum absolute error [N], peak measured force max |F_exp| [N]. Fitness (eq. 5):
G = N / SSE [1/N^2] over all samples of all identification tests, concatenated.
"Variation vs Maxwell" (Table 3): (X_model - X_maxwell) / X_maxwell * 100 [%].

The residual's statistics live here too (one definition for every stage): its correlation time, the
RMSE's standard error, and the block-sandwich covariance of fitted parameters (``block_sandwich``) with
the 95 % interval (``interval``, ``Z95``).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["ErrorMetrics", "error_metrics", "pooled_mse", "fitness", "variation_percent", "compare_to_maxwell",
           "PolyOddEven", "polyfit_odd_even", "correlation_time", "rmse_of_fitness", "rmse_standard_error",
           "block_sandwich", "interval", "Z95"]


def _pair(measured, simulated, what: str = "force") -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(measured, dtype=float)
    b = np.asarray(simulated, dtype=float)
    if a.ndim != 1 or b.ndim != 1:
        raise ValueError(f"measured and simulated {what} must be 1-D arrays, got shapes {a.shape} and {b.shape}")
    if a.size != b.size:
        raise ValueError(f"measured and simulated {what} differ in length: {a.size} vs {b.size}")
    if a.size == 0:
        raise ValueError(f"measured and simulated {what} are empty")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"measured {what} contains non-finite values")
    if not np.all(np.isfinite(b)):
        raise ValueError(f"simulated {what} contains non-finite values")
    return a, b


@dataclass(frozen=True)
class ErrorMetrics:
    """Error indices of one test (forces in N). nrmse and r2 are NaN when the
    measured force is constant (zero range / zero variance)."""

    n: int                    # samples [-]
    sse: float                # sum of squared errors [N^2]
    mse: float                # mean squared error [N^2]
    ame: float                # mean absolute error [N]
    rmse: float               # root mean squared error [N]
    nrmse: float              # RMSE / (max - min of measured) [-]
    r2: float                 # coefficient of determination [-]
    max_abs_error: float      # max |F_exp - F_num| [N]
    peak_measured: float      # max |F_exp| [N]
    fitness: float            # G = N / SSE [1/N^2]; inf for a perfect fit

    def to_dict(self) -> dict[str, float]:
        return asdict(self)


def error_metrics(measured, simulated) -> ErrorMetrics:
    """Metrics of one test. measured, simulated: 1-D force arrays [N] of equal length."""
    f_exp, f_num = _pair(measured, simulated)
    e = f_exp - f_num
    n = e.size
    sse = float(np.dot(e, e))
    mse = sse / n
    rmse = math.sqrt(mse)
    span = float(f_exp.max() - f_exp.min())
    dev = f_exp - f_exp.mean()
    sst = float(np.dot(dev, dev))
    return ErrorMetrics(
        n=n, sse=sse, mse=mse, ame=float(np.mean(np.abs(e))), rmse=rmse,
        nrmse=rmse / span if span > 0 else math.nan,
        r2=1.0 - sse / sst if sst > 0 else math.nan,
        max_abs_error=float(np.max(np.abs(e))),
        peak_measured=float(np.max(np.abs(f_exp))),
        fitness=n / sse if sse > 0 else math.inf,
    )


def pooled_mse(rows) -> float:
    """MSE [N^2] pooled over several tests from their ``error_metrics`` dicts (sample-weighted:
    the MSE of all their samples together); inf without samples."""
    se = n = 0.0
    for m in rows:
        se, n = se + m["mse"] * m["n"], n + m["n"]
    return se / n if n else math.inf


def _autocorrelation(r: np.ndarray, max_lag: int | None = None) -> np.ndarray:
    """Autocorrelation of ``r`` at lags 0, 1, ... up to its first drop below 0.05 (or ``max_lag``, at
    most a quarter of its length); [1.0] for a constant or very short ``r``."""
    r = np.asarray(r, dtype=float) - float(np.mean(r))
    n = r.size
    if n < 4 or not np.any(r):
        return np.ones(1)
    max_lag = min(n // 4, max_lag or n // 4)
    spec = np.fft.rfft(r, 2 * n)
    acf = np.fft.irfft(spec * np.conj(spec))[:max_lag + 1]
    acf = acf / acf[0]
    below = np.nonzero(acf[1:] < 0.05)[0]
    return acf[:(int(below[0]) if below.size else max_lag) + 1]


def correlation_time(r: np.ndarray, max_lag: int | None = None) -> float:
    """Integrated autocorrelation time [samples] of ``r``: 1 + 2 sum of the autocorrelation up to
    its first drop below 0.05 (>= 1; white noise gives ~1)."""
    return max(1.0, 1.0 + 2.0 * float(np.sum(_autocorrelation(r, max_lag)[1:])))


def rmse_of_fitness(g: float) -> float:
    """RMSE [N] of the identification fitness G = N / SSE [1/N^2] (the paper's eq. 5); inf for G = 0."""
    return 1.0 / math.sqrt(g) if g > 0 else math.inf


def rmse_standard_error(r: np.ndarray) -> float:
    """Standard error [N] of the RMSE of the residual ``r`` [N] as an estimate of its population value:
    RMSE / sqrt(2 N_eff) with N_eff = N / (1 + 2 sum rho_k^2) (for a Gaussian stationary residual
    var(MSE) = 2 sigma^4 sum_k rho_k^2 / N; rho: the autocorrelation, as ``correlation_time``). A change
    of the RMSE well under it is no change the data can show."""
    r = np.asarray(r, dtype=float)
    if r.size == 0:
        raise ValueError("rmse_standard_error: an empty residual")
    n_eff = r.size / max(1.0, 1.0 + 2.0 * float(np.sum(_autocorrelation(r)[1:] ** 2)))
    return math.sqrt(float(r @ r) / r.size) / math.sqrt(2.0 * n_eff)


# -- intervals of fitted parameters when the residuals are correlated ---------------------------------
# A least-squares fit's textbook covariance sigma^2 (J^T J)^-1 assumes white residuals. The residual of a
# damper fit is not white: model-form error is smooth in time and repeats at every velocity reversal, and
# the fit band's low-pass correlates even white noise, so the textbook interval is far too narrow.
# ``block_sandwich`` uses the sandwich (heteroscedasticity and autocorrelation consistent) estimate
#
#     Cov = (J^T J)^+ [ sum over blocks b of (J_b^T r_b)(J_b^T r_b)^T ] (J^T J)^+
#
# with contiguous blocks (within one test) several residual correlation times long: the analytic
# counterpart of a residual block bootstrap. Units: J [N per coordinate unit], r [N]; covariances in
# coordinate units^2 (the caller converts). The diagnosis's effect intervals
# (``tuner.diagnosis.refit.effect_intervals``) and the identified parameters' intervals
# (``tuner.identification.intervals``) share it.

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


def fitness(measured, simulated) -> float:
    """Paper eq. 5: G = N / sum (F_exp - F_num)^2 [1/N^2] over all samples.

    measured, simulated: one 1-D force array [N] each, or equal-length sequences of
    1-D arrays (one per test, concatenated). Returns inf for a perfect fit; the Firefly
    treats non-finite fitness as worst, so objectives should not rely on exact zeros.
    """
    if _is_sequence_of_arrays(measured) or _is_sequence_of_arrays(simulated):
        if not (_is_sequence_of_arrays(measured) and _is_sequence_of_arrays(simulated)):
            raise ValueError("measured and simulated must both be arrays or both sequences of arrays")
        if len(measured) != len(simulated) or len(measured) == 0:
            raise ValueError(f"need the same non-zero number of tests, got {len(measured)} and {len(simulated)}")
        pairs = [_pair(m, s, f"force of test {i}") for i, (m, s) in enumerate(zip(measured, simulated))]
        a = np.concatenate([p[0] for p in pairs])
        b = np.concatenate([p[1] for p in pairs])
    else:
        a, b = _pair(measured, simulated)
    e = a - b
    sse = float(np.dot(e, e))
    return a.size / sse if sse > 0 else math.inf


def _is_sequence_of_arrays(x) -> bool:
    if isinstance(x, np.ndarray):
        return False
    return isinstance(x, (list, tuple)) and len(x) > 0 and all(np.ndim(item) == 1 for item in x)


def variation_percent(x_model: float, x_maxwell: float) -> float:
    """Table 3 variation: (x_model - x_maxwell) / x_maxwell * 100 [%]."""
    xm, xr = float(x_model), float(x_maxwell)
    if not (math.isfinite(xm) and math.isfinite(xr)):
        raise ValueError(f"variation needs finite values, got {x_model!r} and {x_maxwell!r}")
    if xr == 0:
        raise ValueError("variation vs Maxwell undefined: Maxwell value is zero")
    return (xm - xr) / xr * 100.0


def compare_to_maxwell(model: ErrorMetrics, maxwell: ErrorMetrics) -> dict[str, float]:
    """Variation of MSE and AME [%] of a model vs the Maxwell model on the same test."""
    if model.n != maxwell.n:
        raise ValueError(f"metrics come from tests of different length: {model.n} vs {maxwell.n}")
    return {"mse": variation_percent(model.mse, maxwell.mse), "ame": variation_percent(model.ame, maxwell.ame)}


@dataclass(frozen=True)
class PolyOddEven:
    """Least-squares polynomial and its parity split, evaluated on x.

    coefficients[k] multiplies x^k (ascending order, units [y]/[x]^k). fit, odd, even:
    arrays like x; even includes the constant term. asymmetry_index = rms(even) / rms(fit)
    [-]: 0 for a symmetric (odd) characteristic.
    """

    coefficients: np.ndarray
    fit: np.ndarray
    odd: np.ndarray
    even: np.ndarray
    asymmetry_index: float


def polyfit_odd_even(x, y, order: int = 5) -> PolyOddEven:
    """Fit y(x) with a polynomial of the given order (paper Fig. 11, eqs. 9-10) and split it
    into odd- and even-order parts. x, y: 1-D arrays of equal length (any units).

    Solved in the scaled variable t = x / max|x|, which keeps the Vandermonde matrix well
    conditioned for x ~ 1e-2 m and does not mix parities (a shift would).
    """
    if int(order) != order or order < 0:
        raise ValueError(f"order must be a non-negative integer, got {order!r}")
    order = int(order)
    xa, ya = _pair(x, y, "data")
    if xa.size < order + 1:
        raise ValueError(f"need at least order + 1 = {order + 1} points, got {xa.size}")
    scale = float(np.max(np.abs(xa)))
    if scale == 0:
        raise ValueError("x is all zero: nothing to fit")
    t = xa / scale
    V = np.vander(t, order + 1, increasing=True)
    if np.linalg.matrix_rank(V) < order + 1:
        raise ValueError(f"x has fewer than {order + 1} distinct values: order {order} fit is not determined")
    c_t, *_ = np.linalg.lstsq(V, ya, rcond=None)
    powers = np.arange(order + 1)
    odd_mask = powers % 2 == 1
    odd = V[:, odd_mask] @ c_t[odd_mask]
    even = V[:, ~odd_mask] @ c_t[~odd_mask]
    fit = odd + even
    rms_fit = math.sqrt(float(np.mean(fit ** 2)))
    if rms_fit == 0:
        raise ValueError("fitted polynomial is identically zero on x: asymmetry index undefined")
    return PolyOddEven(coefficients=c_t / scale ** powers, fit=fit, odd=odd, even=even,
                       asymmetry_index=math.sqrt(float(np.mean(even ** 2))) / rms_fit)


def noise_std(signal, sample_rate: float) -> float:
    """Measurement noise of a sampled signal [its unit], white-equivalent over the Nyquist band:
    sqrt(PSD x sample_rate / 2), the PSD taken as the smaller of its medians over the bands
    0.1-0.2 and 0.2-0.3 x sample_rate. A damper force's content (the harmonics of its
    characteristic's kinks) falls with frequency, so at low sample rates (300 Hz) the upper band
    is the less biased; the bands stop at 0.3 x sample_rate because rigs' anti-alias filters
    start to cut the noise above (the virtual rig's FIR, cut-off 0.4 x, already attenuates 0.3-0.4 x:
    an estimate from there read 8 N for 10 N, and too low a noise makes effects look resolved).
    Any signal left in the bands biases it high (conservative)."""
    from scipy.signal import welch

    x = np.asarray(signal, dtype=float)
    if x.size < 64:
        raise ValueError("noise_std needs at least 64 samples")
    f, p = welch(x - x.mean(), fs=sample_rate, nperseg=min(1024, x.size))
    medians = [np.median(p[(f > lo * sample_rate) & (f < hi * sample_rate)])
               for lo, hi in ((0.1, 0.2), (0.2, 0.3))]
    return float(np.sqrt(min(medians) * sample_rate / 2.0))
