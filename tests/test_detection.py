"""Detection limits (tuner.diagnosis.detection) against closed forms of the linear model."""
import math

import numpy as np
import pytest

from tuner.diagnosis.detection import absorbed_signature, limit_from_signature


def test_a_signature_the_base_can_make_is_absorbed_and_never_detected():
    rng = np.random.default_rng(0)
    J_id, J_val = rng.normal(size=(400, 5)), rng.normal(size=(300, 5))
    w = rng.normal(size=5)
    u = absorbed_signature(J_id @ w, J_val @ w, J_id, J_val)  # the effect is a base parameter change
    assert np.max(np.abs(u)) < 1e-9 * np.max(np.abs(J_val @ w))
    assert limit_from_signature(u, J_id @ w, 100.0, 1.0, 0.05, 0.02)["by_score"] > 1e6


def test_an_orthogonal_signature_gives_the_closed_form_limit():
    """u orthogonal to the base: a hidden effect of the limit's size raises the refitted base's held-out
    MSE by exactly the factor exp(accept + penalty), i.e. it scores just the acceptance threshold."""
    n = 1000
    t = np.linspace(0.0, 1.0, n)
    J = np.column_stack([np.ones(n), t])
    j = np.sin(2 * math.pi * 7 * t) * 50.0  # N per unit; orthogonal-ish to the affine base
    u = absorbed_signature(j, j, J, J)
    mse_ref, accept, penalty = 400.0, 0.05, 0.02
    row = limit_from_signature(u, j, mse_ref, noise_n=1.0, accept=accept, penalty=penalty)
    m = row["by_score"]
    mse_none = mse_ref + m ** 2 * float(u @ u) / n
    assert -math.log(mse_ref / mse_none) - penalty == pytest.approx(accept, rel=1e-12)
    assert row["by_noise"] == pytest.approx(1.0 / math.sqrt(np.mean(j ** 2)))
    assert row["limit"] == max(row["by_score"], row["by_noise"])


def test_the_force_rule_sets_the_limit_when_the_noise_is_large():
    n = 500
    j = np.ones(n) * 2.0
    u = j.copy()
    row = limit_from_signature(u, j, mse_ref=1e-6, noise_n=10.0, accept=0.05, penalty=0.02)
    assert row["limit"] == row["by_noise"] == pytest.approx(5.0)
