"""Track geometry and ERRI B176 irregularity synthesis (campaign.track, campaign.irregularity)."""
import math

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid, quad
from scipy.signal import welch

from campaign.irregularity import A_LATERAL, W_C, W_R, erri_psd, lateral_psd, synthesize
from campaign.track import (
    CONTACT_BASE,
    GRAVITY,
    Section,
    Track,
    clothoid,
    curve,
    curve_with_transitions,
    s_curve_switch,
    straight,
)

# ----------------------------------------------------------------------------- track


def test_curve_with_transitions_is_piecewise_linear():
    R, h = 400.0, 0.06
    tr = Track(curve_with_transitions(R, h, lead_in=50.0, transition=80.0, arc=120.0, lead_out=40.0))
    b = tr.boundaries
    np.testing.assert_allclose(b, [0, 50, 130, 250, 330, 370])
    assert tr.length == pytest.approx(370.0)
    # straights: no curvature or cant
    assert tr.curvature(25.0) == 0.0 and tr.cant(25.0) == 0.0 and tr.curvature(350.0) == 0.0
    # clothoids: linear in s, so the midpoint value is the mean of the ends
    assert tr.curvature(90.0) == pytest.approx(0.5 / R)
    assert tr.cant(90.0) == pytest.approx(0.5 * h)
    assert tr.curvature(50.0 + 20.0) == pytest.approx(0.25 / R)
    assert tr.cant(250.0 + 60.0) == pytest.approx(h * (1 - 60 / 80))
    # constant curve
    s = np.linspace(131.0, 249.0, 7)
    np.testing.assert_allclose(tr.curvature(s), 1.0 / R)
    np.testing.assert_allclose(tr.cant(s), h)
    # continuity at every boundary (no steps in a transition-curve layout)
    eps = 1e-9
    for sb in b[1:-1]:
        assert tr.curvature(sb - eps) == pytest.approx(tr.curvature(sb + eps), abs=1e-10)
        assert tr.cant(sb - eps) == pytest.approx(tr.cant(sb + eps), abs=1e-9)


def test_right_hand_curve_has_negative_curvature_and_cant():
    tr = Track([straight(10.0), curve(50.0, 500.0, 0.084, hand="right")])
    assert tr.curvature(30.0) == pytest.approx(-1 / 500.0)
    assert tr.cant(30.0) == pytest.approx(-0.084)


def test_heading_and_lateral_are_integrals_of_curvature():
    """Analytic heading/lateral position against numerical quadrature of curvature."""
    tr = Track(curve_with_transitions(400.0, 0.06, 30.0, 80.0, 120.0, 40.0) + s_curve_switch(20.0, 30.0))
    # grid containing every section boundary: curvature is linear inside each interval, so
    # the midpoint rule integrates it exactly even across the curvature steps of the S-curve
    s = np.unique(np.concatenate([np.linspace(-5.0, tr.length + 20.0, 100001), tr.boundaries]))
    mid = 0.5 * (s[1:] + s[:-1])
    theta_num = np.concatenate([[0.0], np.cumsum(tr.curvature(mid) * np.diff(s))])
    np.testing.assert_allclose(tr.heading(s), theta_num, rtol=0, atol=1e-12)
    y_num = cumulative_trapezoid(tr.heading(s), s, initial=0.0)
    # heading is piecewise quadratic: trapezoid error <= L ds^2 max|kappa'| / 12 ~ 1e-9 m
    np.testing.assert_allclose(tr.lateral(s), y_num, rtol=0, atol=1e-8)
    # a circular arc of length l turns the track by l / R
    circ = Track([straight(10.0), curve(100.0, 250.0)])
    assert circ.heading(110.0) == pytest.approx(100.0 / 250.0)
    assert circ.lateral(110.0) == pytest.approx(100.0**2 / (2 * 250.0))


