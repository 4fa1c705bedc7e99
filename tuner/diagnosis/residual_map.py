"""The restoring-force map: where the residual lives (``residual_map``, ``map_summary``): r of the identification
tests (the fit's samples, at the fit rate) binned over stroke x velocity and over velocity on the two branches of
the loop (acceleration >= 0 and < 0), and the shares of its power near velocity reversal, at the stroke ends, in
one band of the stroke, above the blow-off knee and in the difference between the branches at equal velocity (a
hysteresis), each beside its share of the samples. Residual r = measured - simulated force [N]; stroke [m],
velocity [m/s].
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tuner.diagnosis.residual_tests import pooled_samples

__all__ = ["ResidualMap", "residual_map", "map_summary", "identification_only", "MIN_BIN_SAMPLES"]

#: the map's bins over the identification tests' range: stroke x velocity; the velocity's edges are symmetric
#: about 0 and their number even, so that v = 0 is an edge and no bin mixes extension and compression
MAP_STROKE_BINS = 12
MAP_VELOCITY_BINS = 16
#: a bin with fewer samples is left empty (NaN): the rms of 25 independent samples scatters by 1/sqrt(2 x 25) =
#: 14 % (one sigma), so a bin at twice the overall rms stands out of it; fewer would read scatter as structure
MIN_BIN_SAMPLES = 25
#: near velocity reversal: |v| below this share of the test's peak |v| (a sine spends 13 % of its time there);
#: friction, a free play or a valve's crack-open that the base's tables cannot follow live there
REVERSAL_SPEED_SHARE = 0.2
#: at the stroke ends: within this share of the test's stroke range from either end (a sine spends 29 % of its
#: time there, it dwells at the ends); an end stop, a top-out spring or a gas spring's rise live there
STROKE_END_SHARE = 0.05
#: the stroke range is cut into this many bands of equal width, to find one position holding a disproportionate
#: share (a groove, a worn or scored stretch of the tube); each band needs MIN_BIN_SAMPLES samples to count
STROKE_BANDS = 10
#: a region holds the residual when its power share is at least CONCENTRATED_RATIO x its time share (an even
#: spread gives 1; the share of a residual correlated over a few cycles scatters by tens of percent, not 2x) and
#: at least CONCENTRATED_SHARE of the power: removing less than a third would cut the rms by less than 18 %, which
#: is not where the error lives
CONCENTRATED_RATIO = 2.0
CONCENTRATED_SHARE = 1 / 3
#: the branches differ (a hysteresis) when the part of the residual that differs between the a >= 0 and a < 0
#: branches at equal velocity holds at least this share of the power: the same third as a region's (independent
#: noise gives about (velocity bins) / (samples): 16 / 1000 = 1.6 % on 5 s at 200 Hz)
HYSTERESIS_SHARE = 1 / 3


@dataclass
class ResidualMap:
    """The residual r = measured - simulated force [N] binned over the restoring-force plane (``residual_map``):
    ``rms_n``, ``count`` over stroke [m] (rows, + extension) x velocity [m/s] (columns, + extension), and
    ``branch_rms_n``, ``branch_mean_n``, ``branch_count`` over velocity on each branch of the loop (row 0:
    acceleration >= 0, row 1: < 0). A bin with fewer than MIN_BIN_SAMPLES samples holds NaN (its count stays)."""

    stroke_edges_m: np.ndarray
    velocity_edges_m_s: np.ndarray
    rms_n: np.ndarray
    count: np.ndarray
    branch_rms_n: np.ndarray
    branch_mean_n: np.ndarray
    branch_count: np.ndarray


def identification_only(preps: list) -> list:
    """The identification tests of ``preps``: the ones the model was fitted on, whose residual the map shows."""
    return [p for p in preps if p.t.role == "identification"]


def _edges(x: np.ndarray, n: int, symmetric: bool = False) -> np.ndarray:
    """n equal bins' edges over the range of x (symmetric: over +-max |x|, 0 an edge when n is even)."""
    if symmetric:
        top = max(float(np.abs(x).max()), 1e-12)
        return np.linspace(-top, top, n + 1)
    lo, hi = float(x.min()), float(x.max())
    return np.linspace(lo, max(hi, lo + 1e-12), n + 1)


