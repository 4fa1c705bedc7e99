"""The datasheet's computation against physics, not against its own output: a Maxwell FMU against the closed form
K*(w) = k i w c / (k + i w c), the lumped FMU's quasi-static force-velocity points against its own damping table,
the first harmonic against a direct least-squares fit of a sine (scipy's ``curve_fit``)."""
from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import curve_fit
from scipy.signal import lsim

from damper_fmu.fmu import build
from damper_fmu.parameters import defaults
from damper_fmu.tables import PwlTable
from tuner.data.prefilter import Prefilter
from tuner.data.reading import RigTest, load_dataset
from tuner.datasheet.characteristic import DatasheetSettings, fmu_characteristic
from tuner.datasheet.measured import NotSine, SineTest, sine_test
from tuner.datasheet.nominal import read_nominal
from tuner.datasheet.sheet import compare_point
from tuner.datasheet.loop import harmonics, loop_quantities, maxwell_equivalent
from tuner.datasheet.sine_runs import SineDriver
from tuner.__main__ import main
from tuner.results.datasheet_figures import FIGURES

K_S, C = 8e6, 3e5  # [N/m], [N s/m]


def closed_form(f_hz: float) -> complex:
    """K*(w) of a spring K_S in series with a dashpot C [N/m]."""
    w = 2 * np.pi * f_hz
    return K_S * 1j * w * C / (K_S + 1j * w * C)


@pytest.fixture(scope="module")
def maxwell_fmu(tmp_path_factory):
    return build("maxwell", tmp_path_factory.mktemp("fmu"), start_values={"k_s": K_S, "c": C},
                 filename="MaxwellDatasheet.fmu")


def test_a_maxwell_fmu_gives_the_closed_form_dynamic_stiffness_and_force_velocity(maxwell_fmu):
    ch = fmu_characteristic(maxwell_fmu, DatasheetSettings(amplitudes_m=(1e-3, 5e-3)), log=lambda line: None)
    listed = sorted({p.frequency_hz for p in ch.dynamic})
    assert sum(0.5 <= f <= 15.0 for f in listed) >= 5
    for p in ch.dynamic:
        k_star, q = closed_form(p.frequency_hz), p.quantities
        assert p.settled
        assert q.storage_n_m == pytest.approx(k_star.real, rel=0.01), p
        assert q.loss_n_m == pytest.approx(k_star.imag, rel=0.01), p
        assert q.loss_angle_deg == pytest.approx(math.degrees(math.atan2(k_star.imag, k_star.real)), abs=0.5)
        # a Maxwell element's equivalent Maxwell element is itself, and it is linear
        assert q.maxwell_k_n_m == pytest.approx(K_S, rel=0.01) and q.maxwell_c_n_s_m == pytest.approx(C, rel=0.01)
        assert q.distortion < 1e-3
    assert ch.series_stiffness_n_m == pytest.approx(K_S, rel=0.01)
    for direction, sign in (("extension", 1.0), ("compression", -1.0)):
        points = [p for p in ch.force_velocity if p.direction == direction]
        assert len(points) >= 5 and all(np.sign(p.velocity_m_s) == sign for p in points)
        for p in points:  # x = A sin(w t): at the peak velocity the force is A K'' of the closed form, signed
            expected = sign * p.amplitude_m * closed_form(p.frequency_hz).imag
            assert p.force_n == pytest.approx(expected, rel=0.01), p


def test_the_lumped_fmus_quasi_static_force_velocity_points_lie_on_its_damping_table(fmu_paths):
    """At the force-velocity sines (25 mm stroke, 0.03-1.9 Hz) the lumped chain's elasticity (Fk,O, 1.5e7 N/m;
    silent blocks) lags the damping table by (w c / k)^2 < 0.3 % at the peak velocity, where the acceleration is
    zero: the points are the table's."""
    p = defaults("lumped")
    table = PwlTable([p[f"Fc_v{i:02d}"] for i in range(1, 15)], [p[f"Fc_{i:02d}"] for i in range(1, 15)])
    ch = fmu_characteristic(fmu_paths["lumped"], DatasheetSettings(frequencies_hz=(1.0,), amplitudes_m=(1e-3,)),
                            log=lambda line: None)
    assert len(ch.force_velocity) == 2 * 10
    for point in ch.force_velocity:
        assert point.settled
        assert point.force_n == pytest.approx(table(point.velocity_m_s), rel=0.01), point


