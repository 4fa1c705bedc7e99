"""The Cooperrider car on the S1002/UIC60 contact table against DYTSI, the DTU railway vehicle
simulator, and the table's interpolation against GSL's cubic spline.

The reference numbers below were produced by ``python benchmarks/dytsi_cooperrider.py`` (which builds
DYTSI outside the repository); the tests themselves need no DYTSI build, only the published input
file and contact table in ``../shared/reference/dytsi`` (or ``$DYTSI_REFERENCE``), which the project
does not contain (LGPL-3.0): without them those tests are skipped.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from campaign.contact_table import ContactTableError, read_contact_table
from campaign.cooperrider import N_STATES, CooperriderCar, state_index
from campaign.cooperrider_params import ModelFileError, read_cooperrider_xml
from campaign.cooperrider_runs import offset_state, run_speeds

REFERENCE = Path(os.environ.get("DYTSI_REFERENCE", Path(__file__).resolve().parents[2] / "shared/reference/dytsi"))
XML = REFERENCE / "input/InputFiles/inputBifurcation-Cooperrider-straight.xml"
needs_reference = pytest.mark.skipif(not XML.exists(), reason=f"DYTSI's published input not found at {REFERENCE} "
                                     "(set DYTSI_REFERENCE to the dytsi/ folder of the reference engines)")

# GSL 2.7 (Debian 12 libgsl-dev) gsl_interp_cspline of RSGEO/1o40/RSGEO.dat, the interpolation DYTSI 1.0r2
# uses with Interp="cspline": benchmarks/dytsi_cooperrider.py, gsl_spline_values(); columns by name.
GSL_POINTS = [0.0, 1.234e-3, -5.6789e-3, 8.0005e-3, 1.69999e-2]
GSL_VALUES = {
    "N": [66661.236634, 66656.25816943051, 66664.80915203625, 63308.46476843377, 56115.906242321835],
    "angle": [0.014223235000003014, 0.01875255439163292, 0.009753169864227638, 0.3188125852833744,
              0.5703315543576295],
    "a": [0.00595184999999999, 0.005833278107544119, 0.006524192893082117, 0.00740882114105542,
          0.00839371853233013],
    "rw": [0.4248829, 0.424921676646759, 0.42481624495885345, 0.4287687511724622, 0.4507703934010197],
    "c22": [3.563104846300018, 3.403139208026614, 4.206430446854147, 6.3496608228065545, 12.004009499356423],
}


def _write_table(path: Path, lat, columns) -> Path:
    lines = ["#", " ".join(f'"c{k}"' for k in range(13))]
    for i, y in enumerate(lat):
        lines.append(" ".join(f"{v:.17g}" for v in [y] + [c[i] for c in columns]))
    path.write_text("\n".join(lines) + "\n\n")
    return path


def test_table_spline_reproduces_a_line_and_rejects_bad_input(tmp_path):
    """A natural cubic spline through samples of a straight line is that line; bad files and
    displacements outside the table raise errors naming the cause."""
    lat = np.linspace(-0.01, 0.01, 21)
    cols = [3.0 + 7.0 * lat * (k + 1) for k in range(12)]
    table = read_contact_table(_write_table(tmp_path / "line.dat", lat, cols))
    y = np.array([-0.00999, -0.0012345, 0.0, 0.004567, 0.01])
    got = table.evaluate(y)
    for k in range(12):
        np.testing.assert_allclose(got[:, k], 3.0 + 7.0 * y * (k + 1), rtol=1e-13, atol=1e-15)
    with pytest.raises(ContactTableError, match="derailment"):
        table.evaluate(0.0101)
    bad = tmp_path / "bad.dat"
    bad.write_text("#\n" + " ".join("x" * 13) + "\n" + "0 " * 12 + "\n")
    with pytest.raises(ContactTableError, match=r"bad.dat:3: 12 columns"):
        read_contact_table(bad)


def test_model_file_errors_name_the_parameter(tmp_path):
    f = tmp_path / "in.xml"
    f.write_text("<input><Bifurcation><Model><CooperriderOrthogonalModel><r0>0.425</r0>"
                 "</CooperriderOrthogonalModel></Model></Bifurcation></input>")
    with pytest.raises(ModelFileError, match="no <h1>"):
        read_cooperrider_xml(f)


@needs_reference
def test_table_interpolation_matches_gsl_cspline():
    table = read_contact_table(REFERENCE / "input/RSGEO/1o40/RSGEO.dat")
    got = table.evaluate(np.array(GSL_POINTS))
    for name, want in GSL_VALUES.items():
        np.testing.assert_allclose(got[:, table.column(name)], want, rtol=1e-10, err_msg=name)


# DYTSI 1.0r2, `DYTSI -T -nt InputFiles/inputBifurcation-Cooperrider-straight.xml` (BDF, rtol 1e-6,
# atol 1e-8), segment at 110 m/s: the leading wheelset's lateral displacement [m] from the 0.1 mm offset.
DYTSI_110 = {"t": [0.1, 0.5, 1.0], "y": [-3.5427739746e-05, 1.4730160442e-05, -1.8790096023e-05]}
# The same run's Jacobian stored at the end of the 100 m/s segment (Jacobians/jac-81.dat, the state 2e-9 m
# from equilibrium): its least damped eigenvalue [1/s] of the hunting family (20..40 rad/s).
DYTSI_HUNTING_EIGENVALUE_100 = complex(-1.2469, 27.7353)


@pytest.fixture(scope="module")
def reference_car():
    model = read_cooperrider_xml(XML)
    return model.params, read_contact_table(model.table_path)


@needs_reference
def test_short_straight_run_follows_dytsi(reference_car):
    """1 s at 110 m/s from DYTSI's initial state: the leading wheelset within 1e-8 m (1e-4 of the
    offset) of DYTSI's stored response, RK4 at 0.5 ms against its BDF."""
    params, table = reference_car
    run = run_speeds(params, table, [110.0], offset_state(), 1.0, dt=5e-4)
    got = np.interp(DYTSI_110["t"], run.t, run.signal()[:, 0])
    np.testing.assert_allclose(got, DYTSI_110["y"], rtol=0.0, atol=1e-8)
    assert run.states.shape == (101, N_STATES, 1)


