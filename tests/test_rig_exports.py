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


def write_mts(path, time, stroke, force, stroke_unit="in", force_unit="lbf", block=1024, skip=(), repeat=()):
    """An MTS 793 data-acquisition export as the controller writes it (tab-separated, CRLF, a blank line
    between blocks, each block opened by its own line, channel names and units row), from SI signals;
    block numbers (0-based) in ``skip`` are left out, those in ``repeat`` written twice."""
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
