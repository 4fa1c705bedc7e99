"""The nonlinear vehicle (campaign.vehicle_nonlinear) against independent references: at small amplitude it is
the linear vehicle of campaign.vehicle (Jacobian, trajectory, growth rate and so the eigenvalue critical speed);
at large amplitude its fixed-step Runge-Kutta integration agrees with a converged solve_ivp solution."""
import dataclasses
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from campaign.vehicle import N_STATES, VehicleModel, VehicleParams, critical_speed
from campaign.vehicle_nonlinear import ContactSettings, NonlinearVehicle, kick_state
from tuner.vehicle.hunting import dominant_rate

# a worn-wheel conicity brings the linear critical speed down to about 430 km/h
PARAMS = dataclasses.replace(VehicleParams(), conicity=0.3)


@pytest.fixture(scope="module")
def v_crit():
    return critical_speed(PARAMS, v_max=300.0, tol=0.01)


def test_jacobian_at_rest_is_the_linear_vehicle():
    """Central differences of the right-hand side at rest give VehicleModel.A (linear Kalker creep, the
    yaw dampers below blow-off) to 1e-6 of each row's largest entry."""
    V = 150.0
    m, A = NonlinearVehicle(PARAMS, V), VehicleModel(PARAMS, V).A
    J = np.empty_like(A)
    for j in range(N_STATES):
        e = np.zeros(N_STATES)
        e[j] = 1e-9 * (1e4 if j >= 28 else 1.0)  # damper forces in N
        J[:, j] = (m.rhs(0.0, e) - m.rhs(0.0, -e)) / (2.0 * e[j])
    scale = np.max(np.abs(A), axis=1, keepdims=True)
    assert np.all(np.abs(J - A) <= 1e-6 * np.maximum(scale, 1e-300))


def test_tiny_kick_follows_the_linear_vehicle_and_its_eigenvalues(v_crit):
    """A 1 nanometre kick (creep 1e-6 of its saturation) at 3 % below and above the eigenvalue critical speed: the trajectory is the linear
    model's (matrix exponential) to 1e-4 of its peak (measured 6e-6 to 6e-5), and its growth rate (dynamic
    mode decomposition, -0.28 and +0.26 1/s) is the largest real part of the linear eigenvalues to 1e-3 1/s
    (measured 5e-6): the small-amplitude critical speed is campaign.vehicle.critical_speed to within 3 %."""
    rates = []
    for f in (0.97, 1.03):
        V = f * v_crit
        run = NonlinearVehicle(PARAMS, V).simulate(kick_state(1e-9), 6.0)
        lin = VehicleModel(PARAMS, V)
        t = np.arange(0.0, 6.0 + 1e-9, 5e-4)
        X = lin.simulate(t, np.zeros((t.size, lin.B.shape[1])), kick_state(1e-9))[::2]
        for cols in (slice(0, 7), slice(7, 14)):  # lateral displacements, yaw angles
            assert np.max(np.abs(run.states[:, cols] - X[:, cols])) < 1e-4 * np.max(np.abs(X[:, cols]))
        sigma, _ = dominant_rate(run.t, run.states)
        sig_eig = float(np.max(lin.eigenvalues().real))
        assert sigma == pytest.approx(sig_eig, abs=1e-3)
        rates.append(sigma)
    assert rates[0] < 0.0 < rates[1]


def test_runge_kutta_agrees_with_solve_ivp_on_a_limit_cycle_with_flange_contact(v_crit):
    """Above the linear critical speed from an 8 mm kick (flange contact at 7 mm, saturated creep, damper
    blow-off): RK4 at 1 ms against DOP853 at rtol 1e-10 over 1.5 s, within 2e-3 of the peak of each
    state group (displacements, yaw, damper forces; measured 2.5e-4, 4.1e-4, 4.4e-4: the kinks of flange and
    blow-off; 3e-5 to 9e-5 with a linear dashpot)."""
    V = 1.1 * v_crit
    m = NonlinearVehicle(PARAMS, V)
    x0 = kick_state(8e-3)
    run = m.simulate(x0, 1.5)
    ref = solve_ivp(m.rhs, (0.0, 1.5), x0, method="DOP853", rtol=1e-10, atol=1e-12, t_eval=run.t, max_step=2e-3)
    assert ref.success
    Y = ref.y.T
    assert np.max(np.abs(Y[:, 3])) > 7e-3  # the flange is reached
    assert np.max(np.abs(Y[:, 28:])) > PARAMS.blowoff_force  # the dampers blow off
    for cols in (slice(0, 7), slice(7, 14), slice(28, 32)):
        assert np.max(np.abs(run.states[:, cols] - Y[:, cols])) < 2e-3 * np.max(np.abs(Y[:, cols]))


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="friction_coefficient"):
        ContactSettings(friction_coefficient=-0.1)
    with pytest.raises(ValueError, match="speed"):
        NonlinearVehicle(PARAMS, -1.0)
    with pytest.raises(ValueError, match="x0"):
        NonlinearVehicle(PARAMS, 50.0).simulate(np.zeros(3), 1.0)
    with pytest.raises(ValueError, match="amplitude"):
        kick_state(math.nan)


@pytest.mark.parametrize("primary", ["free", "rigid"])
def test_kinematic_hunting_wavelengths_of_klingel_and_wickens(primary):
    """Published closed forms of the kinematic (low-speed) hunting of conical wheelsets, reproduced by the car's
    linearisation (= the nonlinear car's Jacobian at rest, tested above) with the bogies freed from the carbody:
    a free wheelset (primary suspension 1e-3 N/m) runs a sine of wavelength 2 pi sqrt(r0 b0 / lambda)
    (Klingel 1883), a rigid two-axle bogie (primary 1e10 N/m) one of 2 pi sqrt(r0 b0 (1 + a^2 / b0^2) / lambda)
    (Wickens 1965; both e.g. in Knothe & Stichel, Rail Vehicle Dynamics, Springer 2017, ch. on the kinematics of
    the wheelset). At 1 m/s the hunting frequency V / wavelength is reproduced to 1e-3 (measured 1e-4)."""
    k = 1e-3 if primary == "free" else 1e10
    p = dataclasses.replace(VehicleParams(), k_px=k, k_py=k, k_sx=0.0, k_sy=0.0, c_sy=0.0, yaw_damping=1e-3,
                            yaw_series_stiffness=1e-3)
    r0, b0, a, lam = p.wheel_radius, p.contact_half_distance, p.semi_wheelbase, p.conicity
    wavelength = 2.0 * math.pi * math.sqrt(r0 * b0 / lam * (1.0 if primary == "free" else 1.0 + a * a / b0 ** 2))
    V = 1.0
    ev = VehicleModel(p, V).eigenvalues()
    f = ev.imag[ev.imag > 1e-6] / (2.0 * math.pi)
    assert np.min(np.abs(f / (V / wavelength) - 1.0)) < 1e-3
