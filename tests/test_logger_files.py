"""Data-logger files as written (issue 38 item 1): a preamble of metadata lines before the header,
date-time stamps with a 12-hour clock, a text-only 'Events' column written on a few rows only, and the
channels in volts that the user's calibrations turn into engineering units.

The files are written here the way the logger of ``tests/data/mr-damper-0.5A`` writes them, from
signals of known truth: a damper at rest for a lead-in, then a stroke of known shape and the force of a
linear damper, written as volts through a known scale and offset, with a load-cell zero offset. Each
is read back and compared with the truth (to the file's 4 decimals). The real file's first 6000 rows
(``tests/data/mr-damper-0.5A``, MIT, its LICENSE beside it) are read with the user's calibrations and
checked against the same rows parsed independently here; so are 400 rows of it ending with two events
written with the column delimiter (issue 63 item 2: the trailing text column takes the rest of the row).
"""
from __future__ import annotations

import gzip
import json
from datetime import datetime
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tuner.__main__ import main
from tuner.data.reading import DataError, load_test

FS = 1000.0
N = 4000                      # 4 s at 1 kHz
REST_S = 1.0                  # the damper at rest before the stroke starts
AMPLITUDE_MM, FREQ_HZ = 4.0, 2.0
DAMPING_N_S_PER_M = 2.0e4     # a linear damper: force = c x velocity
STROKE_MM_PER_V, STROKE_OFFSET_MM = 10.0, -25.0   # the transducer reads 0 V at -25 mm
FORCE_N_PER_V, LOAD_CELL_ZERO_N = 980.665, 25.0   # the load cell reads 25 N with no load
HEADER = "Sample Number, Date/Time, CHANNEL0, CHANNEL1, CHANNEL2, Events"
COLUMNS = dict(time_col="Date/Time", stroke_col="CHANNEL0", force_col="CHANNEL1", damper_class="any")
CALIBRATED = dict(COLUMNS, stroke_scale=STROKE_MM_PER_V, stroke_offset=STROKE_OFFSET_MM, stroke_unit="mm",
                  force_scale=FORCE_N_PER_V, force_unit="N")
VOLT_STEP = 1e-4              # the logger writes 4 decimals
REAL = Path(__file__).resolve().parent / "data" / "mr-damper-0.5A" / "15Hz0x5A_first6000.txt.gz"
#: 400 rows from the middle of the same file, the last one's Events cell holding two events ('DAQ Pause, DAQ Stop')
TWO_EVENTS = REAL.parent / "15Hz0x5A_rows20001-20400_two_events.txt.gz"
REAL_CALIBRATED = dict(time_col="Date/Time", stroke_col="CHANNEL0", stroke_scale=10, stroke_unit="mm",
                       force_col="CHANNEL1", force_scale=980.665, force_unit="N", damper_class="any")


def truth(n: int = N):
    """time [s], stroke [m] (0 during the lead-in, then 0 .. 4 mm), force [N, + tension] of a linear
    damper (0 at rest)."""
    t = np.arange(n) / FS
    phase = 2 * np.pi * FREQ_HZ * np.clip(t - REST_S, 0.0, None)
    x = 1e-3 * AMPLITUDE_MM * (1 - np.cos(phase)) / 2
    v = 1e-3 * AMPLITUDE_MM * np.pi * FREQ_HZ * np.sin(phase)
    return t, x, DAMPING_N_S_PER_M * v


def stamps(start: str, n: int, order: str = "mdy", twelve: bool = True) -> list[str]:
    """Date-time stamps every millisecond from ``start``, as the logger writes them."""
    times = pd.Timestamp(start) + pd.to_timedelta(np.arange(n), unit="ms")
    date = "%m/%d/%Y" if order == "mdy" else "%d/%m/%Y"
    clock = "%I:%M:%S" if twelve else "%H:%M:%S"
    text = times.strftime(f"{date} {clock}")
    ms = [f".{t.microsecond // 1000:03d}" for t in times]
    ampm = times.strftime(" %p") if twelve else [""] * n
    return [a + b + c for a, b, c in zip(text, ms, ampm)]


