"""The Cooperrider car with damper FMUs as its yaw dampers (``tuner.vehicle.cooperrider_cosim``), the critical
speed search (``tuner.vehicle.cooperrider_hunting``) and their report and command.

References: the yaw dampers' elongation from the geometry in closed form; a dashpot force put in from outside
against the car's own ``D6`` dashpot; a Maxwell FMU made a pure dashpot against the built-in car (needs the
DYTSI input, skipped without it as in ``tests/test_cooperrider.py``); the search on responses of known growth.
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from campaign.contact_table import COLUMNS, read_contact_table
from campaign.cooperrider import N_STATES, YAW_DAMPER_NAMES, CooperriderCar, state_index
from campaign.cooperrider_params import XML_NAMES, CooperriderParams, read_cooperrider_xml
from campaign.cooperrider_runs import offset_state, run_speeds
from tuner.vehicle.cooperrider_cosim import CooperriderCosim, DamperCarRun
from tuner.vehicle.cooperrider_hunting import CooperriderSearch, search_critical_speed, speed_text

REFERENCE = Path(os.environ.get("DYTSI_REFERENCE", Path(__file__).resolve().parents[2] / "shared/reference/dytsi"))
XML = REFERENCE / "input/InputFiles/inputBifurcation-Cooperrider-straight.xml"
needs_reference = pytest.mark.skipif(not XML.exists(), reason=f"DYTSI's published input not found at {REFERENCE}")

# a made-up car of the same layout (lengths [m], stiffnesses [N/m], damping [N s/m]): the tests without the
# reference need only its geometry to be a car's
_MADE_UP = dict(r0=0.45, h1=0.1, h2=1.5, a=0.75, l1=0.3, l2=0.3, l3=0.3, v1=0.7, v2=0.1, v3=0.2, v4=0.2,
                u1=7.5, u2=1.25, x1=0.3, s1=1.0, s2=0.1, s3=1.0, s4=0.8, k1=2e6, k2=2e6, k3=1e6, k4=4e5, k5=6e5,
                k6=9e5, D1=2e4, D2=3e4, D3=0.0, D4=0.0, D5=0.0, D6=1.5e5)


def _flat_table(tmp_path: Path):
    """A contact table with the same value at every lateral displacement (a cone of zero conicity)."""
    values = dict(N=6.5e4, angle=0.02, a=6e-3, b=4e-3, aw=0.75, rw=0.45, c11=4.0, c22=3.5, c23=1.5, rz=0.0,
                  qN=1e-4, ry=0.0)
    lines = ["#", " ".join(f'"{c}"' for c in COLUMNS)]
    for y in np.linspace(-0.015, 0.015, 31):
        lines.append(" ".join(f"{v:.17g}" for v in [y, *(values[c] for c in COLUMNS[1:])]))
    path = tmp_path / "flat.dat"
    path.write_text("\n".join(lines) + "\n\n")
    return read_contact_table(path)


def test_yaw_damper_elongation_from_the_geometry(tmp_path):
    """Yawing the car body by psi0 and the bogies by psi1, psi2 stretches the front right damper by
    ly (psi0 - psi1) (its car-body point, s4 ahead of the bogie's, moves forward on the right when the car
    body turns left), the front left by -ly (psi0 - psi1), the rear ones the other way (their car-body points
    behind), with ly = a + l1 + l2 + l3/2; lateral motion leaves them alone."""
    params = CooperriderParams(**_MADE_UP)
    car = CooperriderCar(params, _flat_table(tmp_path), 50.0)
    psi0, psi1, psi2, rates = 2e-3, -1e-3, 5e-4, (0.3, 0.7, -0.2)
    x = np.zeros((N_STATES, 1))
    for body, psi, rate in zip((0, 1, 2), (psi0, psi1, psi2), rates):
        x[state_index(body, "psi")] = psi
        x[state_index(body, "psi", rate=True)] = rate
        x[state_index(body, "y")] = 0.01 * (body + 1)
    ly = params.a + params.l1 + params.l2 + params.l3 / 2.0
    e, v = car.yaw_damper_strokes(x)
    want = ly * np.array([psi0 - psi1, psi1 - psi0, psi2 - psi0, psi0 - psi2])
    want_v = ly * np.array([rates[0] - rates[1], rates[1] - rates[0], rates[2] - rates[0], rates[0] - rates[2]])
    assert YAW_DAMPER_NAMES == ("front_right", "front_left", "rear_right", "rear_left")
    np.testing.assert_allclose(e[:, 0], want, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(v[:, 0], want_v, rtol=1e-12, atol=1e-18)


def test_dashpot_forces_put_in_from_outside_are_the_cars_own_dashpots(tmp_path):
    """The car without D6, given D6 times each damper's elongation rate as tension forces, has the same
    equations as the car with its D6 dashpots (forces and moments, every body), at random states."""
    params = CooperriderParams(**_MADE_UP)
    table = _flat_table(tmp_path)
    speeds = np.array([40.0, 90.0, 130.0])
    own = CooperriderCar(params, table, speeds)
    without = CooperriderCar(params.with_values(D6=0.0), table, speeds)
    x = np.random.default_rng(3).normal(scale=1e-3, size=(N_STATES, 3))
    _, v = without.yaw_damper_strokes(x)
    want = own.rhs(0.0, x)
    tol = 1e-12 * np.max(np.abs(want))
    assert np.max(np.abs(want - without.rhs(0.0, x))) > 1e6 * tol  # the dashpots matter here
    np.testing.assert_allclose(without.rhs(0.0, x, params.D6 * v), want, rtol=0.0, atol=tol)
    one = CooperriderCar(params.with_values(D6=0.0), table, speeds[0])  # one state (66,), forces (4,)
    np.testing.assert_allclose(one.rhs(0.0, x[:, 0], params.D6 * v[:, 0]), want[:, 0], rtol=0.0, atol=tol)


@needs_reference
def test_maxwell_fmu_as_the_d6_dashpot_follows_the_built_in_car():
    """A Maxwell FMU with c = D6 and a series stiffness of 1e11 N/m (a dashpot) as the four yaw dampers: over
    1 s at 110 m/s from the 0.1 mm offset the leading wheelset follows the built-in car (the same Runge-Kutta
    step, 0.5 ms), the difference falling as the square of the communication step (force linear over the
    step: second order) and below 1e-4 of the offset at 0.5 ms."""
    from damper_fmu.fmu import ensure_fmu
    model = read_cooperrider_xml(XML)
    params, table = model.params, read_contact_table(model.table_path)
    ref = run_speeds(params, table, [110.0], offset_state()[:, 0], 1.0, dt=5e-4).signal()[:, 0]
    dashpot = {"k_s": 1e11, "c": params.D6, "internal_tolerance": 1e-10}
    err = {}
    for step, substeps in ((1e-3, 2), (5e-4, 1)):
        with CooperriderCosim(ensure_fmu("maxwell"), params, table, step=step, substeps=substeps,
                              fmu_parameters=dashpot) as co:
            run = co.run([110.0], offset_state()[:, 0], 1.0)
        err[step] = np.max(np.abs(run.signal()[:, 0] - ref))
    assert 3.0 < err[1e-3] / err[5e-4] < 5.0, err
    assert err[5e-4] < 1e-8, err
    with CooperriderCosim(None, params, table) as co:  # the same loop without FMUs: the car's own dashpots
        own = co.run([110.0], offset_state()[:, 0], 1.0).signal()[:, 0]
    np.testing.assert_allclose(own, ref, rtol=0.0, atol=1e-15)


class _KnownGrowth:
    """Stands in for a CooperriderCosim: the leading wheelset's response offset e^(s t) cos(30 t), s = 0.2 (v -
    v_crit) [1/s]; a speed whose response passes the abort limit is stopped there (states NaN)."""

    def __init__(self, v_crit: float):
        self.v_crit, self.batches = v_crit, []

    def run(self, speeds, x0, t_end, *, store=0.01, abort=5e-3):
        self.batches.append(np.asarray(speeds))
        t = np.arange(int(round(t_end / store)) + 1) * store
        states = np.zeros((t.size, N_STATES, len(speeds)))
        stopped = np.full(len(speeds), np.nan)
        for j, v in enumerate(speeds):
            y = x0[state_index(3, "y")] * np.exp(0.2 * (v - self.v_crit) * t) * np.cos(30.0 * t)
            out = np.abs(y) > abort
            if out.any():
                stopped[j] = t[np.argmax(out)]
                y[np.argmax(out):] = np.nan
            states[:, state_index(3, "y"), j] = y
        return DamperCarRun(t=t, speeds=np.asarray(speeds), states=states, forces=np.zeros((t.size, 4, len(speeds))),
                            stopped_at=stopped)


def test_search_finds_a_known_critical_speed_and_says_what_it_did_not_find():
    """Responses growing at 0.2 (v - 107.3) 1/s: three rounds of eight speeds find 107.3 m/s to 0.05 m/s, the
    last bracket 0.39 m/s wide; fast-growing speeds are stopped and count as growing; all decaying or all
    growing: no critical speed, said so."""
    fake = _KnownGrowth(107.3)
    res = search_critical_speed(fake, CooperriderSearch(), log=lambda line: None)
    assert abs(res.critical_speed - 107.3) < 0.05, res.critical_speed
    assert res.bracket[0] < 107.3 < res.bracket[1] and res.bracket[1] - res.bracket[0] < 0.4
    assert len(fake.batches) == 3 and all(b.size == 8 for b in fake.batches)
    entry = res.to_json()
    assert any(r["stopped_past_abort"] and r["growth_rate_per_s"] is None for r in entry["runs"])
    json.dumps(entry, allow_nan=False)
    assert speed_text(entry) == f"{res.critical_speed:.2f} m/s ({3.6 * res.critical_speed:.0f} km/h)"
    stable = search_critical_speed(_KnownGrowth(400.0), CooperriderSearch(), log=lambda line: None)
    assert stable.stable_up_to_max and stable.critical_speed is None and speed_text(stable.to_json()) == "> 250 m/s"
    unstable = search_critical_speed(_KnownGrowth(20.0), CooperriderSearch(v_min=30.0), log=lambda line: None)
    assert unstable.unstable_at_min and speed_text(unstable.to_json()) == "< 30 m/s"


def test_search_settings_are_checked():
    with pytest.raises(ValueError, match="25 m/s"):
        CooperriderSearch(v_min=10.0)
    with pytest.raises(ValueError, match="per_round"):
        CooperriderSearch(per_round=1)
    assert math.isclose(CooperriderSearch().step, 5e-4)
    assert set(XML_NAMES) == set(_MADE_UP)


def _study_json(folder: Path) -> dict:
    """A cooperrider.json as ``cooperrider_study`` writes it, from searches on responses of known growth."""
    quiet = lambda line: None  # noqa: E731
    results = {"built-in D6 dashpot": search_critical_speed(_KnownGrowth(107.4), CooperriderSearch(), log=quiet),
               "DamperMaxwell_tuned": search_critical_speed(_KnownGrowth(131.0), CooperriderSearch(), log=quiet),
               "DamperLumped_tuned": search_critical_speed(_KnownGrowth(400.0), CooperriderSearch(), log=quiet)}
    data = {"model": {"input_file": "in.xml", "contact_table": "RSGEO.dat", "yaw_damper_D6_ns_per_m": 166669.0,
                      "yaw_spring_k6_n_per_m": 903350.0},
            "search": CooperriderSearch().to_json(),
            "results": {k: {"fmu": None if k.startswith("built") else f"{k}.fmu", **r.to_json()}
                        for k, r in results.items()}}
    v = data["results"]["DamperMaxwell_tuned"]["critical_speed_ms"]
    data["results"]["DamperMaxwell_tuned"].update(cycle_speed_ms=1.05 * v, cycle_amplitude_m=7.3e-4,
                                                  cycle_stopped_at_s=None, cycle_time_s=60.0, cycle_wall_time_s=5.0)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "cooperrider.json").write_text(json.dumps(data, allow_nan=False))
    return data


def test_report_and_summary_show_the_cooperrider_critical_speeds_beside_the_cone_car(tmp_path):
    """The vehicle section's table 'Cooperrider car, S1002/UIC60': per yaw damper its critical speed, the ratio
    to the D6 dashpot's and the cone car's (vehicle.json) beside it; summary.json's 'cooperrider' in m/s and km/h."""
    from tuner.cli.summary import cooperrider_summary, update_cooperrider_summary
    from tuner.results.vehicle_report import vehicle_section_html

    out = tmp_path / "run"
    data = _study_json(out / "vehicle")
    cone = {"scenarios": {"critical_speed": "hunting"}, "step_s": 1e-3, "seed": 0,
            "results": {"DamperMaxwell_tuned": {"fmu": "m.fmu", "critical_speed": {
                "critical_speed_kmh": 647.6, "stable_up_to_max": False, "unstable_at_min": False, "kick_m": 3e-3,
                "runs": [{"speed_kmh": 100.0, "growth_rate_per_s": -1.0, "completed": True},
                         {"speed_kmh": 1000.0, "growth_rate_per_s": 2.0, "completed": True}]}}}}
    (out / "vehicle" / "vehicle.json").write_text(json.dumps(cone))
    html = vehicle_section_html(out)
    section = html[html.index("Cooperrider car, S1002/UIC60"):]
    v_ref = data["results"]["built-in D6 dashpot"]["critical_speed_ms"]
    v_max = data["results"]["DamperMaxwell_tuned"]["critical_speed_ms"]
    assert f"<td>{v_ref:.2f} m/s ({3.6 * v_ref:.0f} km/h)</td><td>1.000</td><td>-</td>" in section
    assert (f"<td>{v_max:.2f} m/s ({3.6 * v_max:.0f} km/h)</td><td>{v_max / v_ref:.3f}</td><td>648</td>"
            f"<td>cycle 0.730 mm at {1.05 * v_max:.2f} m/s</td>") in section
    assert "<td>DamperLumped_tuned</td><td>&gt; 250 m/s</td><td>-</td><td>-</td>" in section
    assert "166.7 kN s/m" in section and "0.5 ms" in section
    assert "the tuned FMUs&#x27; linear critical speeds range" not in section  # one FMU speed: no range
    data["results"]["DamperLumped_tuned"]["critical_speed_ms"] = 140.0
    (out / "vehicle" / "cooperrider.json").write_text(json.dumps(data, allow_nan=False))
    cone["results"]["DamperLumped_tuned"] = json.loads(json.dumps(cone["results"]["DamperMaxwell_tuned"]))
    cone["results"]["DamperLumped_tuned"]["critical_speed"]["critical_speed_kmh"] = 804.1
    (out / "vehicle" / "vehicle.json").write_text(json.dumps(cone))
    assert (f"range from {v_max:.2f} m/s (DamperMaxwell_tuned) to 140.00 m/s (DamperLumped_tuned): "
            f"{3.6 * (140.0 - v_max):.0f} km/h, against 156 km/h on the cone car.") in vehicle_section_html(out)
    got = cooperrider_summary(out)
    assert got["DamperLumped_tuned"]["critical_speed_ms"] == 140.0
    assert got["DamperMaxwell_tuned"] == {"critical_speed_ms": v_max, "critical_speed_kmh": 3.6 * v_max,
                                          "bracket_ms": data["results"]["DamperMaxwell_tuned"]["bracket_ms"]}
    assert not update_cooperrider_summary(out)  # no summary.json: nothing to update
    (out / "summary.json").write_text(json.dumps({"verdict": "x"}))
    assert update_cooperrider_summary(out)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["verdict"] == "x" and summary["cooperrider"] == json.loads(json.dumps(got))