@needs_reference
def test_hunting_eigenvalue_matches_dytsi_jacobian(reference_car):
    from campaign.cooperrider_runs import equilibrium, jacobian
    params, table = reference_car
    car = CooperriderCar(params, table, 100.0)
    ev = np.linalg.eigvals(jacobian(car, equilibrium(car)))
    band = ev[(ev.imag > 20.0) & (ev.imag < 40.0)]
    least = band[np.argmax(band.real)]
    assert abs(least - DYTSI_HUNTING_EIGENVALUE_100) < 5e-3, least


# The same run, 125 m/s segment at t = 9.77 s, the trailing bogie's leading wheelset in flange contact
# (output.dat columns "Trailing Bogie - Leading Wheelset[ID 5]::..."): its state (y, ydot, z, zdot, phi,
# phidot, beta, psi, psidot; SI) and DYTSI's rail forces on it, left then right wheel: creep (track frame)
# x, y, z [N], then normal y, z [N] of left and right.
DYTSI_FLANGE_STATE = [8.0418128267e-03, 1.8510302608e-02, 1.7082921880e-07, -3.8888960308e-03, 3.7312847776e-05,
                      3.1900267243e-03, -5.3038533554e-01, -9.7942422672e-04, -2.8437174259e-01]
DYTSI_FLANGE_CREEP = [[5.4617744497e+03, 5.8007721912e+02, 1.9943411493e+02],
                      [-3.3620745316e+03, -1.3319063303e+04, 1.4922066321e+02]]
DYTSI_FLANGE_NORMAL = [[-1.1815419857e+04, 3.4683407095e+04], [1.0872071434e+03, 9.7065289899e+04]]


@needs_reference
def test_wheel_forces_in_flange_contact_match_dytsi(reference_car):
    """Each wheel's creep and normal forces at a stored flange-contact state, to 1e-8 of the largest
    (DYTSI prints 11 significant digits)."""
    params, table = reference_car
    car = CooperriderCar(params, table, 125.0)
    x = np.zeros(N_STATES)
    for (coord, rate), value in zip([("y", 0), ("y", 1), ("z", 0), ("z", 1), ("phi", 0), ("phi", 1), ("beta", 0),
                                     ("psi", 0), ("psi", 1)], DYTSI_FLANGE_STATE):
        x[state_index(5, coord, rate=bool(rate))] = value
    pos, vel = car.body_states(x[:, None])
    wf = car.wheel_forces(pos, vel, x[-4:, None])
    scale = 1e-8 * np.max(np.abs(DYTSI_FLANGE_NORMAL))
    np.testing.assert_allclose(wf.creep[:, :, 2, 0].T, DYTSI_FLANGE_CREEP, rtol=0.0, atol=scale)
    np.testing.assert_allclose(wf.normal[:, :, 2, 0].T, DYTSI_FLANGE_NORMAL, rtol=0.0, atol=scale)


@needs_reference
def test_batch_runs_each_speed_and_mirror_symmetry(reference_car):
    """A batch of two speeds gives each speed's own run; a leftward offset gives the mirror image of a
    rightward one (lateral family odd, vertical family even: left and right wheel read one table)."""
    params, table = reference_car
    both = run_speeds(params, table, [60.0, 120.0], offset_state(m=2), 0.2, dt=5e-4)
    one = run_speeds(params, table, [120.0], offset_state(), 0.2, dt=5e-4)
    np.testing.assert_allclose(both.states[:, :, 1], one.states[:, :, 0], rtol=0.0, atol=1e-15)
    assert np.max(np.abs(both.signal()[:, 0] - both.signal()[:, 1])) > 1e-6
    mirror = run_speeds(params, table, [120.0], offset_state(-1e-4), 0.2, dt=5e-4)
    odd = np.zeros(N_STATES, dtype=bool)
    for body in range(7):
        for coord in ("y", "phi", "psi"):
            odd[[state_index(body, coord), state_index(body, coord, rate=True)]] = True
    sign = np.where(odd, -1.0, 1.0)
    np.testing.assert_allclose(mirror.states[:, :, 0], sign * one.states[:, :, 0], rtol=0.0, atol=1e-12)