def _sine(t, offset, a, b, f):
    return offset + a * np.sin(2 * np.pi * f * t) + b * np.cos(2 * np.pi * f * t)


def test_the_first_harmonic_is_a_direct_least_squares_sine_fit(fmu_paths):
    """The lumped FMU's force at 5 Hz, 5 mm (strongly nonlinear: its harmonics are large) on four whole periods
    after two (the discrete Fourier transform), and at 3 Hz on three periods resampled at 200 Hz, as a rig samples
    (66.7 samples per period: the series fitted by its normal equations)."""
    with SineDriver(fmu_paths["lumped"]) as driver:
        n = driver.settings.samples_per_period(5.0)
        t5, _, f5 = driver.stroke_run(5.0, 5e-3, 6)
        t3, _, f3 = driver.stroke_run(3.0, 5e-3, 5)
    window = np.arange(1 / 3.0, 4 / 3.0, 1 / 200.0)
    cases = [(t5[2 * n:6 * n], f5[2 * n:6 * n], 5.0), (window, np.interp(window, t3, f3), 3.0)]
    for tt, y, freq in cases:
        h = harmonics(tt, y, freq)
        assert h.distortion() > 0.05  # a test that a linear force would not make
        # the three-parameter sine fit (IEEE 1057) at the known frequency, by scipy's nonlinear least squares
        (offset, a, b), _ = curve_fit(lambda t, o, a, b: _sine(t, o, a, b, freq), tt, y,
                                      p0=[0.0, float(np.std(y)), 0.0])
        # y ~ a sin + b cos: Y_1 = b - i a (y = Re(Y_1 exp(i w t)))
        assert abs(h.first - complex(b, -a)) <= 1e-6 * abs(h.first), (h.first, a, b)


def test_loop_quantities_of_a_known_signal():
    """x = A sin(w t), F = F1 sin(w t + d) + 0.1 F1 sin(3 w t): K* = (F1 / A) exp(i d), THD 0.1; the force at the
    peak velocities is F1 sin(d) (the third harmonic is zero there)."""
    f, a, f1, d = 2.0, 1e-3, 1e3, 0.7
    t = np.arange(400) / 200.0  # four whole periods
    w = 2 * np.pi * f
    q = loop_quantities(t, a * np.sin(w * t), f1 * np.sin(w * t + d) + 0.1 * f1 * np.sin(3 * w * t), f)
    assert complex(q.storage_n_m, q.loss_n_m) == pytest.approx(f1 / a * np.exp(1j * d), rel=1e-9)
    assert q.distortion == pytest.approx(0.1, rel=1e-9) and q.periods == 4
    assert q.force_extension_n == pytest.approx(f1 * np.sin(d), rel=1e-9)
    assert q.force_compression_n == pytest.approx(-f1 * np.sin(d), rel=1e-9)
    k, c = maxwell_equivalent(complex(q.storage_n_m, q.loss_n_m), w)
    assert 1 / complex(q.storage_n_m, q.loss_n_m) == pytest.approx(1 / k + 1 / (1j * w * c), rel=1e-9)
    assert maxwell_equivalent(complex(-1.0, 1.0), w)[0] == math.inf  # no spring for a negative storage stiffness


def _strict(path):
    return json.loads(path.read_text(), parse_constant=lambda c: pytest.fail(f"{path.name}: {c}"))


