"""Rig files as rigs write them (issue 13): each format read back to the same SI signals, and unit or
sign mistakes refused, both ways, with the documented messages.

The reference signals are a virtual-rig test of the bundled dataset (twin-tube damper, 1 kHz),
written by these tests in each format; the reader never sees how they were made."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from damper_fmu.fmu import native_reason
from tuner.data.reading import DataError, load_dataset, load_test, load_tests
from tuner.data.preprocess import prepare
from tuner.cli.folders import DEFAULT_DATASET

N = 4000  # 4 s at 1 kHz


@pytest.fixture(scope="module")
def ref():
    t = load_dataset(DEFAULT_DATASET)[0]
    return {"time": t.time[:N] - t.time[0], "stroke": t.stroke[:N], "force": t.force[:N],
            "temperature": 20.0 + 30.0 * t.time[:N] / t.time[N]}


def _same(test, ref, stroke_atol=1e-9, force_atol=1e-6, every=1):
    np.testing.assert_allclose(test.time, ref["time"][::every], atol=1e-9)
    np.testing.assert_allclose(test.stroke, ref["stroke"][::every], atol=stroke_atol)
    np.testing.assert_allclose(test.force, ref["force"][::every], atol=force_atol)


def test_units_row_semicolons_decimal_comma_and_compression_positive(tmp_path, ref):
    """A European rig export: ';' delimiter, decimal comma, mm and kN in a units row, compression
    positive for both stroke and force, oil temperature in a column 'Temp (C)'."""
    rows = ["# exported by RigSoft 4.2", "Zeit;Weg;Kraft;Temp (C)", "s;mm;kN;degC"]
    rows += [f"{t:.3f};{-1e3 * x:.6f};{-f / 1e3:.7f};{c:.3f}".replace(".", ",")
             for t, x, f, c in zip(ref["time"], ref["stroke"], ref["force"], ref["temperature"])]
    p = tmp_path / "export.csv"
    p.write_text("\n".join(rows) + "\n", encoding="utf-8")
    g = load_test(p, time_col="Zeit", stroke_col="Weg", force_col="Kraft", temperature_col="Temp (C)",
                  stroke_sign=-1, force_sign=-1)
    _same(g, ref, stroke_atol=1e-9, force_atol=1e-4)
    np.testing.assert_allclose(g.channels["temperature"], ref["temperature"], atol=1e-3)
    read = g.metadata["read"]
    assert read["delimiter"] == ";" and read["decimal"] == ","
    assert read["units"]["stroke"] == "mm" and read["units"]["force"] == "kN"
    assert read["signs"] == {"stroke": -1, "force": -1}


def test_header_units_tsv_and_parquet(tmp_path, ref):
    frame = pd.DataFrame({"time [s]": ref["time"], "stroke (mm)": 1e3 * ref["stroke"],
                          "force [kN]": ref["force"] / 1e3})
    tsv = tmp_path / "a.tsv"
    frame.to_csv(tsv, sep="\t", index=False, float_format="%.10g")
    pq = tmp_path / "a.parquet"
    frame.to_parquet(pq)
    blanks = tmp_path / "a.dat"
    blanks.write_text("t x F\n[s] [mm] [kN]\n" + "\n".join(
        f"{t:.3f}   {1e3 * x:.6f}  {f / 1e3:.7f}" for t, x, f in zip(ref["time"], ref["stroke"], ref["force"])))
    for path, cols in [(tsv, {}), (pq, {}), (blanks, dict(time_col="t", stroke_col="x", force_col="F"))]:
        g = load_test(path, **cols)
        _same(g, ref, force_atol=1e-3)
        assert g.metadata["read"]["units"]["force"] == "kN", path


def test_datetime_stamps_300hz_to_the_millisecond(tmp_path, ref):
    """300 Hz written with ISO stamps rounded to the millisecond: the clock is recognised (stamps
    jitter by up to half a millisecond), so the samples are used as they are, with a warning."""
    t = np.arange(0, 4.0, 1 / 300)
    x = np.interp(t, ref["time"], ref["stroke"])
    f = np.interp(t, ref["time"], ref["force"])
    stamps = (pd.Timestamp("2026-03-02T10:15:00") + pd.to_timedelta(np.round(t * 1e3), unit="ms"))
    p = tmp_path / "stamped.csv"
    pd.DataFrame({"timestamp": stamps.strftime("%Y-%m-%dT%H:%M:%S.%f").str[:-3], "stroke": x, "force": f}) \
        .to_csv(p, index=False)
    g = load_test(p, time_col="timestamp")
    assert g.sample_rate == pytest.approx(300.0, rel=1e-3)
    np.testing.assert_allclose(g.time, t, atol=1e-6)
    np.testing.assert_allclose(g.force, f)
    assert g.metadata["read"]["time"] == "timestamp"
    assert any("regular 300" in w for w in g.metadata["warnings"])


def test_duplicated_and_missing_samples_are_regularised_with_a_warning(tmp_path, ref):
    t, x, f = ref["time"], ref["stroke"], ref["force"]
    keep = np.ones(N, dtype=bool)
    keep[[500, 1500, 1501]] = False  # three samples lost by the logger
    rows = np.flatnonzero(keep)
    rows = np.insert(rows, 100, rows[100])  # one row written twice
    p = tmp_path / "lossy.csv"
    pd.DataFrame({"time": t[rows], "stroke": x[rows], "force": f[rows]}).to_csv(p, index=False, float_format="%.10g")
    g = load_test(p)
    warn = " ".join(g.metadata["warnings"])
    assert "1 duplicated time stamp" in warn and "interpolated linearly" in warn
    assert len(g.time) == N
    lost = np.zeros(N, dtype=bool)
    lost[[500, 1500, 1501]] = True
    np.testing.assert_allclose(g.force[~lost], f[~lost], atol=1e-6)
    # interpolated samples lie between their neighbours
    for i in (500, 1500, 1501):
        lo, hi = sorted((f[i - 1 if i != 1501 else 1499], f[1502 if i != 500 else 501]))
        assert lo - 1e-6 <= g.force[i] <= hi + 1e-6


def test_no_time_column_with_rate_segments_test_ids_and_positions(tmp_path, ref):
    p = tmp_path / "blocks.csv"
    half = N // 2
    pd.DataFrame({"run": ["A"] * half + ["B"] * half, "x": ref["stroke"], "F": ref["force"]}) \
        .to_csv(p, index=False, float_format="%.10g")
    a, b = load_tests(p, time_col=None, rate_hz=1000.0, stroke_col=2, force_col="3", test_col="run")
    assert (a.name, b.name) == ("blocks-A", "blocks-B")
    np.testing.assert_allclose(a.force, ref["force"][:half])
    np.testing.assert_allclose(b.force, ref["force"][half:])
    np.testing.assert_allclose(b.time, ref["time"][:half], atol=1e-12)  # each test starts at 0
    seg = load_test(p, time_col=None, rate_hz=1000.0, stroke_col="x", force_col="F", extra_cols=[],
                    t_start=1.0, t_end=2.5)
    np.testing.assert_allclose(seg.force, ref["force"][1000:2501])
    assert seg.time[0] == pytest.approx(1.0)


def test_measured_velocity_column_is_used_instead_of_the_differentiator(tmp_path, ref):
    v = np.gradient(ref["stroke"], ref["time"])
    p = tmp_path / "vel.csv"
    pd.DataFrame({"time": ref["time"], "stroke [mm]": 1e3 * ref["stroke"], "force": ref["force"],
                  "velocity [mm/s]": 1e3 * v}).to_csv(p, index=False, float_format="%.10g")
    g = load_test(p, velocity_col="velocity")
    np.testing.assert_allclose(g.velocity, v, rtol=1e-8, atol=1e-12)
    pt = prepare(g, 1000.0)
    np.testing.assert_allclose(pt.stroke_velocity, v, rtol=1e-8, atol=1e-12)
    assert "measured by the rig" in pt.describe()
    flipped = load_test(p, velocity_col="velocity", stroke_sign=-1, force_sign=-1)
    np.testing.assert_allclose(flipped.velocity, -v, rtol=1e-8, atol=1e-12)


def _sweep(tmp_path, name, stroke_scale, force_scale, amplitude_m, freq, c):
    """A sine sweep of a linear damper c [N s/m] (amplitude growing 15-fold to ``amplitude_m`` [m]
    at ``freq`` [Hz], 4 s at 1 kHz), written with the given scale factors (1: SI)."""
    t = np.arange(0, 4.0, 1e-3)
    x = amplitude_m * np.linspace(0.066, 1.0, t.size) * np.sin(2 * np.pi * freq * t)
    f = c * np.gradient(x, t)
    p = tmp_path / f"{name}.csv"
    pd.DataFrame({"time": t, "stroke": stroke_scale * x, "force": force_scale * f}).to_csv(p, index=False)
    return p


HUNTING = dict(amplitude_m=0.7e-3, freq=5.0, c=3e4)  # 1.4 mm peak-to-peak at 5 Hz: 22 mm/s
SWEEP = dict(amplitude_m=0.038, freq=1.0, c=3e4)  # 5-76 mm peak-to-peak
YAW = dict(amplitude_m=0.01, freq=1.0, c=1e6)  # a yaw damper below its blow-off


@pytest.mark.parametrize("case, scales, kind, options, expected", [
    ("hunting_mm_declared_m", (1e3, 1.0), HUNTING, {}, ["implausible stroke", "m/s", "'mm'?", "--stroke-unit"]),
    ("sweep_kN_declared_N", (1.0, 1e-3), SWEEP, {}, ["implausible force for its stroke", "N s/m", "'kN'"]),
    ("hunting_m_declared_mm", (1.0, 1.0), HUNTING, {"stroke_unit": "mm"}, ["implausible stroke", "um", "Is it in 'm'"]),
    ("yaw_m_declared_mm", (1.0, 1.0), YAW, {"stroke_unit": "mm"}, ["implausible stroke for its force", "Is it in 'm'"]),
    ("sweep_N_declared_kN", (1.0, 1.0), SWEEP, {"force_unit": "kN"}, ["implausible force", "Is it in 'N'"]),
])
def test_unit_mistakes_are_refused_both_ways(tmp_path, case, scales, kind, options, expected):
    p = _sweep(tmp_path, case, *scales, **kind)
    with pytest.raises(DataError) as err:
        load_test(p, **options)
    msg = str(err.value)
    assert p.name in msg and "--accept-implausible" in msg
    for s in expected:
        assert s in msg, f"{s!r} not in {msg!r}"
    load_test(p, check_plausible=False, **options)  # the override reads it as declared


@pytest.mark.parametrize("kind", [HUNTING, SWEEP, YAW])
def test_the_right_units_pass(tmp_path, kind):
    load_test(_sweep(tmp_path, "si", 1.0, 1.0, **kind))
    load_test(_sweep(tmp_path, "mm_kn", 1e3, 1e-3, **kind), stroke_unit="mm", force_unit="kN")


def test_inspect_prints_what_was_understood(tmp_path, capsys, ref):
    """`inspect` on a compression-positive mm/kN file with an unused temperature-like column and a
    damper faster than the damping table's last abscissa."""
    from tuner.__main__ import main

    t = np.arange(0, 4.0, 1e-3)
    x = 0.05 * np.sin(2 * np.pi * 1.5 * t)  # 0.47 m/s peak: beyond the 100 mm/s table end
    f = 3e4 * np.gradient(x, t)
    p = tmp_path / "fast.csv"
    pd.DataFrame({"t [s]": t, "pos [mm]": -1e3 * x, "load [kN]": -f / 1e3, "Oil temp": 40.0 + 0 * t}) \
        .to_csv(p, index=False)
    args = ["inspect", str(p), "--time-col", "t", "--stroke-col", "pos", "--force-col", "load",
            "--stroke-sign", "-1", "--force-sign", "-1"]
    code = main(args)
    out = capsys.readouterr().out
    assert code == 0
    assert "stroke in mm, force in kN" in out
    assert "stroke x -1, force x -1" in out
    assert "-50 .. 50 mm" in out
    assert "beyond the damping table's last abscissa 100 mm/s" in out
    assert "'Oil temp'" in out and "--temperature-col" in out
    import json as _json

    assert main(args + ["--json"]) == 0
    figures = _json.loads(capsys.readouterr().out)  # the JSON alone on stdout
    assert figures[0]["coverage"]["velocity_peak_m_s"] == pytest.approx(2 * np.pi * 1.5 * 0.05, rel=0.01)


