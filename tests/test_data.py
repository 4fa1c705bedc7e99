"""Measured-data format: writer, reader, checks, resampling and differentiator."""
import gzip
import json
import math

import numpy as np
import pandas as pd
import pytest

from damper_dataset.writer import write_dataset
from tuner.data.reading import DataError, RigTest, load_dataset, load_files, load_test
from tuner.data.preprocess import Resampler, prepare
from tuner.data.differentiator import Differentiator

FS = 1000.0


def _frame(n=2000, fs=FS, seed=0, temperature=True):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    phase = rng.uniform(0, 6)
    x = 0.02 * np.sin(2 * np.pi * 0.7 * t + phase) + 1e-3 * rng.standard_normal(n)
    f = 8e3 * np.sin(2 * np.pi * 0.7 * t + phase + 1.2) + 50 * rng.standard_normal(n)  # a damper: leads x
    cols = {"time": t, "stroke": x, "force": f}
    if temperature:
        cols["temperature"] = 25 + 10 * t / t[-1] + 0.01 * rng.standard_normal(n)
    return pd.DataFrame(cols)


def _tests(seed=0, **kw):
    return [dict(name="id_1", role="identification", scenario="straight 250 km/h",
                 frame=_frame(seed=seed, **kw), speed_kmh=250.0),
            dict(name="val_1", role="validation", scenario="curve R 500 m",
                 frame=_frame(n=1500, seed=seed + 1, **kw), speed_kmh=86.0, radius_m=500)]


def _write(folder, tests=None, **kw):
    return write_dataset(folder, tests or _tests(), "unit-test dataset", {"seed": 0}, **kw)


# --------------------------------------------------------------------------- writer / reader

def test_round_trip_within_written_resolution(tmp_path):
    tests = _tests()
    _write(tmp_path / "ds", tests)
    got = load_dataset(tmp_path / "ds")
    assert [g.name for g in got] == ["id_1", "val_1"]
    for src, g in zip(tests, got):
        fr = src["frame"]
        assert g.role == src["role"] and g.scenario == src["scenario"]
        assert g.metadata["speed_kmh"] == src["speed_kmh"]
        assert g.sample_rate == pytest.approx(FS, rel=1e-9)
        assert g.channel_units == {"temperature": "degC"}
        # half of the written resolution, plus float rounding
        assert np.max(np.abs(g.time - fr["time"])) <= 0.5e-6 + 1e-12
        assert np.max(np.abs(g.stroke - fr["stroke"])) <= 0.5e-9 + 1e-15
        assert np.max(np.abs(g.force - fr["force"])) <= 0.05 + 1e-9
        assert np.max(np.abs(g.channels["temperature"] - fr["temperature"])) <= 0.005 + 1e-12
    assert got[1].metadata["radius_m"] == 500


def test_time_digits_follow_sample_rate(tmp_path):
    fs = 1024.0  # period 0.9765625 ms: needs more than 6 decimals
    tests = [dict(name="a", role="identification", scenario="s",
                  frame=_frame(n=3000, fs=fs, temperature=False))]
    _write(tmp_path / "ds", tests)
    g = load_dataset(tmp_path / "ds")[0]
    assert g.sample_rate == pytest.approx(fs, rel=1e-9)
    assert np.max(np.abs(np.diff(g.time) * fs - 1.0)) < 1e-3


def test_writer_is_bit_for_bit_deterministic(tmp_path):
    _write(tmp_path / "a", _tests(seed=3))
    _write(tmp_path / "b", _tests(seed=3))  # fresh but equal input objects
    names = sorted(p.name for p in (tmp_path / "a").iterdir())
    assert names == sorted(p.name for p in (tmp_path / "b").iterdir())
    assert names == ["id_1.csv", "manifest.json", "val_1.csv"]
    for n in names:
        assert (tmp_path / "a" / n).read_bytes() == (tmp_path / "b" / n).read_bytes()
    man = json.loads((tmp_path / "a" / "manifest.json").read_text())
    assert man["format"] == "damper-rig-dataset/1"
    assert man["units"] == {"time": "s", "stroke": "m", "force": "N", "temperature": "degC"}
    assert {t["role"] for t in man["tests"]} == {"identification", "validation"}


