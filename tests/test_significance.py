"""Confidence intervals under correlated residuals (tuner.diagnosis.significance), checked against truth:
a straight-line fit with AR(1) noise, many seeds; the 95 % interval must cover the true slope
about 95 % of the time, where the textbook white-noise interval covers far less."""
import numpy as np

from tuner.diagnosis.significance import Z95, block_sandwich, correlation_time


def ar1(rng, n, phi):
    e = rng.normal(size=n)
    out = np.empty(n)
    out[0] = e[0] / np.sqrt(1 - phi ** 2)
    for k in range(1, n):
        out[k] = phi * out[k - 1] + e[k]
    return out


def test_correlation_time_of_white_and_ar1_noise():
    rng = np.random.default_rng(0)
    assert correlation_time(rng.normal(size=20000)) < 1.3
    phi = 0.9  # integrated autocorrelation time (1 + phi) / (1 - phi) = 19; truncated sum a bit lower
    assert 12.0 < correlation_time(ar1(rng, 20000, phi)) < 21.0


def test_block_sandwich_interval_covers_the_truth_with_correlated_residuals():
    n, phi, slope = 4000, 0.9, 0.3
    x = np.sin(np.linspace(0, 40 * np.pi, n)) + 0.3 * np.sin(np.linspace(0, 101 * np.pi, n))
    jac = np.column_stack([x, np.ones(n)])
    cover_sandwich = cover_white = 0
    seeds = 300
    for seed in range(seeds):
        y = slope * x + 0.5 * ar1(np.random.default_rng(seed), n, phi)
        coef, *_ = np.linalg.lstsq(jac, y, rcond=None)
        r = y - jac @ coef
        cov, blocks = block_sandwich(jac, r, [n // 2, n - n // 2], int(np.ceil(3 * correlation_time(r))))
        assert blocks >= 10
        cover_sandwich += abs(coef[0] - slope) <= Z95 * np.sqrt(cov[0, 0])
        white = np.linalg.inv(jac.T @ jac) * (r @ r) / (n - 2)
        cover_white += abs(coef[0] - slope) <= Z95 * np.sqrt(white[0, 0])
    assert cover_sandwich / seeds >= 0.85, cover_sandwich / seeds
    assert cover_white / seeds <= 0.6, cover_white / seeds  # what the textbook interval would claim


def test_blocks_never_straddle_two_tests():
    jac = np.ones((10, 1))
    r = np.array([1.0] * 5 + [-1.0] * 5)
    cov, blocks = block_sandwich(jac, r, [5, 5], 5)
    assert blocks == 2 and cov[0, 0] > 0  # per-test blocks: +5 and -5, not one block summing to 0
