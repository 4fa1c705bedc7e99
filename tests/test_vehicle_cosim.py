"""Vehicle co-simulation with yaw damper FMUs (tuner.vehicle) against independent references: the built-in
Maxwell yaw dampers of campaign.vehicle, and the eigenvalues of its linear model."""
import dataclasses
import math
import zipfile

import numpy as np
import pytest

from campaign.irregularity import A_LATERAL, synthesize
from campaign.scenarios import SCENARIOS, START_OFFSET
from campaign.vehicle import VehicleParams
from damper_fmu.fmu import ensure_fmu
from tuner.vehicle.cosim import VehicleCosim, check_damper_fmu, master_loop, reference_run

LINEAR = dataclasses.replace(VehicleParams(), yaw_blowoff_velocity=math.inf)
AT_BUILTIN = {"k_s": LINEAR.yaw_series_stiffness, "c": LINEAR.yaw_damping}


@pytest.fixture(scope="module")
def maxwell_fmu():
    return ensure_fmu("maxwell")


def _curve_case(t_end):
    sc = SCENARIOS["val3_curve_R500_86"]
    V = sc.speed
    irr = synthesize(START_OFFSET + 20.0 + V * t_end + 10.0, sc.seed_sequence(0), A=A_LATERAL["low"],
                     taper=2.0 * START_OFFSET + 0.5 * V)
    return V, sc.track(), irr


def test_maxwell_fmu_vehicle_agrees_with_builtin_vehicle(maxwell_fmu):
    """Curve entry R 500 m at 86 km/h with irregularity: four Maxwell FMUs at the built-in damper's
    parameters (linear dashpot) stepped at 1 ms give the built-in vehicle's response (measured: bogie yaw
    within 5e-5 of its peak, damper force within 1.1e-4)."""
    V, track, irr = _curve_case(12.0)
    with VehicleCosim(maxwell_fmu, params=LINEAR, fmu_parameters=AT_BUILTIN) as co:
        run = co.run(V, track, irr, 12.0)
    ref = reference_run(LINEAR, V, track, irr, 12.0)
    assert run.completed and run.t.shape == ref.t.shape
    for a, b, tol in ((run.bogie_yaw, ref.bogie_yaw, 1e-3), (run.forces, ref.forces, 1e-3),
                      (run.strokes, ref.strokes, 1e-3),
                      (run.carbody_lateral_acceleration, ref.carbody_lateral_acceleration, 1e-3)):
        peak = np.max(np.abs(b))
        assert peak > 0.0
        assert np.max(np.abs(a - b)) < tol * peak
    # the curve is really run through: quasi-static stroke about d L / R (front right extends in a left curve)
    assert np.max(run.strokes[:, 0]) == pytest.approx(LINEAR.yaw_damper_offset * LINEAR.half_bogie_distance / 500.0,
                                                      rel=0.3)


def test_table_maxwell_fmu_reproduces_the_builtin_blowoff_damper():
    """The built-in damper's blow-off (bilinear dashpot: c1 up to v_b, c2 beyond) as the table-Maxwell
    FMU's Fc,O (exact: v_b = 5 mm/s is a table abscissa, the end pieces extrapolate with c2): the curve
    entry with the dashpot beyond blow-off on a tenth of the samples gives the built-in vehicle's
    response (measured: bogie yaw within 4.6e-5 of its peak, damper force within 1.4e-4)."""
    from damper_fmu.parameters import FC_ABSCISSAE

    p = dataclasses.replace(VehicleParams(), yaw_blowoff_velocity=0.005)
    assert 0.005 in [round(v, 12) for v in FC_ABSCISSAE]

    def dashpot(v):
        c1, c2, vb = p.yaw_damping, p.yaw_damping_blowoff, p.yaw_blowoff_velocity
        return c1 * v if abs(v) <= vb else math.copysign(c1 * vb + c2 * (abs(v) - vb), v)

    table = {"k_s": p.yaw_series_stiffness}
    for i, v in enumerate(FC_ABSCISSAE, start=1):
        table[f"Fc_v{i:02d}"], table[f"Fc_{i:02d}"] = v, dashpot(v)
    V, track, irr = _curve_case(12.0)
    with VehicleCosim(ensure_fmu("maxwell_table"), params=p, fmu_parameters=table) as co:
        run = co.run(V, track, irr, 12.0)
    ref = reference_run(p, V, track, irr, 12.0)
    assert run.completed
    assert np.mean(np.abs(ref.forces) > p.blowoff_force) > 0.05  # the blow-off is exercised
    for a, b in ((run.bogie_yaw, ref.bogie_yaw), (run.forces, ref.forces), (run.strokes, ref.strokes)):
        assert np.max(np.abs(a - b)) < 1e-3 * np.max(np.abs(b))


