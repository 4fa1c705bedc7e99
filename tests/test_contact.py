"""The nonlinear wheel-rail contact (campaign.contact) against closed forms: the small-creep limit is linear
Kalker (the linear vehicle's creep terms), large creep saturates at mu N per wheel in the direction of the
linear force, the Shen-Hedrick-Elkins cubic is smooth where it meets the limit, the flange is a dead band."""
import math

import numpy as np
import pytest

from campaign.contact import WheelRailContact, flange_force, rolling_radius_difference, saturation

CONTACT = WheelRailContact(conicity=0.2, wheel_radius=0.46, contact_half_distance=0.75, f11=1.0e7, f22=0.8e7,
                           friction_coefficient=0.3, wheel_load=64e3, flange_clearance=8e-3,
                           flange_stiffness=1.5e7)


def test_saturation_is_linear_for_small_creep_and_saturates_smoothly_at_three():
    beta = np.array([1e-8, 1e-4, 1e-2])
    # s(beta) / beta = 1 - beta / 3 + beta^2 / 27
    np.testing.assert_allclose(saturation(beta) / beta, 1.0 - beta / 3.0 + beta ** 2 / 27.0, rtol=1e-12)
    assert saturation(3.0) == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_array_equal(saturation([3.0 + 1e-9, 4.0, 1e3]), 1.0)
    # s'(beta) = (1 - beta/3)^2: zero at 3 from below (first derivative continuous), s increasing before
    h = 1e-6
    assert (saturation(3.0) - saturation(3.0 - h)) / h == pytest.approx(0.0, abs=1e-5)
    b = np.linspace(0.0, 3.0, 301)
    assert np.all(np.diff(saturation(b)) > 0.0)
    np.testing.assert_allclose(np.gradient(saturation(b), b)[1:-1], (1.0 - b[1:-1] / 3.0) ** 2, atol=1e-4)
    with pytest.raises(ValueError, match="beta"):
        saturation(-1.0)


def test_small_creep_gives_the_linear_kalker_forces_of_the_linear_vehicle():
    c, V = CONTACT, 50.0
    y, psi, yd, om = 2e-10, -1e-10, 3e-9, -4e-9  # beta ~ 1e-7: s/beta = 1 - beta/3
    f = c.wheelset_forces(y, psi, yd, om, V)
    b0, r0 = c.contact_half_distance, c.wheel_radius
    lat = -2.0 * c.f22 * (yd / V - psi)
    yaw = -2.0 * c.f11 * b0 * (b0 * om / V + c.conicity * y / r0)
    assert float(f.lateral) == pytest.approx(lat, rel=1e-6)
    assert float(f.yaw_moment) == pytest.approx(yaw, rel=1e-6)
    assert float(f.flange) == 0.0


def test_large_creep_saturates_at_mu_n_per_wheel_in_the_direction_of_the_linear_force():
    c = CONTACT
    mu_n = c.friction_coefficient * c.wheel_load
    # pure lateral creepage 0.05 (beta = 0.8e7 * 0.05 / 19.2e3 >> 3): each wheel gives -mu N
    f = c.wheelset_forces(0.0, -0.05, 0.0, 0.0, 30.0)
    assert float(f.lateral) == pytest.approx(-2.0 * mu_n, rel=1e-12)
    assert float(f.yaw_moment) == pytest.approx(0.0, abs=1e-9)
    # combined creepage: the resultant is mu N, the direction that of (-f11 xi_x, -f22 xi_y)
    xi_x, xi_y = np.array([0.01, -0.006]), np.array([0.02, 0.008])  # beta 13 and 4.4
    fx, fy = c.wheel_forces(xi_x, xi_y)
    np.testing.assert_allclose(np.hypot(fx, fy), mu_n, rtol=1e-12)
    np.testing.assert_allclose(np.arctan2(fy, fx), np.arctan2(-c.f22 * xi_y, -c.f11 * xi_x), atol=1e-12)
    # in between: the cubic of beta
    xi = 1.0 * mu_n / c.f22  # beta = 1
    fx, fy = c.wheel_forces(0.0, xi)
    assert float(-fy) == pytest.approx(mu_n * (1 - 1 / 3 + 1 / 27), rel=1e-12)


def test_flange_force_is_zero_in_the_clearance_and_linear_beyond():
    d, k = 8e-3, 1.5e7
    y = np.linspace(-d, d, 101)
    np.testing.assert_array_equal(flange_force(y, d, k), 0.0)
    for excess in (1e-5, 1e-3, 5e-3):
        assert float(flange_force(d + excess, d, k)) == pytest.approx(-k * excess, rel=1e-9)
        assert float(flange_force(-d - excess, d, k)) == pytest.approx(k * excess, rel=1e-9)
    f = CONTACT.wheelset_forces(d + 2e-3, 0.0, 0.0, 0.0, 40.0)
    assert float(f.flange) == pytest.approx(-k * 2e-3, rel=1e-9)
    assert float(f.lateral) == pytest.approx(float(f.flange), rel=1e-12)  # no lateral creep here


def test_rolling_radius_difference_of_a_cone():
    np.testing.assert_allclose(rolling_radius_difference([0.0, 1e-3, -4e-3], 0.15), [0.0, 3e-4, -1.2e-3])


def test_bad_parameters_are_named():
    kw = dict(conicity=0.2, wheel_radius=0.46, contact_half_distance=0.75, f11=1e7, f22=1e7,
              friction_coefficient=0.3, wheel_load=64e3, flange_clearance=8e-3, flange_stiffness=1.5e7)
    for name, bad in (("friction_coefficient", 0.0), ("wheel_load", -1.0), ("flange_clearance", math.nan)):
        with pytest.raises(ValueError, match=name):
            WheelRailContact(**{**kw, name: bad})
    with pytest.raises(ValueError, match="speed"):
        CONTACT.wheelset_forces(0.0, 0.0, 0.0, 0.0, 0.0)