def test_the_datasheet_command_on_a_maxwell_fmu_gives_the_closed_form(maxwell_fmu, tmp_path, capsys):
    out = tmp_path / "sheet"
    assert main(["datasheet", "--fmus", str(maxwell_fmu), "--out", str(out), "--quiet"]) == 0
    sheet = _strict(out / "datasheet.json")
    entry = sheet["fmus"]["MaxwellDatasheet"]
    listed = sorted({p["frequency_hz"] for p in entry["dynamic"]})
    assert sum(0.5 <= f <= 15.0 for f in listed) >= 5
    for p in entry["dynamic"]:
        assert p["source"] == "simulated"
        k_star = closed_form(p["frequency_hz"])
        assert p["storage_n_m"] == pytest.approx(k_star.real, rel=0.01)
        assert p["loss_n_m"] == pytest.approx(k_star.imag, rel=0.01)
    for direction in ("extension", "compression"):
        assert sum(p["direction"] == direction for p in entry["force_velocity"]) >= 5
    with (out / "MaxwellDatasheet_force_velocity.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [float(r["velocity_m_s"]) for r in rows] == sorted(float(r["velocity_m_s"]) for r in rows)
    assert all(float(r["series_stiffness_n_m"]) == pytest.approx(K_S, rel=0.01) for r in rows)
    with (out / "MaxwellDatasheet_maxwell.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(entry["dynamic"])
    assert all(float(r["maxwell_c_n_s_m"]) == pytest.approx(C, rel=0.01) for r in rows)
    assert all((out / name).stat().st_size > 0 for name in FIGURES.values())
    assert "MaxwellDatasheet: series stiffness 8 MN/m" in capsys.readouterr().out


@pytest.mark.parametrize("args, said", [
    (["--fmus", "missing.fmu"], "missing.fmu"),
    (["--amplitudes", "1,-2"], "--amplitudes"),
    (["--fv-amplitude", "0"], "--fv-amplitude"),
    (["--fmus", "FMI3"], "need an FMI 2.0 co-simulation FMU"),
])
def test_bad_datasheet_input_is_refused_by_name(maxwell_fmu, tmp_path, capsys, args, said):
    if args == ["--fmus", "FMI3"]:  # the same damper as an FMI 3.0 FMU
        args = ["--fmus", str(build("maxwell", tmp_path, fmi_version=3))]
    base = {"--fmus": [str(maxwell_fmu)], "--out": [str(tmp_path / "o")]}
    base.update({args[0]: args[1:]})
    argv = ["datasheet", *[x for k, v in base.items() for x in (k, *v)], "--quiet"]
    assert main(argv) == 2
    assert said in capsys.readouterr().err


def _maxwell_rig_test(f_hz: float, amplitude: float, lab: Prefilter | None, rate: float = 1000.0) -> RigTest:
    """A rig's sine test of the Maxwell damper (K_S, C): a stroke faded in over two periods and out over the last,
    the force its exact response (scipy's lsim of F/X = K_S C s / (C s + K_S), independent of the FMU), 0.5 % force
    noise (seed 7), both channels through the lab's filter ``lab`` as a lab exports them."""
    t = np.arange(0.0, 8.0 / f_hz, 1.0 / rate)
    ramp = np.clip(np.minimum(t * f_hz / 2.0, (t[-1] - t) * f_hz), 0.0, 1.0)
    x = amplitude * ramp * np.sin(2 * np.pi * f_hz * t)
    force = lsim(([K_S * C, 0.0], [C, K_S]), x, t)[1]
    force = force + 0.005 * np.max(np.abs(force)) * np.random.default_rng(7).standard_normal(t.size)
    if lab is not None:
        x, force = lab.apply(x, rate), lab.apply(force, rate)
    read = {"prefilter": lab.to_dict() if lab else None}
    return RigTest(name=f"maxwell_{f_hz:g}Hz", role="validation", scenario="", time=t, stroke=x, force=force,
                   sample_rate=rate, metadata={"read": read})


@pytest.mark.parametrize("lab", [None, Prefilter("moving-average", window_s=0.04)], ids=["unfiltered", "filtered"])
def test_a_measured_sine_gives_the_closed_form_and_the_true_model_matches_it(maxwell_fmu, lab):
    """The measured points of a Maxwell damper's rig sine at 2.5 Hz, 3 mm (a lab's moving average over a tenth of
    the period or none): K* within 1 % of the closed form, the forces at peak velocity of the steady sine under the
    same filter; the FMU of the same damper is the measured point within 1 % (its filtered twin)."""
    test = _maxwell_rig_test(2.5, 3e-3, lab)
    sine = sine_test(test)
    assert isinstance(sine, SineTest), sine
    q, k_star = sine.quantities, closed_form(2.5)
    assert q.frequency_hz == pytest.approx(2.5, rel=1e-4) and q.periods >= 4
    assert complex(q.storage_n_m, q.loss_n_m) == pytest.approx(k_star, rel=0.01)
    gain = abs(lab.response(np.array([2.5]), 1000.0)[0]) if lab else 1.0
    assert q.amplitude_m == pytest.approx(3e-3 * gain, rel=0.005)
    # the filter delays force and stroke alike: at the peak velocity the force is A K'' of the filtered sine
    assert q.force_extension_n == pytest.approx(q.amplitude_m * k_star.imag, rel=0.01)
    with SineDriver(maxwell_fmu) as driver:
        row = compare_point(driver, sine)
    assert row["model"]["source"] == "simulated" and row["model"]["settled"]
    for key in ("storage_n_m_pct", "loss_n_m_pct", "force_extension_n_pct", "force_compression_n_pct"):
        assert abs(row["error"][key]) < 1.0, (key, row["error"])


def test_a_stroke_that_is_not_a_sine_gives_no_measured_point():
    t = np.arange(0.0, 10.0, 1e-3)
    x = 3e-3 * np.sin(2 * np.pi * 1.0 * t) + 2e-3 * np.sin(2 * np.pi * 2.7 * t)
    read = sine_test(RigTest(name="two_sines", role=None, scenario="", time=t, stroke=x, force=1e5 * x))
    assert isinstance(read, NotSine) and "departs from a sine" in read.reason


def test_the_real_mr_sine_test_is_read_as_one_and_its_points_stand_beside_the_fmus(maxwell_fmu, tmp_path):
    """The MR damper's 2 mm, 5 Hz sine at 0.5 A (tests/data/mr-damper-0.5A, MIT, its LICENSE beside it), read as
    the lab exported it with its smoothing declared: a sine test near 5 Hz whose points stand in the datasheet as
    measured, beside the FMU's simulated ones with their errors."""
    data = Path(__file__).resolve().parent / "data" / "mr-damper-0.5A" / "2mm5Hz0x5A.txt.gz"
    columns = tmp_path / "columns.toml"
    columns.write_text('[columns]\ntime_col = 1\nstroke_col = 2\nforce_col = 4\nstroke_unit = "mm"\n'
                       'force_unit = "N"\ndamper_class = "any"\nprefilter = "moving-average:20@1000"\n')
    out = tmp_path / "sheet"
    assert main(["datasheet", "--fmus", str(maxwell_fmu), "--out", str(out), "--quiet", "--frequencies", "1,5",
                 "--amplitudes", "2", "--tests", str(data), "--columns", str(columns)]) == 0
    sheet = _strict(out / "datasheet.json")
    (point,) = sheet["measured"]["points"]
    assert point["source"] == "measured" and point["prefilter"] == "moving-average:20@1000.0"
    assert point["frequency_hz"] == pytest.approx(5.0, rel=0.03) and point["loss_n_m"] > 0
    assert point["force_extension_n"] > 0 > point["force_compression_n"]
    (row,) = sheet["fmus"]["MaxwellDatasheet"]["measured_comparison"]
    assert row["test"] == point["test"] and row["model"]["source"] == "simulated"
    assert row["error"]["loss_n_m_pct"] == pytest.approx(100 * (row["model"]["loss_n_m"] - point["loss_n_m"])
                                                          / point["loss_n_m"])


def _table_csv(path: Path, scale: float = 1.0) -> Path:
    """The preset lumped damping table, scaled, as a supplier's nominal sheet in mm/s and kN."""
    p = defaults("lumped")
    rows = [(p[f"Fc_v{i:02d}"] * 1e3, p[f"Fc_{i:02d}"] * scale / 1e3) for i in range(1, 15)]
    path.write_text("velocity [mm/s],force [kN]\n" + "".join(f"{v!r},{f!r}\n" for v, f in rows))
    return path


@pytest.mark.parametrize("scale, inside", [(1.0, True), (1.1, False)])
def test_the_lumped_fmus_points_lie_in_a_band_around_its_own_table_and_outside_one_10_pct_off(
        fmu_paths, tmp_path, scale, inside):
    """The nominal characteristic is the lumped FMU's own damping table (or 10 % above it), +- 2 %: each simulated
    force-velocity point within the table's velocities is inside (outside), the rest not judged."""
    out = tmp_path / "sheet"
    assert main(["datasheet", "--fmus", str(fmu_paths["lumped"]), "--out", str(out), "--quiet", "--frequencies", "2",
                 "--amplitudes", "1", "--velocities", "0.005,0.03,0.09,0.15",
                 "--nominal", str(_table_csv(tmp_path / "nominal.csv", scale)), "--nominal-tolerance", "2"]) == 0
    nominal = _strict(out / "datasheet.json")["nominal"]
    judged = nominal["judged"]["DamperLumped"]
    assert [p["inside"] for p in judged] == [None if abs(p["velocity_m_s"]) > 0.1 else inside for p in judged]
    assert nominal["counts"]["DamperLumped"] == {"inside": 6 if inside else 0, "outside": 0 if inside else 6,
                                                 "not_judged": 2}
    assert nominal["points"][0] == {"velocity_m_s": -0.1, "force_n": pytest.approx(-26e3 * scale),
                                    "tolerance_pct": 2.0}


def test_a_nominal_point_is_judged_against_its_interpolated_band(tmp_path):
    csv_path = tmp_path / "n.csv"
    csv_path.write_text("v_m_s,F_n,tolerance\n-0.2,-20000,10\n-0.1,-10000,5\n0.1,10000,5\n0.2,20000,10\n")
    nominal = read_nominal(csv_path)
    # at 0.15 m/s the nominal is 15 kN and the band +- 7.5 %
    assert nominal.judge(0.15, 15e3 * 1.07)["inside"] is True
    assert nominal.judge(0.15, 15e3 * 1.08)["inside"] is False
    assert nominal.judge(-0.15, -15e3 * 0.93)["inside"] is True
    assert nominal.judge(0.05, 5e3)["inside"] is None  # beyond the nominal's velocities in extension


@pytest.mark.parametrize("text, said", [
    ("velocity [m/s],force [kN]\n0.1,2\n0.2,x\n", "line 3, column 2: force 'x' is not a number"),
    ("velocity [m/s],force [kN]\n0.1,2\n-0.2,3\n", "line 3"),
    ("velocity [in/s],force [kN]\n0.1,2\n0.2,3\n", "unknown velocity unit 'in/s'"),
    ("speed,force\n0.1,2\n0.2,3\n", "no velocity column"),
])
def test_a_bad_nominal_file_is_refused_naming_where(tmp_path, text, said):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=re.escape(said)):
        read_nominal(path, 5.0)


def test_the_bundled_multibody_strokes_are_not_sine_tests():
    """The bundled dataset's rig tests replay simulated vehicle strokes: none is read as a sine test, each says why."""
    tests = load_dataset(Path(__file__).resolve().parents[1] / "data" / "default")
    reads = [sine_test(t) for t in tests]
    assert reads and all(isinstance(r, NotSine) for r in reads)
    assert all("no steady sine" in r.reason or "departs from a sine" in r.reason for r in reads)