def test_refuses_to_overwrite_then_replaces_atomically(tmp_path):
    out = tmp_path / "ds"
    _write(out, _tests(seed=1))
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    with pytest.raises(FileExistsError, match="overwrite"):
        _write(out, _tests(seed=2))
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    (out / "stale.txt").write_text("old")
    _write(out, [_tests(seed=2)[0]], overwrite=True)
    assert sorted(p.name for p in out.iterdir()) == ["id_1.csv", "manifest.json"]
    assert (out / "id_1.csv").read_bytes() != before["id_1.csv"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds"]  # no temp/backup left
    empty = tmp_path / "empty"
    empty.mkdir()
    _write(empty)  # an existing empty folder is not "overwriting"
    assert (empty / "manifest.json").is_file()


def test_failed_overwrite_keeps_old_dataset(tmp_path):
    out = tmp_path / "ds"
    _write(out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    bad = _tests()
    bad[1]["frame"].loc[10, "force"] = np.nan
    with pytest.raises(DataError, match="NaN"):
        _write(out, bad, overwrite=True)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds"]


@pytest.mark.parametrize("mutate, message", [
    (lambda t: t[0].update(role="training"), "unknown role"),
    (lambda t: t[1].update(name="id_1"), "duplicated test name"),
    (lambda t: t[0].update(name="a/b"), "file-safe"),
    (lambda t: t[0].update(frame=t[0]["frame"].drop(columns="force")), "lacks column"),
    (lambda t: t[0]["frame"].insert(3, "pressure", 1.0), "unit of channel 'pressure'"),
    (lambda t: t[0].update(sample_rate_hz=5.0), "set by the writer"),
])
def test_writer_rejects_bad_input(tmp_path, mutate, message):
    tests = _tests()
    mutate(tests)
    with pytest.raises(ValueError, match=message):
        _write(tmp_path / "ds", tests)
    assert not (tmp_path / "ds").exists()


def test_writer_accepts_custom_channel_units(tmp_path):
    tests = _tests()
    tests[0]["frame"]["pressure"] = 1e5 + np.arange(2000.0)
    tests[1]["frame"]["pressure"] = 2e5 + np.arange(1500.0)
    _write(tmp_path / "ds", tests, channel_units={"pressure": "Pa"})
    got = load_dataset(tmp_path / "ds")
    assert got[0].channel_units["pressure"] == "Pa"
    np.testing.assert_allclose(got[0].channels["pressure"], tests[0]["frame"]["pressure"],
                               rtol=1e-10)


# --------------------------------------------------------------------------- units and formats

def _csv(path, cols: dict, comment="# test file", fmt="%.10g"):
    names = list(cols)
    rows = [",".join(fmt % v for v in vals) for vals in zip(*cols.values())]
    path.write_text("\n".join([comment, ",".join(names), *rows]) + "\n")
    return path


def test_unit_conversion_to_si(tmp_path):
    fr = _frame(n=500)
    p = _csv(tmp_path / "mm_kn.csv", {
        "t_ms": fr["time"] * 1e3, "x_mm": fr["stroke"] * 1e3, "F_kN": fr["force"] / 1e3,
        "temperature": fr["temperature"] + 273.15})
    g = load_test(p, time_col="t_ms", stroke_col="x_mm", force_col="F_kN", time_unit="ms",
                  stroke_unit="mm", force_unit="kN", channel_units={"temperature": "K"})
    np.testing.assert_allclose(g.time, fr["time"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(g.stroke, fr["stroke"], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(g.force, fr["force"], rtol=1e-9)
    np.testing.assert_allclose(g.channels["temperature"], fr["temperature"], atol=1e-9)
    assert g.sample_rate == pytest.approx(FS)
    assert g.name == "mm_kn" and g.role is None
    for unit, factor in [("cm", 1e-2), ("um", 1e-6)]:
        q = _csv(tmp_path / f"{unit}.csv", {"time": fr["time"], "stroke": fr["stroke"] / factor,
                                            "force": fr["force"] / 10})
        g = load_test(q, stroke_unit=unit, force_unit="daN")
        np.testing.assert_allclose(g.stroke, fr["stroke"], rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(g.force, fr["force"], rtol=1e-9)


def test_dataset_units_from_manifest(tmp_path):
    fr = _frame(n=300, temperature=False)
    _csv(tmp_path / "a.csv", {"time": fr["time"] * 1e3, "stroke": fr["stroke"] * 1e3,
                              "force": fr["force"] / 1e3})
    (tmp_path / "manifest.json").write_text(json.dumps({
        "format": "damper-rig-dataset/1", "description": "", "created_by": "hand",
        "generator": {}, "units": {"time": "ms", "stroke": "mm", "force": "kN"},
        "tests": [{"name": "a", "file": "a.csv", "role": "validation", "scenario": "x",
                   "sample_rate_hz": 1000}]}))
    g = load_dataset(tmp_path)[0]
    np.testing.assert_allclose(g.stroke, fr["stroke"], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(g.force, fr["force"], rtol=1e-9)
    assert g.role == "validation" and g.sample_rate == 1000


def test_gzip_and_load_files(tmp_path):
    fr = _frame(n=400)
    p = _csv(tmp_path / "a.csv", dict(fr))
    z = tmp_path / "b.csv.gz"
    z.write_bytes(gzip.compress(p.read_bytes()))
    a, b = load_files([p, z], "identification")
    assert a.role == b.role == "identification" and b.name == "b"
    np.testing.assert_array_equal(a.force, b.force)
    np.testing.assert_array_equal(a.channels["temperature"], b.channels["temperature"])
    only = load_test(p, extra_cols=[])
    assert only.channels == {}


def test_parquet_if_available(tmp_path):
    pytest.importorskip("pyarrow")
    fr = _frame(n=400)
    fr.to_parquet(tmp_path / "a.parquet")
    g = load_test(tmp_path / "a.parquet")
    np.testing.assert_array_equal(g.force, fr["force"].to_numpy())


# --------------------------------------------------------------------------- error paths

def _good_cols(n=200):
    t = np.arange(n) / FS
    return {"time": list(t), "stroke": list(0.01 * np.sin(2 * np.pi * 2 * t)),
            "force": list(1e3 * np.cos(2 * np.pi * 2 * t))}


def _raw(path, cols, header=None):
    lines = ["# comment line", header or ",".join(cols)]
    lines += [",".join(str(v) for v in row) for row in zip(*cols.values())]
    path.write_text("\n".join(lines) + "\n")
    return path


def _set(cols, col, row, value):  # row: 1-based data row -> file line row + 2
    cols[col][row - 1] = value
    return cols


ERROR_CASES = {
    "missing_file": (None, {}, ["not found"]),
    "empty_file": (lambda p: p.write_text(""), {}, ["empty"]),
    "comments_only": (lambda p: p.write_text("# a\n\n# b\n"), {}, ["empty"]),
    "header_only": (lambda p: p.write_text("time,stroke,force\n"), {}, ["no data rows"]),
    "missing_column": (lambda p: _raw(p, {"time": [0], "stroke": [0], "load": [0]}), {},
                       ["missing column", "'force'", "columns found", "'load'", "--force-col"]),
    "non_numeric": (lambda p: _raw(p, _set(_good_cols(), "force", 50, "12x5")),
                    {}, ["non-numeric", "'12x5'", "'force'", "data row 50", "line 52"]),
    "nan": (lambda p: _raw(p, _set(_good_cols(), "stroke", 77, "nan")), {},
            ["NaN", "'stroke'", "data row 77", "line 79"]),
    "empty_field": (lambda p: _raw(p, _set(_good_cols(), "force", 3, "")), {},
                    ["NaN", "'force'", "data row 3"]),
    "inf": (lambda p: _raw(p, _set(_good_cols(), "force", 120, "inf")), {},
            ["infinite", "'force'", "data row 120"]),
    "non_monotonic": (lambda p: _raw(p, _set(_good_cols(), "time", 31, 0.0285)), {},
                      ["not increasing", "data row 31"]),
    "gap": (lambda p: _raw(p, {k: v[:100] + v[110:] for k, v in _good_cols().items()}),
            {}, ["gap of", "11 samples", "data row 101", "--t-start"]),
    "too_short": (lambda p: _raw(p, {k: v[:99] for k, v in _good_cols().items()}), {},
                  ["too short", "99 samples", "100"]),
    "stroke_in_mm_read_as_m": (
        lambda p: _raw(p, {**_good_cols(), "stroke": [3e3 * v for v in _good_cols()["stroke"]]}),
        {}, ["implausible stroke", "'mm'"]),
    "force_in_kN_read_as_N": (
        lambda p: _raw(p, {**_good_cols(), "force": [v / 2e3 for v in _good_cols()["force"]]}),
        {}, ["implausible force", "'kN'"]),
    "time_in_ms_read_as_s": (
        lambda p: _raw(p, {**_good_cols(), "time": [v * 1e3 for v in _good_cols()["time"]]}),
        {}, ["implausible sample rate", "'ms'"]),
    "unknown_unit": (lambda p: _raw(p, _good_cols()), {"stroke_unit": "inch"},
                     ["unknown stroke unit", "'inch'"]),
    "spreadsheet": (lambda p: p.write_text("x"), {"_suffix": ".xlsx"}, ["save the sheet as CSV"]),
    "position_out_of_range": (lambda p: _raw(p, _good_cols()), {"force_col": 7}, ["position 7", "3 columns"]),
    "unit_conflict": (lambda p: _raw(p, _good_cols(), header="time,stroke [mm],force"), {"stroke_unit": "m"},
                      ["declares 'mm'", "--stroke-unit 'm'"]),
    "timestamps_garbled": (lambda p: _raw(p, {**_good_cols(), "time": ["2026-01-01T00:00:00"] * 199 + ["soon"]}),
                           {}, ["neither numbers nor timestamps", "'soon'", "data row 200"]),
    "no_time_no_rate": (lambda p: _raw(p, {k: v for k, v in _good_cols().items() if k != "time"}),
                        {"time_col": None}, ["--rate"]),
    "bad_extension": (lambda p: p.write_text("x"), {"_suffix": ".xlsx"}, ["unsupported"]),
    "missing_extra_col": (lambda p: _raw(p, _good_cols()), {"extra_cols": ["temperature"]},
                          ["missing column", "'temperature'"]),
}


@pytest.mark.parametrize("case", sorted(ERROR_CASES))
def test_reader_errors_name_file_and_problem(tmp_path, case):
    make, kwargs, expected = ERROR_CASES[case]
    kwargs = dict(kwargs)
    path = tmp_path / f"{case}{kwargs.pop('_suffix', '.csv')}"
    if make is not None:
        make(path)
    with pytest.raises(DataError) as err:
        load_test(path, **kwargs)
    assert isinstance(err.value, ValueError)
    msg = str(err.value)
    assert path.name in msg
    for s in expected:
        assert s in msg, f"{s!r} not in {msg!r}"


def test_good_file_of_error_fixture_loads(tmp_path):
    """The fixture the error cases mutate is itself valid (so each case tests one defect)."""
    g = load_test(_raw(tmp_path / "ok.csv", _good_cols()))
    assert len(g.time) == 200 and g.sample_rate == pytest.approx(FS)


def _manifest_case(tmp_path, mutate):
    _write(tmp_path / "ds")
    mpath = tmp_path / "ds" / "manifest.json"
    man = json.loads(mpath.read_text())
    mutate(man, tmp_path / "ds")
    mpath.write_text(json.dumps(man))
    return tmp_path / "ds"


@pytest.mark.parametrize("mutate, expected", [
    (lambda m, d: m["tests"][1].update(role="training"), ["'val_1'", "unknown role", "training"]),
    (lambda m, d: m["tests"][0].update(file="nope.csv"), ["'id_1'", "'nope.csv'", "not exist"]),
    (lambda m, d: (d / "val_1.csv").unlink(), ["'val_1'", "'val_1.csv'", "not exist"]),
    (lambda m, d: m.update(format="other/2"), ["format", "'other/2'"]),
    (lambda m, d: m["tests"][0].pop("role"), ["tests[0]", "'role'"]),
    (lambda m, d: m["tests"][1].update(name="id_1"), ["duplicated test name"]),
    (lambda m, d: m["tests"][0].update(sample_rate_hz=500.0), ["id_1.csv", "500", "Hz"]),
    (lambda m, d: m["units"].update(force="lbf"), ["id_1.csv", "unknown force unit", "'lbf'"]),
    (lambda m, d: m.update(tests=[]), ["non-empty"]),
])
def test_manifest_errors(tmp_path, mutate, expected):
    folder = _manifest_case(tmp_path, mutate)
    with pytest.raises(DataError) as err:
        load_dataset(folder)
    for s in expected:
        assert s in str(err.value), f"{s!r} not in {err.value}"


def test_missing_manifest_and_folder(tmp_path):
    with pytest.raises(DataError, match="manifest not found"):
        load_dataset(tmp_path)
    with pytest.raises(DataError, match="folder not found"):
        load_dataset(tmp_path / "nowhere")
    (tmp_path / "manifest.json").write_text("{not json")
    with pytest.raises(DataError, match="invalid JSON"):
        load_dataset(tmp_path)


def test_unknown_role_in_load_files(tmp_path):
    p = _raw(tmp_path / "a.csv", _good_cols())
    with pytest.raises(DataError, match="unknown role 'fit'"):
        load_files([p], "fit")


def _same_test(a: RigTest, b: RigTest):
    assert (a.name, a.role, a.scenario, a.sample_rate, a.channel_units) == (b.name, b.role, b.scenario,
                                                                           b.sample_rate, b.channel_units)
    for x, y in ((a.time, b.time), (a.stroke, b.stroke), (a.force, b.force)):
        np.testing.assert_array_equal(x, y)
    assert a.metadata == b.metadata


def test_the_reader_options_as_one_record_read_as_the_keywords_do(tmp_path):
    """``ReadOptions`` (issue 64): its defaults are the reader's, a file read with the record is the file read
    with the same options by keyword (``load_tests``, ``load_test``, ``load_files``), keywords go over a
    record, and the record is frozen."""
    import dataclasses

    from tuner.data.reading import ReadOptions, load_tests

    fr = _frame(n=500)
    p = _csv(tmp_path / "a.csv", {"t_ms": fr["time"] * 1e3, "x_mm": fr["stroke"] * 1e3, "F_kN": -fr["force"] / 1e3})
    kw = dict(time_col="t_ms", stroke_col="x_mm", force_col="F_kN", time_unit="ms", stroke_unit="mm",
              force_unit="kN", force_sign=-1, t_start=0.1, damper_class="any")
    record = ReadOptions(**kw)
    _same_test(load_test(p, record), load_test(p, **kw))
    _same_test(load_tests(p, record)[0], load_tests(p, **kw)[0])
    (a,), (b,) = load_files([p], "validation", record), load_files(p, "validation", **kw)
    _same_test(a, b)
    assert a.role == "validation" and a.metadata["read"]["signs"] == {"stroke": 1, "force": -1}
    assert load_test(p, record, t_start=0.2).duration == pytest.approx(a.duration - 0.1, abs=2 / FS)
    q = _csv(tmp_path / "plain.csv", dict(fr))
    _same_test(load_test(q), load_test(q, ReadOptions()))
    assert record.merged({"force_sign": 1}, t_start=None) == ReadOptions(**{**kw, "force_sign": 1, "t_start": None})
    assert record.merged() is record and record.signs == {"stroke": 1, "force": -1}
    with pytest.raises(dataclasses.FrozenInstanceError):
        record.force_sign = 1


def test_an_unknown_reader_option_is_named_with_the_known_ones(tmp_path):
    """By keyword, in a record or in a record's overrides: TypeError naming the option and listing the known
    ones; a mapping given where the record goes is refused (keywords take single options)."""
    from tuner.data.reading import ReadOptions

    p = _raw(tmp_path / "a.csv", _good_cols())
    for call in (lambda: ReadOptions(stroke_units="mm"), lambda: ReadOptions().merged({"stroke_units": "mm"}),
                 lambda: load_files([p], "identification", stroke_units="mm"),
                 lambda: load_test(p, ReadOptions(), stroke_units="mm")):
        with pytest.raises(TypeError, match=r"unknown reader option\(s\) \['stroke_units'\]; known: time_col, "
                                            r"stroke_col, .*stroke_unit, .*damper_class"):
            call()
    with pytest.raises(TypeError, match="must be a ReadOptions"):
        load_test(p, {"stroke_unit": "mm"})


def test_the_mapping_file_and_the_command_line_give_one_record_per_file(tmp_path):
    """``column_options``: the defaults, then the mapping file's [columns], then its entry for the file, then
    the command line (which wins); every option of a mapping file is a field of the record, and every one
    the command line names by itself has its option."""
    import argparse

    from tuner.cli.options import DATA_OPTIONS, add_data_options, column_options
    from tuner.data.reading import COLUMN_OPTIONS, READ_OPTIONS, ReadOptions

    mapping = tmp_path / "columns.toml"
    mapping.write_text('[columns]\ntime_col = "Zeit"\nstroke_unit = "mm"\nforce_sign = -1\n'
                       '[files."run_07.csv"]\nstroke_unit = "cm"\nforce_zero = 0.5\nprefilter = "moving-average:0.02"\n')
    ap = argparse.ArgumentParser()
    add_data_options(ap)
    every, per_file = column_options(ap.parse_args(["--columns", str(mapping), "--force-zero", "0.25", "--rate",
                                                    "500", "--accept-implausible"]))
    assert every == ReadOptions(time_col="Zeit", stroke_unit="mm", force_sign=-1, force_zero=0.25, rate_hz=500.0,
                                check_plausible=False)
    assert per_file == {"run_07.csv": every.merged(stroke_unit="cm", prefilter="moving-average:0.02")}
    assert column_options(ap.parse_args(["--time-col", "none"]))[0] == ReadOptions(time_col=None)
    assert set(COLUMN_OPTIONS) <= set(READ_OPTIONS)
    assert set(DATA_OPTIONS) <= {a.dest for a in ap._actions}


# --------------------------------------------------------------------------- differentiator

def _lsq_derivative_coeffs(window, fs, order=3):
    """Least-squares cubic fit over a centred window: slope at the centre (independent)."""
    k = np.arange(window) - (window - 1) // 2
    vander = np.vander(k, order + 1, increasing=True)
    return np.linalg.pinv(vander)[1] * fs  # y'[n] = sum_k c_k x[n + k]


def _amp_phase(t, y, f):
    a = np.column_stack([np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t)])
    c, s = np.linalg.lstsq(a, y, rcond=None)[0]
    return math.hypot(c, s), math.atan2(-s, c)  # y = A cos(2 pi f t + phi)


@pytest.mark.parametrize("fs", [500.0, 1000.0, 2000.0])
def test_differentiator_accurate_to_one_percent_up_to_20hz(fs):
    d = Differentiator.design(fs)
    t = np.arange(int(4 * fs)) / fs
    m = d.window
    for f in [0.5, 2.0, 5.0, 10.0, 15.0, 20.0]:
        v = d.apply(1e-3 * np.cos(2 * np.pi * f * t + 0.4))
        amp, ph = _amp_phase(t[m:-m], v[m:-m], f)
        assert abs(amp / (1e-3 * 2 * np.pi * f) - 1) < 0.01, (fs, f)
        assert abs(ph - (0.4 + np.pi / 2)) < 1e-3, (fs, f)  # zero-phase


def test_differentiator_sum_of_sinusoids_vs_analytic():
    comps = [(0.02, 0.3, 0.1), (3e-3, 2.1, 1.0), (1e-3, 7.0, 2.0), (2e-4, 13.0, 0.5),
             (1e-4, 20.0, 3.0)]  # (amplitude [m], frequency [Hz], phase [rad])
    t = np.arange(8000) / FS
    x = sum(a * np.sin(2 * np.pi * f * t + p) for a, f, p in comps)
    v_true = sum(a * 2 * np.pi * f * np.cos(2 * np.pi * f * t + p) for a, f, p in comps)
    bound = 0.01 * sum(a * 2 * np.pi * f for a, f, _ in comps)  # 1 % of each component
    d = Differentiator.design(FS)
    m = d.window
    assert np.max(np.abs(d.apply(x) - v_true)[m:-m]) < bound
    # the same through prepare(), without and with resampling
    test = RigTest("s", "identification", "", t, x, 1e3 * v_true, sample_rate=FS)
    for rate in (FS, 200.0):
        p = prepare(test, rate)
        vt = sum(a * 2 * np.pi * f * np.cos(2 * np.pi * f * p.time + c) for a, f, c in comps)
        k = d.window if p.resampler is None else 0  # SG one-sided fit at the raw ends
        assert np.max(np.abs(p.stroke_velocity - vt)[k:len(vt) - k]) < bound, rate


def test_differentiator_is_the_documented_filter():
    d = Differentiator.design(FS)
    assert d.polyorder == 3 and d.window % 2 == 1
    assert 5e-3 <= d.window / FS <= 40e-3  # "a few ms" to a few tens of ms
    c = _lsq_derivative_coeffs(d.window, FS)
    x = np.random.default_rng(1).standard_normal(3000)
    windows = np.lib.stride_tricks.sliding_window_view(x, d.window)
    m = (d.window - 1) // 2
    np.testing.assert_allclose(d.apply(x)[m:-m], windows @ c, rtol=1e-9, atol=1e-9 * FS)
    # frequency response from the independent coefficients
    k = np.arange(d.window) - m
    f = np.linspace(0.1, FS / 2, 5000)
    rel = np.abs(np.exp(2j * np.pi * np.outer(f, k) / FS) @ c) / (2 * np.pi * f)
    assert np.max(np.abs(rel[f <= 20] - 1)) < 0.01
    f3 = f[np.argmax(rel < 1 / np.sqrt(2))]
    assert d.cutoff_hz == pytest.approx(f3, abs=0.2)
    # longest window meeting the requirement: one step longer breaks the design tolerance
    c2 = _lsq_derivative_coeffs(d.window + 2, FS)
    k2 = np.arange(d.window + 2) - m - 1
    fb = np.linspace(0.1, 20, 200)
    rel2 = np.abs(np.exp(2j * np.pi * np.outer(fb, k2) / FS) @ c2) / (2 * np.pi * fb)
    assert np.max(np.abs(rel2 - 1)) > d.tol


def test_differentiator_noise_gain():
    sigma = 1e-6  # white stroke noise [m]
    x = sigma * np.random.default_rng(2).standard_normal(200_000)
    d = Differentiator.design(FS)
    m = d.window
    v = d.apply(x)[m:-m]
    expected = sigma * np.linalg.norm(_lsq_derivative_coeffs(d.window, FS))
    assert np.std(v) == pytest.approx(expected, rel=0.02)
    central = np.std((x[2:] - x[:-2]) * FS / 2)  # central difference on the same noise
    assert np.std(v) < 0.2 * central


# --------------------------------------------------------------------------- resampling

def test_resampling_preserves_low_frequency_and_removes_alias():
    t = np.arange(10_000) / FS
    slow = np.sin(2 * np.pi * 3.0 * t + 0.2)
    x = slow + 0.5 * np.sin(2 * np.pi * 150.0 * t)  # 150 Hz > new Nyquist 100 Hz
    test = RigTest("r", "validation", "", t, 0.01 * x, 1e3 * x, {"temperature": 20 + x},
                   sample_rate=FS, channel_units={"temperature": "degC"})
    p = prepare(test, 200.0)
    assert p.sample_rate == 200.0 and p.resampler is not None
    k = (p.time - t[0]) * 200.0  # output on the grid t0 + k / 200 Hz
    np.testing.assert_allclose(k, np.round(k), atol=1e-6)
    np.testing.assert_allclose(np.diff(p.time), 1 / 200.0, rtol=1e-9)
    # edge loss: at most the filter half length (+ one output period) at each end
    half_s = (len(p.resampler.taps) - 1) / 2 / FS
    assert t[0] < p.time[0] <= t[0] + half_s + 1 / 200
    assert t[-1] - half_s - 1 / 200 <= p.time[-1] <= t[-1]
    ref = np.sin(2 * np.pi * 3.0 * p.time + 0.2)
    for y, scale in [(p.force, 1e3), (p.stroke, 0.01), (p.channels["temperature"] - 20, 1.0)]:
        assert np.max(np.abs(y / scale - ref)) < 2e-3  # everywhere: no edge transient
        alias, _ = _amp_phase(p.time, y / scale, 50.0)  # 150 Hz folds to 50 Hz
        assert alias < 1e-3
    naive_alias, _ = _amp_phase(t[::5], x[::5], 50.0)
    assert naive_alias > 0.45  # the test signal does alias without the filter


def test_resampling_passband_and_rational_ratio():
    t = np.arange(6000) / FS
    for rate, f in [(200.0, 60.0), (300.0, 100.0), (250.0, 2.0)]:
        rs = Resampler.design(FS, rate)
        assert rs.rate_out == pytest.approx(rate, rel=1e-12)
        y = rs.apply(np.cos(2 * np.pi * f * t + 0.3))
        to = (rs.first_index() + np.arange(len(y))) / rate
        amp, ph = _amp_phase(to, y, f)
        assert abs(amp - 1) < 2e-3 and abs(ph - 0.3) < 1e-3, rate  # flat, zero-phase
    with pytest.raises(ValueError, match="ratio"):
        Resampler.design(FS, 1000.0 * math.sqrt(2) / 3, max_denominator=20)


def test_prepare_at_source_rate_changes_nothing():
    fr = _frame(n=1000)
    test = RigTest("n", "identification", "sc", fr["time"].to_numpy(), fr["stroke"].to_numpy(),
                   fr["force"].to_numpy(), {"temperature": fr["temperature"].to_numpy()},
                   sample_rate=FS, metadata={"speed_kmh": 43})
    p = prepare(test, FS)
    assert p.resampler is None and p.sample_rate == FS
    np.testing.assert_array_equal(p.time, test.time)
    np.testing.assert_array_equal(p.stroke, test.stroke)
    np.testing.assert_array_equal(p.force, test.force)
    np.testing.assert_array_equal(p.channels["temperature"], test.channels["temperature"])
    assert p.metadata == {"speed_kmh": 43} and p.role == "identification"
    text = p.describe()
    assert "Savitzky-Golay" in text and "not resampled" in text
    assert "Savitzky-Golay" in prepare(test, 250.0).describe()
    assert "250 Hz" in prepare(test, 250.0).describe()
    with pytest.raises(ValueError, match="fit_rate_hz"):
        prepare(test, 0.0)
    short = RigTest("s", None, "", test.time[:150], test.stroke[:150], test.force[:150],
                    sample_rate=FS)
    with pytest.raises(DataError, match="too short to resample"):
        prepare(short, 200.0)


def test_temperature_column_by_name_and_a_warning_for_an_unused_one(tmp_path):
    """A rig that calls its oil temperature 'Temp (C)': used with temperature_col, in K converted;
    without the option the column is kept as an ordinary channel and a warning names it."""
    from tuner.data.reading import load_test

    t = np.arange(0.0, 2.0, 1e-3)
    frame = pd.DataFrame({"time": t, "stroke": 1e-3 * np.sin(6 * t), "force": 1e3 * np.cos(6 * t),
                          "Temp (C)": 20.0 + t, "Oil K": 293.15 + t})
    path = tmp_path / "rig.csv"
    frame.to_csv(path, index=False)
    plain = load_test(path)
    assert "temperature" not in plain.channels
    assert any("Temp (C)" in w and "--temperature-col" in w for w in plain.metadata["warnings"])
    named = load_test(path, temperature_col="Temp (C)")
    np.testing.assert_allclose(named.channels["temperature"], 20.0 + t)
    kelvin = load_test(path, temperature_col="Oil K", temperature_unit="K")
    np.testing.assert_allclose(kelvin.channels["temperature"], 20.0 + t, atol=1e-9)
    with pytest.raises(DataError, match="missing column 'oil' \\(temperature\\)"):
        load_test(path, temperature_col="oil")


def test_reading_warnings_are_given_once_each_naming_its_file(tmp_path):
    """A file of two tests (a test-id column) whose unused 'Temp (C)' column warns for each test: the job's
    list holds that warning once; a warning that does not name its file gets the file in front."""
    from tuner.data.reading import load_tests, reading_warnings

    t = np.arange(0.0, 2.0, 1e-3)
    frame = pd.DataFrame({"run": np.repeat(["a", "b"], t.size), "time": np.concatenate([t, t]),
                          "stroke": np.tile(1e-3 * np.sin(6 * t), 2), "force": np.tile(1e3 * np.cos(6 * t), 2),
                          "Temp (C)": 20.0})
    path = tmp_path / "two_runs.csv"
    frame.to_csv(path, index=False)
    a, b = load_tests(path, test_col="run", damper_class="any")
    assert a.metadata["warnings"] == b.metadata["warnings"] and len(a.metadata["warnings"]) == 1
    (warning,) = a.metadata["warnings"]
    assert warning.startswith(f"{path}: ") and "Temp (C)" in warning
    b.metadata["warnings"].append("time stamps repaired")
    assert reading_warnings([a, b]) == [warning, f"{path}: time stamps repaired"]
    assert reading_warnings([RigTest("c", None, "", t, t, t)]) == []


def _sine_test(freq_hz, amp_m, rate=2000.0, noise_m=1e-6, seconds=6.0):
    t = np.arange(0.0, seconds, 1.0 / rate)
    x = amp_m * np.sin(2 * np.pi * freq_hz * t) + np.random.default_rng(3).normal(0.0, noise_m, t.size)
    return RigTest("sine", "identification", "sine", t, x, 1e5 * np.gradient(x, t), sample_rate=rate)


def test_differentiator_band_follows_the_stroke_spectrum():
    """A 35 Hz stroke gets a band that covers it and its velocity within the 0.5 % design
    tolerance (analytic reference 2 pi f A); a 2 Hz stroke keeps the 20 Hz design, and white
    stroke noise (5 um on a 2 mm stroke) does not widen it."""
    from tuner.data.preprocess import MIN_DIFF_BAND_HZ, stroke_band_hz

    fast = _sine_test(35.0, 5e-4)
    assert 35.0 <= stroke_band_hz(fast, 200.0) <= 40.0
    p = prepare(fast, 200.0)
    core = slice(len(p.time) // 4, 3 * len(p.time) // 4)
    amp = np.sqrt(2) * np.std(p.stroke_velocity[core])
    assert amp == pytest.approx(2 * np.pi * 35.0 * 5e-4, rel=0.006)
    assert stroke_band_hz(_sine_test(2.0, 2e-3, noise_m=5e-6), 200.0) == MIN_DIFF_BAND_HZ
    # a quasi-static stroke whose velocity PSD is overtaken by the noise's f^2 rise below the top
    slow = _sine_test(0.2, 2e-2, rate=1000.0, noise_m=2e-5, seconds=20.0)
    assert stroke_band_hz(slow, 250.0) == MIN_DIFF_BAND_HZ
    fixed = prepare(fast, 200.0, diff_band_hz=20.0)        # the old fixed band: 35 Hz read too low
    assert np.sqrt(2) * np.std(fixed.stroke_velocity[core]) < 0.97 * 2 * np.pi * 35.0 * 5e-4


def test_inspect_summary_states_the_differentiator_band_and_its_velocity():
    """What `inspect` prints is the velocity the fit will see: a 35 Hz stroke's band and peak velocity
    (analytic 2 pi f A = 110 mm/s; the old fixed 20 Hz band read it more than 3 % low)."""
    from tuner.data.summary import format_summary, summarize

    fast = _sine_test(35.0, 5e-4, noise_m=0.0)     # a peak (max) would pick up differentiated noise
    s = summarize(fast, 200.0)
    assert "up to 35" in s["velocity_source"]
    assert max(-s["velocity_m_s"][0], s["velocity_m_s"][1]) == pytest.approx(2 * np.pi * 35.0 * 5e-4, rel=0.01)
    assert "up to 20 Hz" in format_summary(fast, 200.0, diff_band_hz=20.0)


@pytest.mark.parametrize("rate", [3004.8, 1111.11])
def test_a_logger_clock_with_no_small_integer_ratio_is_resampled_to_the_fit_rate(rate):
    """A 3004.8 Hz logger clock (200/3004.8 = 125/1878) and an arbitrary one: the prepared stroke,
    velocity and force at 200 Hz equal the analytic signals at the output times (a 1.5 Hz stroke,
    a force with a 7 Hz component) within the resampler's documented pass-band flatness (0.1 %), as
    the integer-ratio path does for 3000 Hz (a clock taken as 3000 Hz instead of 3004.8 Hz would
    be 0.16 % slow: the stroke off by 12 % of its amplitude after 8 s, 100x these bounds; the
    prepared signals are within 6e-5 of the truth on both paths)."""
    def make(fs):
        t = np.arange(int(8.0 * fs)) / fs
        x = 0.004 * np.sin(2 * np.pi * 1.5 * t)
        f = 2e6 * x + 300.0 * np.sin(2 * np.pi * 7.0 * t + 0.3)
        return RigTest("t", "identification", "sine", t, x, f, {"temperature": 20.0 + 0 * t}, fs)

    assert Resampler.ratio(rate, 200.0) is None
    for fs in (rate, 3000.0):
        p = prepare(make(fs), 200.0)
        assert p.sample_rate == pytest.approx(200.0, rel=1e-9)
        t = p.time
        x_true = 0.004 * np.sin(2 * np.pi * 1.5 * t)
        v_true = 0.004 * 2 * np.pi * 1.5 * np.cos(2 * np.pi * 1.5 * t)
        f_true = 2e6 * x_true + 300.0 * np.sin(2 * np.pi * 7.0 * t + 0.3)
        inner = slice(10, -10)  # the differentiator is one-sided near the ends
        assert np.max(np.abs(p.stroke - x_true)) < 1e-3 * 0.004
        assert np.max(np.abs(p.force - f_true)) < 1e-3 * 8300.0
        assert np.max(np.abs(p.stroke_velocity - v_true)[inner]) < 5e-3 * 0.004 * 2 * np.pi * 1.5
        assert ("interpolated (cubic spline)" in p.describe()) == (fs != 3000.0)
