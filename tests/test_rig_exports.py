"""Rig files as the industry's controllers and labs write them (issue 75): MTS 793 data-acquisition exports,
US customary units, MATLAB files (v5 and v7.3) and a whole test programme in one file.

The tests write their own fixtures from the bundled dataset's tests (an MTS export of a bundled test, a
.mat of it in both versions) and from the virtual campaign (a stepped sine on the virtual rig), and check
the round trip against the CSV as the reader reads it, and the programme's steps against the frequencies
and amplitudes the campaign drove."""
from __future__ import annotations

import numpy as np
import pytest

from damper_fmu.fmu import native_reason
from tuner.__main__ import main
from tuner.cli.folders import DEFAULT_DATASET
from tuner.data.reading import DataError, load_test, load_tests
from tuner.data.units import M_PER_IN, N_PER_LBF

#: the exact US customary factors, written out independently of the reader: 1 in = 2.54 cm, 1 lbf =
#: 0.45359237 kg x 9.80665 m/s^2 (standard gravity)
INCH_M, LBF_N = 2.54e-2, 0.45359237 * 9.80665
STROKE_FACTORS = {"mm": 1e-3, "in": INCH_M}
FORCE_FACTORS = {"kN": 1e3, "lbf": LBF_N, "kip": 1e3 * LBF_N}


def write_mts(path, time, stroke, force, stroke_unit="in", force_unit="lbf", block=1024, skip=(), repeat=(),
              time_column=True):
    """An MTS 793 data-acquisition export as the controller writes it (tab-separated, CRLF, a blank line
    between blocks, each block opened by its own line, channel names and units row), from SI signals;
    block numbers (0-based) in ``skip`` are left out, those in ``repeat`` written twice; ``time_column``
    False: without the Time channel (the blocks' stamps alone tell the time)."""
    lines = ["MTS793|MPT|ENU|1|2|.|/|:|1|0|0|A", ""]
    ks, kf = STROKE_FACTORS[stroke_unit], FORCE_FACTORS[force_unit]
    for b, start in enumerate(range(0, len(time), block)):
        if b in skip:
            continue
        rows = slice(start, min(start + block, len(time)))
        sec = 4 + b
        stamp = f"10/4/2021 7:{48 + sec // 60}:{sec % 60:02d} AM"
        text = [f"Data Acquisition\t1: Data Acquisition\tTime:\t{time[rows][-1] + 0.0196941:.7f}\tSec\t{stamp}",
                "Stroke\tLoad\tTime", f"{stroke_unit}\t{force_unit}\tSec"]
        text += [f"{x / ks:.10g}\t{f / kf:.10g}\t{t:.10g}" for x, f, t in zip(stroke[rows], force[rows], time[rows])]
        if not time_column:
            text = text[:1] + [row.rsplit("\t", 1)[0] for row in text[1:]]
        lines += (text + [""]) * (2 if b in repeat else 1)
    path.write_bytes(("\r\n".join(lines) + "\r\n").encode("utf-8"))
    return path


@pytest.fixture(scope="module")
def bundled():
    """The bundled dataset's first identification and validation tests, read from their CSV files."""
    csv = {p.stem: p for p in DEFAULT_DATASET.glob("*.csv")}
    return {name: load_test(csv[name], time_col="time") for name in ("id1_straight_250", "val1_straight_250")}


def _same_samples(read, ref):
    """Count equal, stroke and force peaks within 0.01 %, every sample alike (10 significant digits written)."""
    assert len(read.time) == len(ref.time)
    for what in ("stroke", "force"):
        a, b = getattr(read, what), getattr(ref, what)
        assert np.max(np.abs(a)) == pytest.approx(np.max(np.abs(b)), rel=1e-4), what
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-8 * np.max(np.abs(b)))
    np.testing.assert_allclose(read.time, ref.time, atol=1e-9)