def test_c_and_python_master_loops_agree(maxwell_fmu):
    if master_loop() is None:
        pytest.skip("no C compiler")
    V, track, irr = _curve_case(2.0)
    runs = []
    for c_loop in (True, False):
        with VehicleCosim(maxwell_fmu, params=LINEAR, fmu_parameters=AT_BUILTIN, c_loop=c_loop) as co:
            runs.append(co.run(V, track, irr, 2.0))
    a, b = runs
    np.testing.assert_allclose(a.states, b.states, rtol=0, atol=1e-9 * np.max(np.abs(b.states)))
    np.testing.assert_allclose(a.forces, b.forces, rtol=0, atol=1e-9 * np.max(np.abs(b.forces)))


def test_bad_fmus_are_named(maxwell_fmu, tmp_path):
    with pytest.raises(FileNotFoundError, match="nowhere.fmu"):
        VehicleCosim(tmp_path / "nowhere.fmu")
    bad = tmp_path / "NoForce.fmu"
    with zipfile.ZipFile(maxwell_fmu) as zin, zipfile.ZipFile(bad, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'name="force"', b'name="damper_force"')
            zout.writestr(item, data)
    with pytest.raises(ValueError, match=r"NoForce\.fmu: no variable 'force'"):
        check_damper_fmu(bad)
    with pytest.raises(ValueError, match="one damper FMU or 4"):
        VehicleCosim([maxwell_fmu] * 2)
    with pytest.raises(ValueError, match="no parameter"):
        VehicleCosim(maxwell_fmu, fmu_parameters={"k_x": 1.0})


def test_time_domain_critical_speed_matches_eigenvalues(maxwell_fmu):
    """Hunting: kick runs with four Maxwell FMUs (k_s 1e7 N/m, c 1e5 N s/m), bisection on the speed, against
    the eigenvalues of campaign.vehicle's linear model (about 380 km/h; measured agreement 0.002 %)."""
    from tuner.vehicle.hunting import critical_speed_time_domain, eigen_critical_speed

    ks, c = 1e7, 1e5
    v_eig = eigen_critical_speed(ks, c)
    assert 350 / 3.6 < v_eig < 410 / 3.6
    with VehicleCosim(maxwell_fmu, fmu_parameters={"k_s": ks, "c": c}) as co:
        res = critical_speed_time_domain(co, 330 / 3.6, 430 / 3.6, tol=0.5 / 3.6)
    assert res.bracket[0] <= res.speed <= res.bracket[1]
    assert res.speed == pytest.approx(v_eig, rel=0.005)
    assert any(not done for _, s, done in res.runs) or max(s for _, s, _ in res.runs) > 0


