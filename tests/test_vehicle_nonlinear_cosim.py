"""The nonlinear car with damper FMUs (tuner.vehicle.nonlinear_cosim) against an independent reference: the
same car with its built-in Maxwell yaw dampers (in its equations, no co-simulation) solved by solve_ivp."""
import dataclasses
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from campaign.vehicle import VehicleParams, critical_speed
from campaign.vehicle_nonlinear import NonlinearVehicle, kick_state
from damper_fmu.fmu import ensure_fmu
from tuner.vehicle.nonlinear_cosim import NonlinearCosim, nonlinear_master_loop

LINEAR = dataclasses.replace(VehicleParams(), conicity=0.3, yaw_blowoff_velocity=math.inf)
AT_BUILTIN = {"k_s": LINEAR.yaw_series_stiffness, "c": LINEAR.yaw_damping}


def test_maxwell_fmus_in_the_nonlinear_car_agree_with_solve_ivp():
    """An 8 mm kick at 1.1 times the linear critical speed (about 480 km/h at conicity 0.3): saturated creep,
    flange contact, damper forces near 20 kN. Four Maxwell FMUs at the built-in damper's parameters, 1 ms
    communication steps, RK4 within each step with the force linear over it, against DOP853 at rtol 1e-10
    on the built-in vehicle: within 5e-3 of the peak of lateral displacements, yaw angles and damper forces
    (measured 2.0e-3, 2.3e-3 and 2.2e-3: the explicit coupling's lag; the vehicle's own RK4 error is 3e-5
    to 9e-5)."""
    V = 1.1 * critical_speed(LINEAR, v_max=300.0)
    x0 = kick_state(8e-3)
    with NonlinearCosim(ensure_fmu("maxwell"), params=LINEAR, fmu_parameters=AT_BUILTIN) as co:
        run = co.run(V, x0, 1.0)
    ref = solve_ivp(NonlinearVehicle(LINEAR, V).rhs, (0.0, 1.0), x0, method="DOP853", rtol=1e-10, atol=1e-12,
                    t_eval=run.t, max_step=2e-3)
    assert ref.success and run.states.shape == ref.y.T.shape
    Y = ref.y.T
    assert np.max(np.abs(Y[:, 3])) > 7e-3 and np.max(np.abs(Y[:, 28:])) > 1e4  # flange reached, large forces
    for cols in (slice(0, 7), slice(7, 14), slice(28, 32)):
        assert np.max(np.abs(run.states[:, cols] - Y[:, cols])) < 5e-3 * np.max(np.abs(Y[:, cols]))


def test_c_and_python_master_loops_agree():
    """The C loop (c/nonlinear_master.c) and the Python loop: the same steps, two RK4 substeps per 1 ms, the
    lumped FMU (nonlinear, interpolating its inputs) on a flange-contact cycle: equal to 1e-9 of each state's
    peak (measured 1e-12)."""
    if nonlinear_master_loop() is None:
        pytest.skip("no C compiler")
    runs = []
    for c_loop in (True, False):
        with NonlinearCosim(ensure_fmu("lumped"), params=LINEAR, substeps=2, c_loop=c_loop) as co:
            runs.append(co.run(140.0, kick_state(8e-3), 0.15))
    a, b = runs
    assert np.all(np.abs(a.states - b.states) <= 1e-9 * np.max(np.abs(b.states), axis=0))  # per state


def test_bad_arguments_are_named(tmp_path):
    fmu = ensure_fmu("maxwell")
    with pytest.raises(ValueError, match="one damper FMU or 4"):
        NonlinearCosim([fmu] * 3)
    with pytest.raises(ValueError, match="substeps"):
        NonlinearCosim(fmu, substeps=0)
    with pytest.raises(FileNotFoundError, match="nowhere.fmu"):
        NonlinearCosim(tmp_path / "nowhere.fmu")
    with NonlinearCosim(fmu) as co:
        with pytest.raises(ValueError, match="x0"):
            co.run(50.0, np.zeros(3), 1.0)