def test_column_mapping_file_and_cli_errors(tmp_path, capsys, ref):
    from tuner.__main__ import main

    p = tmp_path / "run_07.csv"
    pd.DataFrame({"Zeit": ref["time"], "Weg": -1e3 * ref["stroke"], "Kraft": ref["force"]}) \
        .to_csv(p, index=False, float_format="%.10g")
    mapping = tmp_path / "columns.toml"
    mapping.write_text('[columns]\ntime_col = "Zeit"\nstroke_col = "Weg"\nforce_col = "Kraft"\nstroke_unit = "mm"\n'
                       '[files."run_07.csv"]\nstroke_sign = -1\n')
    assert main(["inspect", str(p), "--columns", str(mapping)]) == 0
    assert "stroke x -1" in capsys.readouterr().out
    bad = tmp_path / "bad.toml"
    bad.write_text('[columns]\nstroke_units = "mm"\n')
    assert main(["inspect", str(p), "--columns", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "bad.toml" in err and "stroke_units" in err
    # without the mapping: the mm stroke read as m is refused, naming the file and the fix
    assert main(["inspect", str(p), "--time-col", "Zeit", "--stroke-col", "Weg", "--force-col", "Kraft"]) == 2
    err = capsys.readouterr().err
    assert "run_07.csv" in err and "implausible stroke" in err and "--stroke-unit" in err


def test_tables_cover_a_faster_dampers_velocity_range():
    """table_abscissae: Table 2's layout for the bundled data (peak 119 mm/s < 150), stretched for a
    damper driven to 0.6 m/s so that the last rate abscissa lies just above the peak, and the
    parametrization's bounds follow the stretched elongations."""
    from damper_fmu.parameters import FC_ABSCISSAE, FK_ABSCISSAE
    from tuner.identification.engine import Signals
    from tuner.identification.problem import table_abscissae
    from tuner.identification.parametrization import Parametrization

    t = np.arange(0, 5.0, 5e-3)

    def sig(vpeak):
        v = vpeak * np.sin(2 * np.pi * t)
        return Signals("s", t, v / (2 * np.pi), v, 0 * t, np.ones(t.size, dtype=bool), None, 1)

    slow = table_abscissae([sig(0.119)], 2.7e4)
    assert [slow[f"Fc_v{i:02d}"] for i in range(1, 15)] == pytest.approx(FC_ABSCISSAE)
    assert [slow[f"Fk_x{i:02d}"] for i in range(1, 11)] == pytest.approx(FK_ABSCISSAE)
    fast = table_abscissae([sig(0.6)], 1.2e5)
    assert fast["Fc_v14"] == pytest.approx(1.05 * 0.6) and fast["Fc_v01"] == pytest.approx(-1.05 * 0.6)
    ratio = fast["Fc_v08"] / FC_ABSCISSAE[7]
    assert all(fast[f"Fc_v{i:02d}"] / FC_ABSCISSAE[i - 1] == pytest.approx(ratio) for i in range(1, 15))
    assert fast["Fk_x10"] == pytest.approx(1.05 * 1.2e5 / 1.5e7)
    par = Parametrization("lumped", force_limit=1.8e5, fixed=fast)
    lo, hi = par.bounds["Fk_10"]
    assert lo == pytest.approx(0.2 * 1.5e7 * fast["Fk_x10"]) and hi == pytest.approx(3 * 1.5e7 * fast["Fk_x10"])
    with pytest.raises(ValueError, match="14 increasing nonzero"):
        table_abscissae([sig(0.6)], 1e4, damping=[0.1] * 14)


def test_a_fit_of_a_faster_damper_exports_tables_covering_its_velocity_range(tmp_path):
    """End to end: a Maxwell-like damper driven to ~0.6 m/s (6 x the bundled data's peak), one
    Firefly generation: the tuned FMU's damping table reaches beyond the data's peak velocity."""
    import zipfile
    import xml.etree.ElementTree as ET

    from damper_fmu import simulate
    from tuner.__main__ import main

    files = []
    for k, role in enumerate(("id", "val")):
        t = np.arange(0, 4.0, 1e-3)
        x = 0.04 * np.sin(2 * np.pi * 2.4 * t + k) * np.minimum(t, 1.0)
        v = np.gradient(x, t)
        f = simulate("maxwell", t, x, v, params={"k_s": 2e7, "c": 2e4})
        files.append(tmp_path / f"{role}.csv")
        pd.DataFrame({"time": t, "stroke [mm]": 1e3 * x, "force [kN]": f / 1e3}).to_csv(files[-1], index=False)
    out = tmp_path / "fit"
    assert main(["fit", "--identification", str(files[0]), "--validation", str(files[1]), "--out", str(out),
                 "--models", "lumped", "--population", "3", "--iterations", "1", "--polish", "0", "--workers", "0",
                 "--no-diagnose", "--diff-band", "40",
                 "--engine", "inprocess" if native_reason() else "native"]) == 0
    settings = __import__("json").loads((out / "metrics.json").read_text())["settings"]
    assert settings["diff_band_hz"] == 40.0 and "0.5 % up to 40 Hz" in settings["preprocessing"][0]
    vals = __import__("json").loads((out / "parameters.json").read_text())["lumped"]["values"]
    assert vals["Fc_v14"] > 0.6 and vals["Fc_v01"] < -0.6
    fmu = next((out / "fmu").glob("DamperLumped*_tuned.fmu"))
    with zipfile.ZipFile(fmu) as z:
        md = ET.fromstring(z.read("modelDescription.xml"))
    start = {v.get("name"): float(v.find("Real").get("start")) for v in md.iter("ScalarVariable")
             if v.find("Real") is not None and v.find("Real").get("start") is not None}
    assert start["Fc_v14"] == pytest.approx(vals["Fc_v14"])


def test_quality_gate_names_a_model_that_does_not_describe_the_data():
    from tuner.identification.fit import QUALITY_AME_PCT, quality_gate

    tests = {"a": {"role": "identification", "models": {"m": {"ame": 900.0, "peak_measured": 1e4}}},
             "b": {"role": "validation", "models": {"m": {"ame": 300.0, "peak_measured": 1e4}}},
             "c": {"role": "validation", "models": {"m": {"ame": 1500.0, "peak_measured": 1e4}}}}
    q = quality_gate(tests, ["m"])["m"]
    assert q["worst_test"] == "c" and q["worst_ame_pct_of_peak"] == pytest.approx(15.0)
    assert q["describes_data"] is (15.0 <= QUALITY_AME_PCT) and "does NOT describe" in q["text"]
    del tests["c"]
    q = quality_gate(tests, ["m"])["m"]
    assert q["describes_data"] and q["worst_test"] == "b"  # held-out tests only
    q = quality_gate({"a": tests["a"]}, ["m"])["m"]
    assert q["worst_test"] == "a" and "no held-out test" in q["text"]


@pytest.mark.parametrize("signs, refused", [((1, 1), False), ((-1, -1), False), ((1, -1), True), ((-1, 1), True)])
def test_a_flipped_sign_is_refused_because_a_damper_absorbs_power(tmp_path, ref, signs, refused):
    """The bundled twin-tube test written with stroke/force signs flipped: both flipped is only
    another convention (power unchanged) and passes; one flipped makes the damper deliver power."""
    p = tmp_path / "signs.csv"
    pd.DataFrame({"time": ref["time"], "stroke": signs[0] * ref["stroke"], "force": signs[1] * ref["force"]}) \
        .to_csv(p, index=False, float_format="%.10g")
    if refused:
        with pytest.raises(DataError, match="anti-correlated.*--force-sign -1"):
            load_test(p)
        g = load_test(p, force_sign=signs[1], stroke_sign=signs[0])  # the fix the message names
        assert g.metadata["read"]["plausibility"]["force_velocity_correlation"] > 0.3
    else:
        load_test(p)


def test_columns_nobody_asked_for_do_not_refuse_the_file_and_keep_their_declared_units(tmp_path):
    """A logger's file: a sample-rate constant written once in the first row, an empty trailing
    column, a thermocouple in volts next to the oil temperature in degC. The columns in use are read
    in their declared units; the incomplete ones are left out with a warning naming them; the volt
    column is a channel in V (not taken for the oil temperature)."""
    rate = 300.0
    t = np.arange(2000) / rate
    x_mm = 5.0 * np.sin(2 * np.pi * t)
    path = tmp_path / "logger.csv"
    with open(path, "w") as f:
        f.write("Time (s),Displacement (mm),Load (kN),Force (V),Temperature (V),fs,\n")
        for i in range(t.size):
            f.write(f"{t[i]:.5f},{x_mm[i]:.4f},{3 * x_mm[i]:.4f},{0.1 * x_mm[i]:.4f},{1.5 + 1e-3 * i:.4f},"
                    f"{'300' if i == 0 else ''},\n")
    (test,) = load_tests(path, time_col="Time (s)", stroke_col="Displacement (mm)", force_col="Load (kN)")
    assert np.allclose(test.stroke, 1e-3 * x_mm, atol=1e-7) and np.allclose(test.force, 3e3 * x_mm, atol=0.1)
    assert test.channel_units["Force (V)"] == "V" and test.channel_units["Temperature (V)"] == "V"
    assert "temperature" not in test.channels
    read = test.metadata["read"]
    assert "fs" in read["ignored"] and "fs" not in test.channels
    warnings = " ".join(test.metadata["warnings"])
    assert "'fs' not read" in warnings and "not a temperature unit" in warnings
    # a channel the user asks for must still be complete
    with pytest.raises(DataError, match="'fs' is NaN"):
        load_tests(path, time_col="Time (s)", stroke_col="Displacement (mm)", force_col="Load (kN)",
                   extra_cols=["fs"])


def test_a_force_in_kn_read_as_n_is_flagged_by_the_damper_class(tmp_path):
    """A yaw damper's 76 mm stroke with a force column of 18 N peak (kN values read as N, above the
    hard 200 N s/m floor): read with a warning naming the yaw range and suggesting kN; silent with
    --damper-class any, and silent on the bundled yaw-damper campaign."""
    from tuner.data.reading import DAMPER_CLASSES

    t = np.arange(3000) / 200.0
    x_mm = 38.0 * np.sin(2 * np.pi * 0.5 * t)
    f = 300.0 * np.gradient(x_mm, t) / 1000.0  # 300 N s/m: a 3e5 N s/m damper's kN figures
    p = tmp_path / "yaw.csv"
    pd.DataFrame({"time": t, "stroke [mm]": x_mm, "force [N]": f}).to_csv(p, index=False)
    (test,) = load_tests(p)
    (warning,) = [w for w in test.metadata["warnings"] if "apparent damping" in w]
    assert "below the yaw damper range" in warning and "Is it in 'kN'?" in warning
    (test,) = load_tests(p, damper_class="any")
    assert not any("apparent damping" in w for w in test.metadata.get("warnings", []))
    with pytest.raises(ValueError, match="unknown damper class"):
        load_tests(p, damper_class="bogie")
    lo, hi = DAMPER_CLASSES["yaw"]
    for t_ in load_dataset(DEFAULT_DATASET):
        assert lo <= t_.metadata["read"]["plausibility"]["apparent_damping_n_s_per_m"] <= hi
        assert not any("apparent damping" in w for w in t_.metadata.get("warnings", []))