def test_dominant_rate_separates_beating_modes():
    """Two modes 0.04 Hz apart (the vehicle's two hunting modes beat like this): the decomposition finds the
    less damped one's rate, where an envelope slope over 4 s would not."""
    from tuner.vehicle.hunting import dominant_rate

    t = np.arange(0, 8.0, 1e-3)
    m1 = np.exp(-0.02 * t) * np.cos(2 * np.pi * 6.96 * t)
    m2 = 3.0 * np.exp(-0.15 * t) * np.cos(2 * np.pi * 6.92 * t + 1.0)
    Z = np.column_stack([m1 + m2, 0.5 * m1 - m2, np.gradient(m1 + m2, t), np.gradient(0.5 * m1 - m2, t)])
    rate, freq = dominant_rate(t, Z)
    assert rate == pytest.approx(-0.02, abs=2e-3)
    assert freq == pytest.approx(6.96, abs=0.01)


def test_vehicle_command(maxwell_fmu, tmp_path, capsys):
    """``python -m tuner vehicle``: side-by-side table, JSON and a figure per scenario; the Maxwell FMU's
    time-domain critical speed next to its eigenvalue one; a missing FMU is a clear error (exit 2)."""
    import json

    from tuner.__main__ import main

    out = tmp_path / "veh"
    code = main(["vehicle", "--fmus", str(maxwell_fmu), "--out", str(out), "--quiet", "--scenarios",
                 "critical_speed", "curve_entry", "--v-min", "700", "--v-max", "900", "--tol", "10"])
    assert code == 0
    text = capsys.readouterr().out
    assert "critical speed [km/h]" in text and "curve_entry: peak bogie yaw [mrad]" in text
    data = json.loads((out / "vehicle.json").read_text())
    r = data["results"]["DamperMaxwell"]
    cs = r["critical_speed"]
    assert cs["critical_speed_kmh"] == pytest.approx(cs["eigenvalue_critical_speed_kmh"], rel=0.02)
    assert r["curve_entry"]["peak_damper_force_n"] > 1e3
    assert (out / "critical_speed.png").is_file() and (out / "curve_entry.png").is_file()
    assert main(["vehicle", "--fmus", str(tmp_path / "missing.fmu"), "--out", str(out)]) == 2
    assert "missing.fmu" in capsys.readouterr().err


def test_fmus_side_by_side_on_workers_give_the_figures_of_one_process(tmp_path):
    """The job runs the tuned FMUs' scenarios on the draws' workers, one FMU per worker
    (``compare_fmus(..., executor=...)``): every figure of vehicle.json is the one-process run's (the same
    simulations; the growth rates' least squares may round differently with another BLAS thread count, so to
    1e-9), in the order of the FMUs given."""
    from damper_fmu.fmu import build
    from tuner.executors import FleetExecutor
    from tuner.vehicle.compare import ScenarioOptions, compare_fmus

    fmus = [build("maxwell", tmp_path / name, start_values={"k_s": k_s, "c": c})
            for name, k_s, c in (("soft", 4e6, 2e5), ("stiff", 1.4e7, 5e5))]
    kw = dict(options=ScenarioOptions(scenarios=("critical_speed", "curve_entry"), tol=5 / 3.6), log=lambda m: None)
    alone = compare_fmus(fmus, tmp_path / "alone", **kw)
    with FleetExecutor("pool:2") as ex:
        pooled = compare_fmus(fmus, tmp_path / "pooled", executor=ex, **kw)
    assert len(alone["results"]) == 2 and list(pooled["results"]) == list(alone["results"])

    def figures(data):
        out = []
        for r in data["results"].values():
            cs = r["critical_speed"]
            out += [cs["critical_speed_kmh"], *(run["growth_rate_per_s"] for run in cs["runs"])]
            out += [v for k, v in sorted(r["curve_entry"].items()) if k != "wall_time_s"]
        return np.array(out, dtype=float)

    speeds = [r["critical_speed"]["critical_speed_kmh"] for r in alone["results"].values()]
    assert abs(speeds[0] - speeds[1]) > 10.0  # two dampers, two vehicles: the order is checked too
    np.testing.assert_allclose(figures(pooled), figures(alone), rtol=1e-9, atol=0)
    assert (tmp_path / "pooled" / "critical_speed.png").is_file()