def test_s_curve_switch_layout():
    secs = s_curve_switch(lead_in=40.0, lead_out=60.0)
    tr = Track(secs)
    kinds = [sec.kind for sec in secs]
    assert kinds == ["straight", "curve", "straight", "curve", "straight"]
    b = tr.boundaries
    assert b[3] - b[2] == pytest.approx(6.0)  # intermediate straight
    assert tr.curvature(b[1] + 1) == pytest.approx(1 / 190.0)
    assert tr.curvature(b[3] + 1) == pytest.approx(-1 / 190.0)
    assert tr.curvature(b[2] + 1) == 0.0
    assert np.all(tr.cant(np.linspace(0, tr.length, 1001)) == 0.0)
    # opposite hands of equal length: the track leaves parallel to how it entered
    assert tr.heading(tr.length) == pytest.approx(0.0, abs=1e-12)


def test_cant_deficiency():
    R, h = 500.0, 0.084
    tr = Track([curve(100.0, R, h)])
    v_eq = math.sqrt(GRAVITY * h / CONTACT_BASE * R)  # balanced speed
    assert tr.cant_deficiency(50.0, v_eq) == pytest.approx(0.0, abs=1e-12)
    V = 86 / 3.6
    assert tr.uncompensated_acceleration(50.0, V) == pytest.approx(V**2 / R - GRAVITY * h / CONTACT_BASE)
    assert tr.cant_deficiency(50.0, V) == pytest.approx(CONTACT_BASE * V**2 / (GRAVITY * R) - h)
    assert tr.cant_angle(50.0) == pytest.approx(h / CONTACT_BASE)


def test_outside_defined_track():
    tr = Track([straight(10.0), clothoid(20.0, math.inf, 300.0)])
    assert tr.curvature(-3.0) == 0.0 and tr.heading(-3.0) == 0.0
    # beyond the end the last curvature continues
    assert tr.curvature(100.0) == pytest.approx(1 / 300.0)
    assert tr.heading(40.0) - tr.heading(30.0) == pytest.approx(10.0 / 300.0)


@pytest.mark.parametrize(
    "make",
    [
        lambda: straight(-1.0),
        lambda: straight(float("nan")),
        lambda: curve(10.0, -5.0),
        lambda: curve(10.0, 400.0, cant=-0.01),
        lambda: curve(10.0, 400.0, hand="up"),
        lambda: clothoid(10.0, math.inf, 0.0),
        lambda: Section("spiral", 10.0),
        lambda: Section("straight", 10.0, 0.001, 0.001),
        lambda: Section("curve", 10.0, 0.001, 0.002),
        lambda: Track([]),
        lambda: Track([straight(5.0), "curve"]),
        lambda: Track([straight(5.0)]).curvature([1.0, float("nan")]),
        lambda: s_curve_switch(10.0, 10.0, first_hand="middle"),
    ],
)
def test_bad_track_input(make):
    with pytest.raises(ValueError):
        make()


# ----------------------------------------------------------------------------- irregularity


def test_psd_formula():
    W = np.array([0.01, 0.1, 1.0])
    A = A_LATERAL["low"]
    np.testing.assert_allclose(erri_psd(W, A), A * W_C**2 / ((W**2 + W_R**2) * (W**2 + W_C**2)))
    np.testing.assert_allclose(lateral_psd(W, "high") / lateral_psd(W, "low"), 6.125e-7 / 2.119e-7)
    with pytest.raises(ValueError):
        lateral_psd(W, "medium")


def test_harmonic_amplitudes_carry_the_band_variance():
    """sum a_k^2 / 2 is the Riemann sum of int S dW over the band (dW = 2 pi / period)."""
    p = synthesize(20000.0, seed=1, ds=0.1)
    var_formula = quad(lambda W: erri_psd(W, A_LATERAL["low"]), 2 * math.pi / 200, 2 * math.pi / 3, limit=200)[0]
    assert np.sum(p.amplitudes**2) / 2 == pytest.approx(var_formula, rel=0.01)
    assert p.wavenumbers.min() >= 2 * math.pi / 200 and p.wavenumbers.max() <= 2 * math.pi / 3