def _bin_of(x: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Bin index of every x (the last bin closed on the right)."""
    return np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2)


def _binned(r: np.ndarray, k: np.ndarray, n: int):
    """(rms [N], mean [N], count) of r in each bin k of n; NaN where a bin has fewer than MIN_BIN_SAMPLES."""
    count = np.bincount(k, minlength=n)
    ok = count >= MIN_BIN_SAMPLES
    rms, mean = np.full(n, np.nan), np.full(n, np.nan)
    rms[ok] = np.sqrt(np.bincount(k, r * r, n)[ok] / count[ok])
    mean[ok] = np.bincount(k, r, n)[ok] / count[ok]
    return rms, mean, count


def residual_map(preps: list) -> ResidualMap:
    """The residual of ``preps`` (their usable samples, pooled) binned over stroke x velocity and over velocity
    on the a >= 0 and a < 0 branches (``ResidualMap``); the bins span the samples' range."""
    if not preps:
        raise ValueError("no tests to map")
    r, x, v = (pooled_samples(preps, f) for f in (lambda p: p.r, lambda p: p.t.stroke, lambda p: p.t.velocity))
    negative_a = pooled_samples(preps, lambda p: p.acc < 0)
    xe, ve = _edges(x, MAP_STROKE_BINS), _edges(v, MAP_VELOCITY_BINS, symmetric=True)
    kx, kv = _bin_of(x, xe), _bin_of(v, ve)
    rms, _, count = _binned(r, kx * MAP_VELOCITY_BINS + kv, MAP_STROKE_BINS * MAP_VELOCITY_BINS)
    b_rms, b_mean, b_count = _binned(r, negative_a * MAP_VELOCITY_BINS + kv, 2 * MAP_VELOCITY_BINS)
    shape = (MAP_STROKE_BINS, MAP_VELOCITY_BINS)
    return ResidualMap(xe, ve, rms.reshape(shape), count.reshape(shape), b_rms.reshape(2, -1),
                       b_mean.reshape(2, -1), b_count.reshape(2, -1))


def _share(r2: np.ndarray, sel: np.ndarray) -> dict:
    """A region's share of the residual power (r2: r^2 per sample) and of the samples [0-1], and their ratio."""
    power, time = float(r2[sel].sum() / (r2.sum() or 1.0)), float(sel.mean())
    return {"power_share": power, "time_share": time, "ratio": power / time if time > 0 else None}


def _at_stroke_ends(p) -> np.ndarray:
    """The samples of one test within STROKE_END_SHARE of its stroke range (usable samples) from either end."""
    x = p.t.stroke
    lo, hi = float(x[p.use].min()), float(x[p.use].max())
    return (x <= lo + STROKE_END_SHARE * (hi - lo)) | (x >= hi - STROKE_END_SHARE * (hi - lo))


def _stroke_band(x: np.ndarray, r2: np.ndarray) -> dict:
    """Of STROKE_BANDS equal bands of the stroke x [m], the one whose power share is the largest multiple of its
    time share (bands of MIN_BIN_SAMPLES samples or more): ``_share`` with its ends [m]."""
    edges = _edges(x, STROKE_BANDS)
    k = _bin_of(x, edges)
    n, power = np.bincount(k, minlength=STROKE_BANDS), np.bincount(k, r2, STROKE_BANDS)
    ratio = np.where(n >= MIN_BIN_SAMPLES, power / np.maximum(n, 1), -np.inf)
    j = int(np.argmax(ratio))
    return {**_share(r2, k == j), "stroke_from_m": float(edges[j]), "stroke_to_m": float(edges[j + 1])}


def _branch_asymmetry(m: ResidualMap, r2: np.ndarray) -> dict:
    """The residual power that differs between the a >= 0 and a < 0 branches at equal velocity: the between-branch
    sum of squares of the branch means in every velocity bin where both branches hold MIN_BIN_SAMPLES, over the
    whole residual power; its time share is those bins' samples."""
    both = (m.branch_count >= MIN_BIN_SAMPLES).all(axis=0)
    n, mean = m.branch_count[:, both], m.branch_mean_n[:, both]
    pooled = (n * mean).sum(axis=0) / np.maximum(n.sum(axis=0), 1)
    power = float((n * (mean - pooled) ** 2).sum() / (r2.sum() or 1.0))
    return {"power_share": power, "time_share": float(n.sum() / r2.size),
            "hysteresis": bool(power >= HYSTERESIS_SHARE)}


def map_summary(preps: list, knee: float) -> dict:
    """Where the residual of ``preps`` lives (their usable samples, pooled): each region's share of the residual
    power and of the samples [0-1] and their ratio: ``near_reversal`` (|v| < REVERSAL_SPEED_SHARE x the test's
    peak |v|), ``stroke_ends`` (within STROKE_END_SHARE of the test's stroke range from either end),
    ``stroke_band`` (the band of the stroke with the largest ratio, its ends [m]) and ``above_knee`` (|v| >=
    ``knee`` [m/s]); ``branch_asymmetry`` (the power that differs between the a >= 0 and a < 0 branches at equal
    velocity: a hysteresis when at least HYSTERESIS_SHARE); ``concentrated_in``: the regions holding at least
    CONCENTRATED_SHARE of the power at CONCENTRATED_RATIO x their time share or more, largest ratio first."""
    r, x = pooled_samples(preps, lambda p: p.r), pooled_samples(preps, lambda p: p.t.stroke)
    r2 = r * r
    slow = pooled_samples(preps, lambda p: np.abs(p.t.velocity) < REVERSAL_SPEED_SHARE * np.abs(p.t.velocity[p.use]).max())
    regions = {"near_reversal": _share(r2, slow), "stroke_ends": _share(r2, pooled_samples(preps, _at_stroke_ends)),
               "stroke_band": _stroke_band(x, r2),
               "above_knee": {**_share(r2, pooled_samples(preps, lambda p: np.abs(p.t.velocity) >= knee)),
                              "knee_velocity_m_s": float(knee)}}
    held = [k for k, d in regions.items() if d["power_share"] >= CONCENTRATED_SHARE
            and d["ratio"] is not None and d["ratio"] >= CONCENTRATED_RATIO]
    return {"tests": [p.t.name for p in preps], "samples": int(r.size), "rms_residual_n": float(np.sqrt(r2.mean())),
            "regions": regions, "branch_asymmetry": _branch_asymmetry(residual_map(preps), r2),
            "concentrated_in": sorted(held, key=lambda k: -regions[k]["ratio"]),
            "thresholds": {"reversal_speed_share": REVERSAL_SPEED_SHARE, "stroke_end_share": STROKE_END_SHARE,
                           "stroke_bands": STROKE_BANDS, "min_bin_samples": MIN_BIN_SAMPLES,
                           "concentrated_ratio": CONCENTRATED_RATIO, "concentrated_share": CONCENTRATED_SHARE,
                           "hysteresis_share": HYSTERESIS_SHARE}}