@pytest.mark.parametrize("stroke_unit, force_unit", [("in", "lbf"), ("in", "kip"), ("mm", "kN")])
def test_mts_export_reads_with_no_options_to_the_csv_samples(tmp_path, bundled, stroke_unit, force_unit):
    ref = bundled["id1_straight_250"]
    path = write_mts(tmp_path / "rig.txt", ref.time, ref.stroke, ref.force, stroke_unit, force_unit)
    got = load_test(path)
    _same_samples(got, ref)
    read = got.metadata["read"]
    assert read["format"] == "MTS 793 export"
    assert read["columns"] == {"time": "Time", "stroke": "Stroke", "force": "Load"}
    assert read["units"]["stroke"] == stroke_unit and read["units"]["force"] == force_unit
    blocks = read["format_info"]["blocks"]
    assert len(blocks) == -(-len(ref.time) // 1024) and blocks[0]["stamp"] == "10/4/2021 7:48:04 AM"
    assert blocks[0]["line"] == 3 and read["format_info"]["rows_per_block"] == 1024
    assert "warnings" not in got.metadata
    conv = read["converted"] or {}
    assert {r: c["factor"] for r, c in conv.items()} == {r: f for r, f in (("stroke", INCH_M if stroke_unit == "in"
                                                                            else None),
                                                                           ("force", FORCE_FACTORS[force_unit]
                                                                            if force_unit != "kN" else None)) if f}


def test_us_factors_are_the_exact_definitions():
    assert M_PER_IN == INCH_M and N_PER_LBF == pytest.approx(LBF_N, rel=1e-15)


def test_mts_missing_and_repeated_blocks_are_warnings_naming_them(tmp_path, bundled):
    ref = bundled["id1_straight_250"]
    path = write_mts(tmp_path / "gaps.txt", ref.time, ref.stroke, ref.force, skip=(4,), repeat=(1,))
    tests = load_tests(path)
    assert [t.name for t in tests] == ["gaps-part1", "gaps-part2"]
    assert [len(t.time) for t in tests] == [4 * 1024, len(ref.time) - 5 * 1024]
    np.testing.assert_allclose(tests[1].force, ref.force[5 * 1024:], atol=1e-6)
    warns = tests[0].metadata["warnings"]
    assert any("block 3 (line" in w and "repeats block 2 (line" in w and "left out" in w for w in warns), warns
    # blocks are numbered as they stand in the file (the repeated one counts): the 6th follows a gap of one
    assert any("1 block(s) missing between block 5 (line" in w and "and block 6 (line" in w for w in warns), warns


def test_mts_without_a_time_channel_checks_the_blocks_by_their_stamps(tmp_path, bundled):
    ref = bundled["id1_straight_250"]
    path = write_mts(tmp_path / "stamps.txt", ref.time, ref.stroke, ref.force, skip=(6,), repeat=(2,),
                     time_column=False)
    tests = load_tests(path, rate_hz=1000.0)
    assert [len(t.time) for t in tests] == [6 * 1024, len(ref.time) - 7 * 1024]
    np.testing.assert_allclose(tests[1].stroke, ref.stroke[7 * 1024:], atol=1e-12)
    warns = tests[0].metadata["warnings"]
    assert any("block 4 (line" in w and "repeats block 3 (line" in w for w in warns), warns
    assert any("1 block(s) missing between block 7 (line" in w and "Time: stamps: due at" in w for w in warns), warns
    assert len(warns) == 2  # the short last block is no warning


def test_mts_export_with_a_decimal_comma(tmp_path, bundled):
    """An export whose first line declares ',' as the decimal mark (its sixth field): every number, the
    blocks' Time: stamps too, written with a comma."""
    ref = bundled["id1_straight_250"]
    path = write_mts(tmp_path / "deu.txt", ref.time[:3000], ref.stroke[:3000], ref.force[:3000], "mm", "kN")
    path.write_bytes(path.read_bytes().replace(b".", b","))
    got = load_test(path)
    np.testing.assert_allclose(got.stroke, ref.stroke[:3000], atol=1e-12)
    np.testing.assert_allclose(got.force, ref.force[:3000], atol=1e-6)
    assert got.metadata["read"]["decimal"] == ","
    # the second block's stamp, as written: its last sample's time + 0.0196941 s
    assert got.metadata["read"]["format_info"]["blocks"][1]["time"] == pytest.approx(ref.time[2047] + 0.0196941, abs=1e-7)


def test_mts_block_with_other_channels_is_refused_naming_its_line(tmp_path, bundled):
    ref = bundled["id1_straight_250"]
    path = write_mts(tmp_path / "mixed.txt", ref.time[:3000], ref.stroke[:3000], ref.force[:3000])
    text = path.read_bytes().decode().split("\r\n")
    k = [i for i, s in enumerate(text) if s == "Stroke\tLoad\tTime"][1]
    text[k] = "Stroke\tLoad\tTime\tTemp"
    path.write_bytes("\r\n".join(text).encode())
    with pytest.raises(DataError, match=rf"line {k + 1}: the block's channel names .* differ from the first"):
        load_test(path)


def test_us_units_in_a_header_and_by_option(tmp_path, bundled):
    ref = bundled["id1_straight_250"]
    rows = "\n".join(f"{t:.6f},{x / INCH_M:.10g},{f / LBF_N:.10g}" for t, x, f in zip(ref.time, ref.stroke, ref.force))
    header = tmp_path / "header.csv"
    header.write_text("time [s],stroke (in),force [lbf]\n" + rows + "\n")
    _same_samples(load_test(header), ref)
    plain = tmp_path / "plain.csv"
    plain.write_text("time,stroke,force\n" + rows + "\n")
    _same_samples(load_test(plain, stroke_unit="in", force_unit="lbf"), ref)
    # a file in lbf read as kip is 1000 x too strong: the suggestion stays among the US units
    with pytest.raises(DataError, match="Is it in 'lbf'"):
        load_test(plain, stroke_unit="in", force_unit="kip")


def test_inspect_says_what_it_read_and_converted(tmp_path, bundled, capsys):
    ref = bundled["id1_straight_250"]
    path = write_mts(tmp_path / "rig.txt", ref.time, ref.stroke, ref.force)
    assert main(["inspect", str(path)]) == 0
    err = capsys.readouterr().out
    assert "columns: time <- 'Time', stroke <- 'Stroke', force <- 'Load'" in err
    assert "format: MTS 793 export (MTS793|MPT|ENU|1|2|.|/|:|1|0|0|A): 10 blocks of 1024 rows" in err
    assert "first block 1, line 3" in err and "10/4/2021 7:48:04 AM" in err and "last block 10" in err
    assert "stroke in -> m x 0.0254; force lbf -> N x 4.4482216152605" in err
    assert "lbf*s/in" in err


def test_fit_and_diagnose_take_mts_exports(tmp_path, bundled, capsys):
    """`fit` runs on two MTS exports with no reading options (a tiny budget); `diagnose` reads them and
    starts (it stops at a missing --from folder, after the data are read)."""
    files = [write_mts(tmp_path / f"{name}.txt", t.time, t.stroke, t.force, "in", "kip")
             for name, t in bundled.items()]
    out = tmp_path / "fit"
    code = main(["fit", "--identification", str(files[0]), "--validation", str(files[1]), "--out", str(out),
                 "--models", "lumped", "--population", "4", "--iterations", "1", "--polish", "1", "--no-diagnose",
                 "--no-figures", "--workers", "0", "--quiet", "--engine", "inprocess" if native_reason() else "native"])
    assert code == 0, capsys.readouterr().err[-2000:]
    assert (out / "parameters.json").is_file() and (out / "metrics.json").is_file()
    capsys.readouterr()
    code = main(["diagnose", "--identification", str(files[0]), "--validation", str(files[1]),
                 "--from", str(tmp_path / "nowhere"), "--out", str(tmp_path / "diag")])
    captured = capsys.readouterr()
    err = captured.out + captured.err
    assert code == 2 and "format: MTS 793 export" in err and "no parameters.json" in err, err[-2000:]


# --------------------------------------------------------------------------- MATLAB files

def write_mat73(path, variables: dict):
    """A MATLAB v7.3 file as MATLAB writes one: HDF5 behind a 512-byte text header, each array stored
    transposed (MATLAB is column-major) with its ``MATLAB_class``, a struct as a group of class 'struct'."""
    import h5py

    def put(group, name, value):
        if isinstance(value, dict):
            sub = group.create_group(name)
            sub.attrs["MATLAB_class"] = np.bytes_("struct")
            for k, v in value.items():
                put(sub, k, v)
            return
        ds = group.create_dataset(name, data=np.atleast_2d(np.asarray(value, dtype=float)).T
                                  if np.ndim(value) < 2 else np.asarray(value, dtype=float).T)
        ds.attrs["MATLAB_class"] = np.bytes_("double")

    with h5py.File(path, "w", userblock_size=512) as f:
        for name, value in variables.items():
            put(f, name, value)
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Oct  4 07:48:04 2021 HDF5 schema 1.00 ."
    with open(path, "r+b") as fh:
        fh.write(header.ljust(116) + b"\x00" * 8 + b"\x00\x02IM")
    return path


@pytest.fixture(scope="module")
def signals(bundled):
    """The first bundled test's time [s], stroke [mm] and force [kN], and the test as read from its CSV."""
    ref = bundled["id1_straight_250"]
    return ref.time, 1e3 * ref.stroke, 1e-3 * ref.force, ref


def _matrix(signals):
    t, x, f, _ = signals
    return np.column_stack([t, x, f])


MM_KN = {"stroke_unit": "mm", "force_unit": "kN"}


def test_mat_v5_column_vectors_by_name(tmp_path, signals):
    import scipy.io

    t, x, f, ref = signals
    path = tmp_path / "vectors.mat"
    scipy.io.savemat(path, {"t": t[:, None], "x": x[:, None], "F": f[:, None], "fs": 1000.0})
    got = load_test(path, time_col="t", stroke_col="x", force_col="F", **MM_KN)
    _same_samples(got, ref)
    read = got.metadata["read"]
    assert read["format"] == "MATLAB v5" and read["columns"] == {"time": "t", "stroke": "x", "force": "F"}
    assert read["format_info"]["scalars"] == {"fs": 1000.0}


def test_mat_v5_matrix_columns_and_struct_fields(tmp_path, signals):
    import scipy.io

    t, x, f, ref = signals
    path = tmp_path / "matrix.mat"
    scipy.io.savemat(path, {"data": _matrix(signals), "rig": {"time": t[None, :], "stroke": x[None, :],
                                                               "load": {"cell": f[None, :]}}})
    _same_samples(load_test(path, time_col="data:1", stroke_col="data:2", force_col="data(:,3)", **MM_KN), ref)
    _same_samples(load_test(path, time_col="rig.time", stroke_col="rig.stroke", force_col="rig.load.cell", **MM_KN),
                  ref)
    # channels in rows (3 x N) are read by their rows under the same names
    scipy.io.savemat(path, {"data": _matrix(signals).T})
    _same_samples(load_test(path, time_col="data:1", stroke_col="data:2", force_col="data:3", **MM_KN), ref)


@pytest.mark.parametrize("layout", ["matrix", "struct"])
def test_mat_v73_reads_the_same(tmp_path, signals, layout):
    t, x, f, ref = signals
    if layout == "matrix":
        path = write_mat73(tmp_path / "v73.mat", {"data": _matrix(signals)})
        cols = {"time_col": "data:1", "stroke_col": "data:2", "force_col": "data:3"}
    else:
        path = write_mat73(tmp_path / "v73.mat", {"rig": {"t": t[None, :], "x": x[:, None], "F": f[None, :]}})
        cols = {"time_col": "rig.t", "stroke_col": "rig.x", "force_col": "rig.F"}
    got = load_test(path, **cols, **MM_KN)
    _same_samples(got, ref)
    assert got.metadata["read"]["format"] == "MATLAB v7.3"


def test_mat_missing_name_lists_the_variables_found(tmp_path, signals):
    import scipy.io

    path = tmp_path / "vectors.mat"
    t, x, f, _ = signals
    scipy.io.savemat(path, {"t": t[:, None], "x": x[:, None], "F": f[:, None], "data": _matrix(signals)})
    n = len(t)
    with pytest.raises(DataError, match=rf"missing column 'force' \(force\); variables found: t \({n}x1\), "
                                        rf"x \({n}x1\), F \({n}x1\), data \({n}x3: columns data:1 \.\. data:3\)"):
        load_test(path, time_col="t", stroke_col="x", **MM_KN)


def test_mat_through_the_command_line_and_a_columns_file(tmp_path, signals, capsys):
    path = write_mat73(tmp_path / "lab.mat", {"data": _matrix(signals)})
    mapping = tmp_path / "columns.toml"
    mapping.write_text('[columns]\ntime_col = "data:1"\nstroke_col = "data(:,2)"\nforce_col = "data:3"\n'
                       'stroke_unit = "mm"\nforce_unit = "kN"\n')
    assert main(["inspect", str(path), "--columns", str(mapping)]) == 0
    out = capsys.readouterr().out
    assert "columns: time <- 'data:1', stroke <- 'data:2', force <- 'data:3'" in out
    assert "format: MATLAB v7.3; variables: data (10001x3: columns data:1 .. data:3)" in out


# --------------------------------------------------------------------------- a test programme in one file

#: the programme the virtual rig runs: four frequencies, then an amplitude step at 2 Hz
PROGRAMME = [(0.5, 0.020, 6), (1.0, 0.015, 8), (2.0, 0.008, 10), (4.0, 0.004, 12), (2.0, 0.004, 10)]


@pytest.fixture(scope="module")
def stepped(tmp_path_factory):
    """A stepped sine run on the virtual rig (``campaign.programme``), written as one CSV; its truth spans."""
    from campaign.programme import programme_test

    df, spans = programme_test(PROGRAMME, seed=5)
    path = tmp_path_factory.mktemp("programme") / "stepped.csv"
    df.to_csv(path, index=False, float_format="%.9g")
    return path, spans


def test_a_stepped_sine_is_cut_into_its_steps(stepped):
    from tuner.data.programme import SETTLING_CYCLES

    path, spans = stepped
    tests = load_tests(path, programme=True)
    assert len(tests) == len(spans)
    for test, truth in zip(tests, spans):
        step = test.metadata["read"]["step"]
        assert step["frequency_hz"] == pytest.approx(truth["frequency_hz"], rel=0.01), test.name
        assert step["amplitude_m"] == pytest.approx(truth["amplitude_m"], rel=0.02), test.name
        assert test.name == f"stepped-{truth['frequency_hz']:.3g}Hz-{truth['amplitude_m'] * 1e3:.3g}mm"
        # the fade-in and the settling cycles are left out, the fade-out too: the test lies within the held
        # cycles, after the settling ones, and spans whole cycles
        period = 1.0 / truth["frequency_hz"]
        assert step["t_start_s"] >= truth["t_start_s"] + SETTLING_CYCLES * period - 0.01 * period
        assert step["t_end_s"] <= truth["t_end_s"] + 0.01 * period
        assert step["cycles"] >= truth["cycles"] - SETTLING_CYCLES - 1
        assert test.duration == pytest.approx(step["cycles"] * period, abs=2e-3)
        assert np.ptp(test.stroke) / 2 == pytest.approx(truth["amplitude_m"], rel=0.02)


def test_steps_are_picked_by_number_frequency_and_amplitude(stepped):
    from tuner.data.programme import cut_programme, select_steps

    path, _ = stepped
    assert [t.name for t in load_tests(path, steps="2Hz:4mm")] == ["stepped-2Hz-4mm"]
    whole = load_test(path)
    steps = cut_programme(whole.time, whole.stroke, str(path))
    names = lambda sel: [s.label for s in select_steps(steps, sel, str(path))]  # noqa: E731
    assert names("2") == ["1Hz-15mm"]
    assert names("1,4") == ["0.5Hz-20mm", "4Hz-4mm"]
    assert names("2Hz") == ["2Hz-8mm", "2Hz-4mm"]
    assert names("2Hz:4mm") == ["2Hz-4mm"]
    assert names("4mm") == ["4Hz-4mm", "2Hz-4mm"]
    assert names("0.5906in") == ["1Hz-15mm"]
    with pytest.raises(DataError, match=r"no step at '3Hz' .*steps: 1: 0.5 Hz 20 mm, 2: 1 Hz 15 mm"):
        load_tests(path, steps="3Hz")
    with pytest.raises(DataError, match=r"step 9 asked for, but the programme has 5 steps"):
        load_tests(path, steps="9")
    with pytest.raises(DataError, match=r"cannot read the step selection 'fast'"):
        load_tests(path, steps="fast")


def test_a_file_without_a_programme_is_refused_with_the_fix(tmp_path, bundled):
    ref = bundled["id1_straight_250"]
    path = tmp_path / "track.csv"
    path.write_text("time,stroke,force\n" + "\n".join(f"{t:.3f},{x:.9g},{f:.6g}" for t, x, f in
                                                      zip(ref.time, ref.stroke, ref.force)))
    with pytest.raises(DataError, match="no test programme found.*read it without --programme|no run of 3 or more"):
        load_tests(path, programme=True)


def test_fit_takes_steps_as_identification_and_validation(stepped, tmp_path, capsys):
    path, _ = stepped
    out = tmp_path / "fit"
    code = main(["fit", "--identification", f"{path}@1", f"{path}@3", "--validation", f"{path}@2,4Hz,5",
                 "--out", str(out), "--models", "lumped", "--population", "4", "--iterations", "1", "--polish", "1",
                 "--no-diagnose", "--no-figures", "--workers", "0", "--engine",
                 "inprocess" if native_reason() else "native"])
    log = capsys.readouterr().out
    assert code == 0, log[-2000:]
    for name, role in (("stepped-0.5Hz-20mm", "identification"), ("stepped-2Hz-8mm", "identification"),
                       ("stepped-1Hz-15mm", "validation"), ("stepped-4Hz-4mm", "validation"),
                       ("stepped-2Hz-4mm", "validation")):
        assert f"{name} ({role}): {path}" in log, name
    metrics = (out / "metrics.json").read_text()
    assert all(n in metrics for n in ("stepped-1Hz-15mm", "stepped-4Hz-4mm", "stepped-2Hz-4mm"))


def test_short_low_frequency_steps_keep_two_cycles(tmp_path):
    """A supplier's programme holds few cycles at its low frequencies: a step of 3 cycles leaves out one
    settling cycle and keeps two; the fade-in and fade-out never count."""
    from campaign.programme import programme_test

    df, spans = programme_test([(0.2, 0.0127, 3), (0.5, 0.0127, 4), (2.0, 0.0127, 10)], seed=2, pause_s=0.0)
    path = tmp_path / "short.csv"
    df.to_csv(path, index=False, float_format="%.9g")
    steps = [t.metadata["read"]["step"] for t in load_tests(path, programme=True)]
    assert [(s["cycles"], s["settling_cycles"]) for s in steps] == [(2, 1), (2, 2), (8, 2)]
    for s, truth in zip(steps, spans):
        assert s["frequency_hz"] == pytest.approx(truth["frequency_hz"], rel=0.01)
        assert s["amplitude_m"] == pytest.approx(truth["amplitude_m"], rel=0.02)


def test_an_mts_export_of_a_stepped_sine_in_inches_is_cut_into_its_steps(tmp_path):
    """The rig of the issue: an MTS 793 controller's stepped sine, 0.2 to 2 Hz at 0.5 in, 1024 Hz, in in and
    lbf, read with --programme alone and picked by frequency and amplitude in inches."""
    from campaign.programme import programme_test

    plan = [(0.2, 0.5 * INCH_M, 3), (0.5, 0.5 * INCH_M, 4), (1.0, 0.5 * INCH_M, 5), (2.0, 0.5 * INCH_M, 8)]
    df, spans = programme_test(plan, seed=4, sample_rate=1024.0, pause_s=1.0)
    path = write_mts(tmp_path / "race_damper.dat", df["time"].to_numpy(), df["stroke"].to_numpy(),
                     df["force"].to_numpy())
    tests = load_tests(path, programme=True)
    assert [t.name for t in tests] == ["race_damper-0.2Hz-12.7mm", "race_damper-0.5Hz-12.7mm",
                                       "race_damper-1Hz-12.7mm", "race_damper-2Hz-12.7mm"]
    for test, truth in zip(tests, spans):
        step = test.metadata["read"]["step"]
        assert step["frequency_hz"] == pytest.approx(truth["frequency_hz"], rel=0.01)
        assert step["amplitude_m"] == pytest.approx(truth["amplitude_m"], rel=0.02)
        assert test.sample_rate == pytest.approx(1024.0, rel=1e-6)
    assert [t.name for t in load_tests(path, steps="1Hz:0.5in")] == ["race_damper-1Hz-12.7mm"]