def test_welch_psd_matches_erri_formula():
    """Welch estimate of a 100 km profile against S(W) inside the synthesised band.

    Statistics: with ~200 harmonics per Welch bin and random phases, each segment's
    periodogram value is a sum of many random phasors, i.e. (CLT) exponentially distributed
    about the true PSD, as for Gaussian noise. For Gaussian noise, Welch with a Hann window
    and 50 % overlap over K segments has a relative standard deviation sigma =
    sqrt(1.056 / K) per bin (Welch 1967); this is an upper bound here, because the harmonic
    amplitudes are deterministic (no Rayleigh amplitude scatter). We require every bin
    within 5 sigma and the mean ratio over the n bins within 5 sigma / sqrt(n / 2) (factor
    2: neighbouring Hann bins are correlated). Bins within 4 bin widths of the band edges
    are excluded (window leakage across the edge); the smoothing bias of the window at the
    low-W end (S ~ W^-2) is below 2 %, well inside the tolerance.
    """
    ds, length, nseg = 0.1, 100_000.0, 8192
    p = synthesize(length, seed=7, ds=ds)
    f, P = welch(p.y, fs=1.0 / ds, window="hann", nperseg=nseg, noverlap=nseg // 2, detrend=False)
    W = 2 * math.pi * f
    S_est = P / (2 * math.pi)  # one-sided, per (cycle/m) -> per (rad/m)
    dWbin = 2 * math.pi / (nseg * ds)
    band = (W > 2 * math.pi / 200 + 4 * dWbin) & (W < 2 * math.pi / 3 - 4 * dWbin)
    ratio = S_est[band] / lateral_psd(W[band])
    K = (p.y.size - nseg) // (nseg // 2) + 1
    sigma = math.sqrt(1.056 / K)
    assert band.sum() > 100
    assert np.all(np.abs(ratio - 1.0) < 5 * sigma), (ratio.min(), ratio.max(), sigma)
    assert abs(ratio.mean() - 1.0) < 5 * sigma / math.sqrt(band.sum() / 2)
    # outside the band there is (almost) nothing: far below the formula
    out = (W > 2 * math.pi / 3 * 1.5) & (W < 4.0)
    assert np.all(S_est[out] < 1e-3 * lateral_psd(W[out]))


def test_seeds_reproducible_and_uncorrelated():
    """Same seed -> same profile; different seeds -> correlation within 5 sigma of zero,
    sigma^2 = pi int S^2 dW / (L sigma_y^4) for two independent profiles with the same
    (one-sided) spectrum over length L (Bartlett)."""
    L, ds = 50_000.0, 0.1
    a = synthesize(L, seed=11, ds=ds)
    np.testing.assert_array_equal(a.y, synthesize(L, seed=11, ds=ds).y)
    b = synthesize(L, seed=12, ds=ds)
    assert not np.allclose(a.y, b.y)
    Wlo, Whi = 2 * math.pi / 200, 2 * math.pi / 3
    var = quad(lambda W: lateral_psd(W), Wlo, Whi, limit=200)[0]
    int_s2 = quad(lambda W: lateral_psd(W) ** 2, Wlo, Whi, limit=200)[0]
    sigma_rho = math.sqrt(math.pi * int_s2 / L) / var
    rho = np.corrcoef(a.y, b.y)[0, 1]
    assert abs(rho) < 5 * sigma_rho, (rho, sigma_rho)
    assert sigma_rho < 0.05  # the test is informative


def test_profile_interpolation_and_taper():
    p = synthesize(500.0, seed=3, taper=40.0)
    assert p(0.0) == 0.0
    assert p(-5.0) == 0.0 and p(p.length + 1.0) == 0.0
    s = np.array([12.34, 250.01])
    np.testing.assert_allclose(p(s), np.interp(s, p.s, p.y))
    full = synthesize(500.0, seed=3)
    i = p.s >= 40.0
    np.testing.assert_array_equal(p.y[i], full.y[i])
    assert np.all(np.abs(p.y[~i]) <= np.abs(full.y[~i]))


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(length=-1.0),
        dict(length=100.0, ds=2.0),
        dict(length=100.0, lambda_min=300.0),
        dict(length=100.0, A=-1.0),
        dict(length=100.0, taper=-1.0),
    ],
)
def test_bad_irregularity_input(kwargs):
    with pytest.raises(ValueError):
        synthesize(**kwargs)