def test_cooperrider_command_without_the_simulators_input_says_where_to_get_it(tmp_path, capsys):
    from damper_fmu.fmu import ensure_fmu
    from tuner.__main__ import main

    missing = tmp_path / "nowhere" / "input.xml"
    code = main(["vehicle", "--fmus", str(ensure_fmu("maxwell")), "--cooperrider", "--cooperrider-input",
                 str(missing), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and str(missing) in err and "--cooperrider-input" in err and "DYTSI_REFERENCE" in err
    code = main(["vehicle", "--fmus", str(ensure_fmu("maxwell")), "--cooperrider", "--nonlinear", "--quiet",
                 "--out", str(tmp_path / "out")])
    assert code == 2 and "choose one of --nonlinear and --cooperrider" in capsys.readouterr().err


def test_cycle_amplitude_above_the_critical_speed_of_a_known_cycle():
    """A response settling on a cycle of 0.73 mm: its amplitude over the last 10 s, at 1.05 times the speed given."""
    from tuner.vehicle.cooperrider_hunting import cycle_above

    class Cycle(_KnownGrowth):
        def run(self, speeds, x0, t_end, *, store=0.01, abort=5e-3):
            run = super().run(speeds, x0, t_end, store=store, abort=abort)
            t = run.t
            run.states[:, state_index(3, "y"), 0] = 7.3e-4 * (1.0 - np.exp(-t / 5.0)) * np.sin(29.0 * t)
            return run

    got = cycle_above(Cycle(1e4), 100.0, CooperriderSearch(cycle_time=60.0))
    assert got["cycle_speed_ms"] == pytest.approx(105.0) and got["cycle_stopped_at_s"] is None
    assert got["cycle_amplitude_m"] == pytest.approx(7.3e-4 * (1.0 - math.exp(-10.0)), rel=1e-3)
    with pytest.raises(ValueError, match="cycle_time"):
        CooperriderSearch(cycle_time=5.0)


@needs_reference
def test_a_speed_past_the_abort_limit_leaves_the_batch_without_disturbing_the_others():
    """Two speeds, the second started at 0.3 mm with the limit at 0.2 mm: it stops after the first step (NaN from
    then on, its time recorded); the first runs on with its FMUs as if alone."""
    from damper_fmu.fmu import ensure_fmu
    model = read_cooperrider_xml(XML)
    params, table = model.params, read_contact_table(model.table_path)
    x0 = np.hstack([offset_state(1e-4), offset_state(3e-4)])
    with CooperriderCosim(ensure_fmu("maxwell"), params, table, fmu_parameters={"c": params.D6}) as co:
        both = co.run([60.0, 60.0], x0, 0.2, abort=2e-4)
        alone = co.run([60.0], x0[:, 0], 0.2, abort=2e-4)
    assert both.stopped_at[1] == pytest.approx(5e-4) and math.isnan(both.stopped_at[0])
    assert np.all(np.isnan(both.states[1:, :, 1])) and np.all(np.isnan(both.forces[1:, :, 1]))
    assert np.max(np.abs(both.signal()[:, 0])) < 2e-4 and np.max(np.abs(both.forces[:, :, 0])) > 1.0
    np.testing.assert_allclose(both.states[:, :, 0], alone.states[:, :, 0], rtol=0.0, atol=1e-15)
    np.testing.assert_allclose(both.forces[:, :, 0], alone.forces[:, :, 0], rtol=1e-12, atol=1e-9)