def write_logger(path, start="2022-05-25 11:59:58", order="mdy", twelve=True, n=N, preamble=None,
                 before_header=(), extra_row=None, events=None):
    """The logger's file: a 7-line preamble, the header, then per row the sample number, the stamp,
    CHANNEL0 (stroke, V), CHANNEL1 (force, V, with the load cell's zero offset), CHANNEL2 (the command,
    V) and an event on the first, a middle and the last row only (the other rows have 5 fields).
    ``before_header``: extra preamble lines; ``extra_row``: (row index, text) of a damaged row;
    ``events``: {row index: text} of more events."""
    t, x, f = truth(n)
    x_mm = 1e3 * x
    v0 = (x_mm - STROKE_OFFSET_MM) / STROKE_MM_PER_V
    v1 = (f + LOAD_CELL_ZERO_N) / FORCE_N_PER_V
    events = {0: "DAQ Start", n // 2: "Marker", n - 1: "DAQ Pause", **(events or {})}
    lines = preamble or ["Header Size:  7", "Version:  2", "Sampling Interval:  0.001", "Sampling Rate:  1000",
                         f"Sample Count:  {n}", "Device Serial Number:  0"]
    lines = list(lines) + list(before_header) + [HEADER]
    for k, stamp in enumerate(stamps(start, n, order, twelve)):
        row = f"{k + 1:10d},   {stamp}, {v0[k]:.4f}, {v1[k]:.4f}, {x_mm[k] / 10:.4f}"
        lines.append(row + (f", {events[k]}" if k in events else ""))
        if extra_row is not None and k == extra_row[0]:
            lines.append(extra_row[1])
    with open(path, "w", encoding="utf-8", newline="\r\n") as fh:
        fh.write("\n".join(lines) + "\n")
    return path


def _same_as_truth(g, n=N, tared=True):
    t, x, f = truth(n)
    np.testing.assert_allclose(g.time, t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(g.stroke, x, rtol=0, atol=1e-3 * STROKE_MM_PER_V * VOLT_STEP / 2 * 1.001)
    # the tare subtracts a mean of rounded values: at most one more half step
    atol = FORCE_N_PER_V * VOLT_STEP / 2 * (2 if tared else 1) * 1.001
    np.testing.assert_allclose(g.force, f if tared else f + LOAD_CELL_ZERO_N, rtol=0, atol=atol)


# --------------------------------------------------------------------------- read as written

def test_logger_file_reads_to_the_truth_with_its_calibration_and_tare(tmp_path):
    """Preamble, 12-hour stamps across noon, Events on 3 rows, volts with scale and offset, the load
    cell's zero removed over the lead-in."""
    path = write_logger(tmp_path / "run_01.txt")
    g = load_test(path, **CALIBRATED, force_zero=0.8)
    _same_as_truth(g)
    read = g.metadata["read"]
    assert read["header_line"] == 7
    assert read["preamble"] == {"Header Size": "7", "Version": "2", "Sampling Interval": "0.001",
                                "Sampling Rate": "1000", "Sample Count": "4000", "Device Serial Number": "0"}
    assert read["declared_rate"]["agrees"] and read["declared_rate"]["declared_hz"]["Sampling Rate"] == 1000.0
    assert read["date_order"] == "mdy" and "12-hour clock" in read["stamps"]
    assert "25 at data row 1 (line 8)" in read["stamps"]
    assert read["text_columns"] == {"Events": "'DAQ Start', 'Marker', 'DAQ Pause' on 3 of 4000 rows"}
    assert "Events" in read["ignored"] and "Events" not in g.channels
    assert read["force_zero"]["removed_n"] == pytest.approx(LOAD_CELL_ZERO_N, abs=FORCE_N_PER_V * VOLT_STEP / 2)
    assert read["force_zero"]["samples"] == 801 and read["force_zero"]["stroke_motion_m"] == 0.0
    cal = read["calibration"]
    assert cal["stroke"]["scale"] == STROKE_MM_PER_V and cal["stroke"]["offset"] == STROKE_OFFSET_MM
    assert cal["stroke"]["raw_range"] == pytest.approx([2.5, 2.9])
    assert cal["stroke"]["scaled_range"] == pytest.approx([0.0, 4.0])
    assert cal["force"]["unit"] == "N" and cal["force"]["raw_range"][0] < 0 < cal["force"]["raw_range"][1]
    assert read["units"] == {"stroke": "mm", "force": "N", "time": "timestamp"}
    assert set(g.channels) == {"Sample Number", "CHANNEL2"}
    np.testing.assert_allclose(g.channels["CHANNEL2"], 1e3 * truth()[1] / 10, atol=VOLT_STEP / 2 * 1.001)
    assert not g.metadata.get("warnings")


def test_the_offset_may_be_given_instead_of_the_tare(tmp_path):
    """--force-offset -25 (N) does what the tare measures; with neither, the zero stays in the force."""
    path = write_logger(tmp_path / "run_02.txt")
    g = load_test(path, **CALIBRATED, force_offset=-LOAD_CELL_ZERO_N)
    np.testing.assert_allclose(g.force, truth()[2], rtol=0, atol=FORCE_N_PER_V * VOLT_STEP / 2 * 1.001)
    _same_as_truth(load_test(path, **CALIBRATED), tared=False)


@pytest.mark.parametrize("start, order, twelve, expected", [
    ("2022-05-31 23:59:58", "mdy", True, "mdy"),     # 11:59:58 PM on 05/31 to 12:00:01 AM on 06/01
    ("2022-05-31 23:59:58", "dmy", False, "dmy"),    # 31/05/2022 23:59:58 to 01/06/2022 00:00:01
])
def test_stamps_across_midnight_in_either_day_month_order(tmp_path, start, order, twelve, expected):
    g = load_test(write_logger(tmp_path / f"midnight_{order}.txt", start=start, order=order, twelve=twelve),
                  **CALIBRATED, force_zero=0.5)
    _same_as_truth(g)
    read = g.metadata["read"]
    assert read["date_order"] == expected
    assert ("12-hour" if twelve else "24-hour") in read["stamps"]


def test_ambiguous_dates_that_change_are_refused_naming_the_option(tmp_path):
    """05/06/2022 11:59:58 PM to 05/07/2022 12:00:01 AM: every day and month field <= 12, and the two
    orders differ by a month: refused with --date-order; given, the order reads the truth."""
    path = write_logger(tmp_path / "may_june.txt", start="2022-05-06 23:59:58")
    with pytest.raises(DataError) as err:
        load_test(path, **CALIBRATED)
    msg = str(err.value)
    for s in ("may_june.txt", "'Date/Time'", "--date-order mdy", "--date-order dmy", "line 8", "date_order"):
        assert s in msg, (s, msg)
    g = load_test(path, **CALIBRATED, date_order="mdy", force_zero=0.5)
    _same_as_truth(g)
    assert g.metadata["read"]["date_order"] == "mdy" and "--date-order mdy" in g.metadata["read"]["stamps"]
    with pytest.raises(DataError, match="gap of"):  # 6 May to 5 June: a month's gap, refused
        load_test(path, **CALIBRATED, date_order="dmy")


def test_ambiguous_dates_that_do_not_change_need_no_order(tmp_path):
    g = load_test(write_logger(tmp_path / "one_day.txt", start="2022-05-06 10:00:00"), **CALIBRATED,
                  force_zero=0.5)
    _same_as_truth(g)
    assert g.metadata["read"]["date_order"] is None and "not needed" in g.metadata["read"]["stamps"]


def test_a_date_order_the_stamps_contradict_is_refused(tmp_path):
    path = write_logger(tmp_path / "us.txt")
    with pytest.raises(DataError) as err:
        load_test(path, **CALIBRATED, date_order="dmy")
    msg = str(err.value)
    assert "us.txt" in msg and "--date-order dmy" in msg and "month field is 25" in msg and "line 8" in msg
    assert "use --date-order mdy" in msg


def test_the_declared_rate_is_checked_and_stands_in_for_a_missing_time_column(tmp_path):
    wrong = ["Header Size:  7", "Version:  2", "Sampling Interval:  0.002", "Sampling Rate:  500",
             "Sample Count:  4000", "Device Serial Number:  0"]
    g = load_test(write_logger(tmp_path / "wrong_rate.txt", preamble=wrong), **CALIBRATED)
    (warning,) = g.metadata["warnings"]
    assert "'Sampling Interval: 0.002' (500 Hz)" in warning and "gives 1000 Hz" in warning
    assert not g.metadata["read"]["declared_rate"]["agrees"]
    g = load_test(write_logger(tmp_path / "no_time.txt"), **dict(CALIBRATED, time_col=None), force_zero=0.5)
    _same_as_truth(g)
    assert "as the preamble declares ('Sampling Interval: 0.001')" in g.metadata["read"]["time"]


def test_a_csv_preamble_of_key_value_pairs_before_a_header_with_units(tmp_path):
    """Another logger's export: 'key,value' lines, then a header with units; the rate is declared in kHz."""
    t, x, f = truth()
    path = tmp_path / "export.csv"
    rows = ["Logger,RigSoft 4", "Sample rate,1 kHz", "Date,2024-05-14", "time [s],stroke [mm],force [kN]"]
    rows += [f"{a:.3f},{1e3 * b:.6f},{c / 1e3:.7f}" for a, b, c in zip(t, x, f)]
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    g = load_test(path, damper_class="any")
    np.testing.assert_allclose(g.stroke, x, rtol=0, atol=0.5e-9 * 1.001)
    np.testing.assert_allclose(g.force, f, rtol=0, atol=0.5e-4 * 1.001)
    read = g.metadata["read"]
    assert read["header_line"] == 4 and read["units"] == {"stroke": "mm", "force": "kN", "time": "s"}
    assert read["preamble"] == {"Logger": "RigSoft 4", "Sample rate": "1 kHz", "Date": "2024-05-14"}
    assert read["declared_rate"] == {"declared_hz": {"Sample rate": 1000.0}, "time_column_hz": g.sample_rate,
                                     "agrees": True}


def test_a_measured_velocity_in_volts_with_its_calibration_and_the_stroke_sign(tmp_path):
    """A velocity channel written as volts (50 mm/s per V, 0.1 V at rest) and declared in V: read with
    its scale and offset in mm/s (the header's V is the raw unit), and flipped with the stroke's sign."""
    t, x, f = truth()
    v_mm_s = 1e3 * np.gradient(x, t)
    path = tmp_path / "velocity.csv"
    pd.DataFrame({"time [s]": t, "stroke [mm]": 1e3 * x, "force [N]": f, "vel (V)": v_mm_s / 50.0 + 0.1}) \
        .to_csv(path, index=False, float_format="%.6f")
    cal = dict(velocity_col="vel", velocity_scale=50.0, velocity_offset=-5.0, velocity_unit="mm/s", damper_class="any")
    g = load_test(path, **cal)
    np.testing.assert_allclose(g.velocity, 1e-3 * v_mm_s, rtol=0, atol=1e-3 * 50 * 0.5e-6 * 1.001)
    read = g.metadata["read"]
    assert read["units"]["velocity"] == "mm/s" and read["calibration"]["velocity"]["raw_unit"] == "V"
    flipped = load_test(path, **cal, stroke_sign=-1, force_sign=-1)
    np.testing.assert_allclose(flipped.velocity, -g.velocity, rtol=0, atol=1e-15)


# --------------------------------------------------------------------------- errors

def test_the_header_line_option_overrides_a_misleading_preamble(tmp_path):
    """A preamble line with as many comma-separated fields as the table, right before the header, is
    taken for the header: the missing column's message names --header-line, which reads the file."""
    for listed, expected in (("stroke, force, command, a, b, c", "missing column 'Date/Time'"),
                             ("stroke, force, command, spare, spare, spare",
                              "names column(s) ['spare'] more than once")):
        path = write_logger(tmp_path / "channels_listed.txt", before_header=[f"Channels: {listed}"])
        with pytest.raises(DataError) as err:
            load_test(path, **CALIBRATED)
        msg = str(err.value)
        assert expected in msg and "line 7" in msg and "--header-line N" in msg, msg
        g = load_test(path, **CALIBRATED, header_line=8, force_zero=0.5)
        _same_as_truth(g)
        assert g.metadata["read"]["header_line"] == 8 and g.metadata["read"]["preamble"]["Channels"] == listed


@pytest.mark.parametrize("damaged, fields, why", [
    # a number more among the numeric columns, then an event: the number falls where 'Events' starts
    ("  100, 05/25/2022 11:59:58.099 AM, 2.5, 0.02, 0.02, 0.0, Marker", 7, "its field 6 ('0.0') is a number"),
    ("  100, 05/25/2022 11:59:58.099 AM, 2.5, 0.02", 4, "not a row of that table"),  # fields missing
])
def test_a_damaged_row_is_named_with_its_line_and_the_header_line(tmp_path, damaged, fields, why):
    path = write_logger(tmp_path / "damaged.txt", extra_row=(99, damaged))
    with pytest.raises(DataError) as err:
        load_test(path, **CALIBRATED)
    msg = str(err.value)
    for s in ("damaged.txt", f"line 108 has {fields} field(s)", "the header (line 7) has 6", why, "--header-line N"):
        assert s in msg, (s, msg)


def test_an_events_cell_holding_the_delimiter_reads_as_one_event(tmp_path):
    """Rows whose 'Events' text holds the delimiter, the first row's too (the header is found over it): the
    trailing text column takes the rest of the row, the text joined back; the signals are the truth's."""
    path = write_logger(tmp_path / "two_events.txt", events={0: "DAQ Start, Trigger", 1999: "Marker, trigger 2"})
    g = load_test(path, **CALIBRATED, force_zero=0.8)
    _same_as_truth(g)
    assert g.metadata["read"]["header_line"] == 7
    assert g.metadata["read"]["text_columns"] == {
        "Events": "'DAQ Start, Trigger', 'Marker, trigger 2', 'Marker' ... on 4 of 4000 rows"}


@pytest.mark.parametrize("options, expected", [
    (dict(header_line=0), ["--header-line (header_line) must be a line number from 1, got 0"]),
    (dict(header_line="7"), ["--header-line (header_line)", "'7'"]),
    (dict(header_line=99999), ["--header-line 99999 is beyond the file's last line (4007)"]),
    (dict(stroke_scale=0.0), ["--stroke-scale (stroke_scale) must be a positive finite number, got 0.0"]),
    (dict(force_scale=-FORCE_N_PER_V), ["--force-scale (force_scale)", "--force-sign -1"]),
    (dict(force_offset="25 N"), ["--force-offset (force_offset) must be a finite number, got '25 N'"]),
    (dict(stroke_scale=float("nan")), ["--stroke-scale (stroke_scale)", "nan"]),
    (dict(velocity_scale=1.0), ["--velocity-scale", "--velocity-col"]),
    (dict(date_order="ymd"), ["--date-order (date_order) must be mdy", "'ymd'"]),
    (dict(force_zero=5.0), ["--force-zero 5 s is not shorter than the test (3.999 s)"]),
    (dict(force_zero=1.5), ["the stroke moves", "first 1.5 s", "shorter --force-zero"]),
    (dict(force_zero=-1.0), ["--force-zero (force_zero) must be a positive finite number"]),
])
def test_bad_option_values_are_refused_naming_the_option(tmp_path, options, expected):
    path = write_logger(tmp_path / "good.txt")
    with pytest.raises(DataError) as err:
        load_test(path, **{**CALIBRATED, **options})
    msg = str(err.value)
    assert "good.txt" in msg
    for s in expected:
        assert s in msg, (s, msg)


# --------------------------------------------------------------------------- command line

def _cli_args(path):
    return ["inspect", str(path), "--time-col", "Date/Time", "--stroke-col", "CHANNEL0", "--stroke-scale", "10",
            "--stroke-offset", "-25", "--stroke-unit", "mm", "--force-col", "CHANNEL1", "--force-scale", "980.665",
            "--force-unit", "N", "--force-zero", "0.8", "--damper-class", "any"]


def test_inspect_shows_preamble_stamps_calibration_tare_and_events(tmp_path, capsys):
    path = write_logger(tmp_path / "run_03.txt")
    assert main(_cli_args(path)) == 0
    out = capsys.readouterr().out
    assert "column names on line 7, after a preamble (Header Size: 7, Version: 2" in out
    assert "month/day/year (a second field above 12: 25 at data row 1 (line 8)), 12-hour clock (AM/PM)" in out
    assert ("declared sample rate: Sampling Interval 1000 Hz, Sampling Rate 1000 Hz; the time column gives "
            "1000 Hz") in out
    assert "stroke = 10 x 'CHANNEL0' - 25 [mm]: raw 2.5 .. 2.9 -> 0 .. 4 mm" in out
    assert "force = 980.665 x 'CHANNEL1' [N]: raw " in out
    removed = round(LOAD_CELL_ZERO_N / FORCE_N_PER_V, 4) * FORCE_N_PER_V  # the zero as written, in volts
    assert f"force zero: {removed:.4g} N removed (the mean over the first 0.8 s, 801 samples" in out
    assert "text column 'Events' left out (not a signal): 'DAQ Start', 'Marker', 'DAQ Pause' on 3 of 4000 rows" in out
    assert "4000 samples at 1000 Hz" in out and "warning" not in out
    assert main(_cli_args(path) + ["--json"]) == 0
    figures = json.loads(capsys.readouterr().out)[0]  # strict JSON: no NaN
    assert figures["date_order"] == "mdy" and figures["force_zero"]["samples"] == 801
    assert figures["calibration"]["stroke"]["scaled_range"] == pytest.approx([0.0, 4.0])


def test_columns_file_keys_and_command_line_errors(tmp_path, capsys):
    """The calibration as --columns keys (TOML for every file, JSON per file); a file the reader cannot
    parse and a bad option value exit 2 naming the file and the option, and fit writes nothing."""
    path = write_logger(tmp_path / "run_04.txt", before_header=["Channels: stroke, force, command, a, b, c"])
    toml = tmp_path / "columns.toml"
    toml.write_text('[columns]\ntime_col = "Date/Time"\nstroke_col = "CHANNEL0"\nstroke_scale = 10\n'
                    'stroke_offset = -25.0\nstroke_unit = "mm"\nforce_col = "CHANNEL1"\nforce_scale = 980.665\n'
                    'force_unit = "N"\nforce_zero = 0.8\ndamper_class = "any"\ndate_order = "mdy"\n'
                    '[files."run_04.txt"]\nheader_line = 8\n')
    assert main(["inspect", str(path), "--columns", str(toml)]) == 0
    assert "force zero: 25.01 N removed" in capsys.readouterr().out
    per_file = tmp_path / "columns.json"
    per_file.write_text(json.dumps({"columns": {"header_line": 3}, "files": {}}))
    assert main(["inspect", str(path), "--columns", str(per_file)]) == 2
    err = capsys.readouterr().err
    assert "run_04.txt" in err and "the header (line 3) has" in err and "--header-line N" in err
    assert main(_cli_args(path)[:2] + ["--time-col", "Date/Time"]) == 2  # the misleading preamble line
    assert "--header-line N" in capsys.readouterr().err
    assert main(_cli_args(path) + ["--header-line", "8", "--force-zero", "9"]) == 2
    assert "--force-zero 9 s is not shorter than the test" in capsys.readouterr().err
    out = tmp_path / "fit"
    assert main(["fit", "--identification", str(path), "--validation", str(path), "--out", str(out)]
                + _cli_args(path)[2:]) == 2
    assert "run_04.txt" in capsys.readouterr().err and not out.exists()


# --------------------------------------------------------------------------- the real logger's file

def _real_rows():
    """The real slice parsed here, independently of the reader: (sample numbers, stamps, CHANNEL0 [V],
    CHANNEL1 [V], events)."""
    with gzip.open(REAL, "rt", encoding="utf-8", newline="") as fh:
        lines = fh.read().splitlines()
    rows = [[c.strip() for c in line.split(",")] for line in lines[7:]]
    return ([int(r[0]) for r in rows], [r[1] for r in rows], np.array([float(r[2]) for r in rows]),
            np.array([float(r[3]) for r in rows]), [r[5] for r in rows if len(r) > 5])


def test_the_real_logger_slice_reads_with_the_users_calibrations():
    """The first 6000 rows of the MR damper's raw logger file, as written: time from the Date/Time column
    at 1 kHz, stroke in mm (10 mm/V), force in N (980.665 N/V), the load cell's zero removed over the
    4.7 s lead-in before the press moves."""
    numbers, stamp_text, v0, v1, events = _real_rows()
    g = load_test(REAL, **REAL_CALIBRATED, force_zero=4.0)
    first, last = (datetime.strptime(s, "%m/%d/%Y %I:%M:%S.%f %p") for s in (stamp_text[0], stamp_text[-1]))
    assert len(g.time) == len(numbers) == 6000 and g.sample_rate == pytest.approx(1000.0, rel=1e-12)
    assert g.duration == pytest.approx((last - first).total_seconds(), abs=1e-9)
    np.testing.assert_allclose(g.time, (np.array(numbers) - 1) / 1000.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(g.stroke, 10e-3 * v0, rtol=0, atol=1e-12)
    zero = np.mean(980.665 * v1[:4001])
    np.testing.assert_allclose(g.force, 980.665 * v1 - zero, rtol=0, atol=1e-9)
    read = g.metadata["read"]
    assert read["force_zero"]["removed_n"] == pytest.approx(zero, abs=1e-9)
    assert read["header_line"] == 7 and read["preamble"]["Sampling Rate"] == "1000"
    assert read["declared_rate"]["agrees"] and read["date_order"] == "mdy"
    assert events == ["DAQ Start"] and read["text_columns"] == {"Events": "'DAQ Start' on 1 of 6000 rows"}
    assert read["plausibility"]["force_velocity_correlation"] > 0.3  # as written, the damper absorbs power
    assert not g.metadata.get("warnings")


def test_inspect_on_the_real_logger_slice(capsys):
    assert main(["inspect", str(REAL), "--time-col", "Date/Time", "--stroke-col", "CHANNEL0", "--stroke-scale", "10",
                 "--stroke-unit", "mm", "--force-col", "CHANNEL1", "--force-scale", "980.665", "--force-unit", "N",
                 "--damper-class", "any"]) == 0
    out = capsys.readouterr().out
    assert "6000 samples at 1000 Hz" in out and "stroke -3.926 .. 0.05 mm" in out
    assert "stroke = 10 x 'CHANNEL0' [mm]: raw -0.3926 .. 0.005 -> -3.926 .. 0.05 mm" in out
    assert "text column 'Events' left out (not a signal): 'DAQ Start' on 1 of 6000 rows" in out
    assert main(["inspect", str(REAL)]) == 2  # no column named: the message lists what the file holds
    err = capsys.readouterr().err
    assert "15Hz0x5A_first6000.txt.gz" in err and "'Date/Time'" in err and "--time-col" in err


def _file_lines(path) -> list[str]:
    with gzip.open(path, "rt", encoding="utf-8", newline="") as fh:
        return fh.read().splitlines()


def test_the_real_logger_with_two_events_in_the_last_row_reads_every_row(tmp_path):
    """Another of the lab's files ends with two events in the 'Events' cell, written with the column
    delimiter: every row reads, the last row's numbers in their columns, its events as one text. A row with
    a field more among the numbers is still refused naming its line."""
    lines = _file_lines(TWO_EVENTS)
    rows = [[c.strip() for c in line.split(",")] for line in lines[7:]]  # parsed here, independently
    last = rows[-1]
    assert len(last) == 7 and all(len(r) == 5 for r in rows[:-1])  # the fixture as described
    g = load_test(TWO_EVENTS, **REAL_CALIBRATED)
    numbers = np.array([int(r[0]) for r in rows])
    assert len(g.time) == len(rows) == 400
    np.testing.assert_allclose(g.time, (numbers - numbers[0]) / 1000.0, rtol=0, atol=1e-9)
    assert g.stroke[-1] == pytest.approx(10e-3 * float(last[2]), abs=1e-12)
    assert g.force[-1] == pytest.approx(980.665 * float(last[3]), abs=1e-9)
    assert g.channels["CHANNEL2"][-1] == float(last[4]) and g.channels["Sample Number"][-1] == numbers[-1]
    assert g.metadata["read"]["text_columns"] == {"Events": f"{', '.join(last[5:])!r} on 1 of 400 rows"}
    assert not g.metadata.get("warnings")

    k = 100  # row 101, file line 108: a number more among the numeric columns, its event after it
    cells = lines[7 + k].split(",")
    damaged = tmp_path / "damaged.txt"
    damaged.write_text("\n".join(lines[:7 + k] + [",".join(cells[:3] + cells[2:] + [" Marker"])]
                                 + lines[8 + k:]) + "\n", encoding="utf-8")
    with pytest.raises(DataError) as err:
        load_test(damaged, **REAL_CALIBRATED)
    msg = str(err.value)
    for s in ("damaged.txt", f"line {8 + k} has 7 field(s)", "the header (line 7) has 6",
              f"its field 6 ({cells[4].strip()!r}) is a number", "--header-line N"):
        assert s in msg, (s, msg)
