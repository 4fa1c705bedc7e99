"""Regression tests for the shapes of real rig files (issue 29 item 4): small files written here the way
three public datasets were written, from a damper model with known truth, read as written.

* ``press_200``: an MR damper at 0 A on a test press: sine tests at 200 Hz, space-separated text
  WITHOUT a header (columns by position: time [s], stroke [mm], stroke command [mm], force [N],
  current [A]), stroke and force low-pass filtered by the rig's software (nothing left between 0.1 and
  0.3 x the sample rate). Read with ``--time-col 1 --stroke-col 2 --force-col 4 --stroke-unit mm``.
* ``heat_gun_300``: a damper warmed by a heat gun over a 96 s run at 300 Hz: date-time stamps to the
  millisecond, volt and engineering channels side by side (``Force (V)``, ``Force (N)``,
  ``Temperature (V)``, ``Temperature (degC)``; volts = gain x value + offset), a sample-rate constant
  written in the first row only, and a trailing comma on every line (an empty last column).
* ``logger_3k``: a white-noise test of a large MR damper logged at 3004.8 Hz with jittered time stamps,
  stroke in cm, force in kN, current and valve command beside them.

The truth: the signals written (before the file's rounding) and the force noise put into them
(``tests/noise_cases.py`` for the press, ``campaign.synthetic.model_tests`` with and without noise for
the heat gun, white noise of known rms for the logger). What test_rig_formats.py and test_data.py
already hold (headers with units, a units row, ms-rounded ISO stamps, a first-row constant and a
trailing empty column in a file with a header, a 3004.8 Hz clock given in memory) is not repeated.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from campaign.damper_class import random_damper
from campaign.synthetic import model_tests
from damper_fmu import simulate
from damper_fmu.fmu import native_reason
from damper_fmu.parameters import defaults
from tuner.__main__ import main
from tuner.data.noise import force_noise
from tuner.data.preprocess import Resampler, prepare
from tuner.data.reading import load_files, load_test

from noise_cases import noise_case

FIT_RATE = 200.0
PRESS_OPTIONS = dict(time_col=1, stroke_col=2, force_col=4, stroke_unit="mm")
PRESS_ARGS = ["--time-col", "1", "--stroke-col", "2", "--force-col", "4", "--stroke-unit", "mm"]


def _half_step(decimals: int) -> float:
    """Largest rounding error of a value written with ``decimals`` decimals (and a float's share)."""
    return 0.5 * 10.0 ** -decimals * (1 + 1e-6)


def _within_factor_2(estimate: float, truth: float) -> bool:
    return truth / 2 <= estimate <= 2 * truth


# --------------------------------------------------------------------------- the writers

def write_press_200(path, test) -> None:
    """The press's text file: fixed-width columns separated by blanks, no header, no comment; time
    [s, 3 decimals], stroke [mm, 5], stroke command [mm, 2: the set-point, a clean sine], force
    [N, 3], coil current [A, 3: 0 A throughout]."""
    command = 1e3 * test.stroke
    with open(path, "w", encoding="utf-8", newline="\n") as fh:
        for t, x, c, f in zip(test.time, test.stroke, command, test.force):
            fh.write(f"{t:9.3f} {1e3 * x:11.5f} {c:9.2f} {f:12.3f} {0.0:7.3f}\n")


FORCE_GAIN_V_PER_N, FORCE_OFFSET_V = 1.0 / 2000.0, 0.0123      # a +-10 V load cell of +-20 kN
TEMP_GAIN_V_PER_C, TEMP_OFFSET_V = 0.01, 0.5                    # a thermocouple amplifier, 10 mV/degC


def heat_gun_temperature(t):
    """Oil temperature [degC] under the heat gun: 22 degC rising towards 70 degC (40 s time constant)."""
    return 22.0 + 48.0 * (1.0 - np.exp(-t / 40.0))


def write_heat_gun_300(path, t, stroke, force, start="2024-05-14 13:59:58") -> None:
    """The logger's CSV: date-time stamps (US month/day, 12-hour clock, to the millisecond),
    displacement [mm, 4], force in V [5] and in N [2], temperature in V [5] and in degC [2], the sample
    rate in the first row only, a trailing comma on every line (the header's too). The run crosses
    2 pm: the 12-hour clock goes from 01:59:59 PM to 02:00:00 PM."""
    stamps = pd.Timestamp(start) + pd.to_timedelta(np.round(t * 1e3), unit="ms")
    text = stamps.strftime("%m/%d/%Y %I:%M:%S.%f %p")
    temp = heat_gun_temperature(t)
    with open(path, "w", encoding="utf-8", newline="\r\n") as fh:
        fh.write("Timestamp,Displacement (mm),Force (V),Force (N),Temperature (V),Temperature (degC),"
                 "Sample Rate (Hz),\n")
        for i in range(t.size):
            stamp = text[i][:23] + text[i][26:]  # microseconds cut to milliseconds, keeping ' PM'
            fh.write(f"{stamp},{1e3 * stroke[i]:.4f},{FORCE_GAIN_V_PER_N * force[i] + FORCE_OFFSET_V:.5f},"
                     f"{force[i]:.2f},{TEMP_GAIN_V_PER_C * temp[i] + TEMP_OFFSET_V:.5f},{temp[i]:.2f},"
                     f"{'300' if i == 0 else ''},\n")


LOGGER_RATE = 3004.8
JITTER_S = 20e-6


def white_noise_stroke(seed: int, duration: float, fs: float, rms_m: float = 4e-3, band=(0.5, 15.0)):
    """(time, stroke [m], velocity [m/s]): a band-limited white-noise stroke, 80 random-phase sines of
    equal amplitude spread over ``band`` [Hz] (a flat spectrum), faded in over 1 s."""
    rng = np.random.default_rng([seed, 3005])
    freqs, phases = rng.uniform(*band, 80), rng.uniform(0, 2 * np.pi, 80)
    t = np.arange(int(round(duration * fs))) / fs
    arg = 2 * np.pi * freqs[:, None] * t + phases[:, None]
    a = rms_m * math.sqrt(2.0 / 80)
    x, v = a * np.sin(arg).sum(0), (a * 2 * np.pi * freqs[:, None] * np.cos(arg)).sum(0)
    r = np.where(t < 1.0, 0.5 - 0.5 * np.cos(np.pi * np.minimum(t, 1.0)), 1.0)
    dr = np.where(t < 1.0, 0.5 * np.pi * np.sin(np.pi * np.minimum(t, 1.0)), 0.0)
    return t, x * r, v * r + x * dr


def write_logger_3k(path, stamps, stroke, force, current) -> None:
    """The 3 kHz logger's CSV: time [s, 6 decimals, jittered stamps], stroke in cm [5], force in kN [5],
    the coil current [A, 3] and the valve command [V, 3] beside them; units in the header."""
    with open(path, "w", encoding="utf-8", newline="\n") as fh:
        fh.write("Time [s],Stroke [cm],Force [kN],Current [A],Valve command [V]\n")
        for t, x, f, i in zip(stamps, stroke, force, current):
            fh.write(f"{t:.6f},{1e2 * x:.5f},{f / 1e3:.5f},{i:.3f},{2.0 * i:.3f}\n")


# --------------------------------------------------------------------------- the cases

@pytest.fixture(scope="module")
def press(tmp_path_factory):
    """Two press files of known noise: a filtered sine (periodic) and a filtered random stroke."""
    folder = tmp_path_factory.mktemp("press")
    out = {}
    for shape, seed in (("sine_200_filtered", 4), ("random_200_filtered", 5)):
        test, truth = noise_case(shape, seed, fit_rate_hz=FIT_RATE)
        path = folder / f"{shape}.txt"
        write_press_200(path, test)
        out[shape] = (path, test, truth)
    return out


@pytest.fixture(scope="module")
def heat_gun(tmp_path_factory):
    params = defaults("lumped")
    kw = dict(seed=7, durations=(96.0,), roles=("identification",), fs=300.0)
    (noisy,), (clean,) = model_tests("lumped", params, noise_n=15.0, **kw), model_tests("lumped", params, noise_n=0.0, **kw)
    frame = noisy["frame"]
    noise = frame["force"].to_numpy() - clean["frame"]["force"].to_numpy()
    path = tmp_path_factory.mktemp("heat_gun") / "heat_gun_run_03.csv"
    t = frame["time"].to_numpy()
    write_heat_gun_300(path, t, frame["stroke"].to_numpy(), frame["force"].to_numpy())
    in_band = float(np.std(Resampler.design(300.0, FIT_RATE).apply(noise)))
    return path, frame, {"noise_n": float(np.std(noise)), "in_band_n": in_band}


@pytest.fixture(scope="module")
def logger(tmp_path_factory):
    t, x, v = white_noise_stroke(11, 8.0, LOGGER_RATE)
    clean = simulate("lumped", t, x, v, params=random_damper("lumped", 11))
    sigma = 40.0  # white load-cell noise [N rms] over the logger's Nyquist band
    rng = np.random.default_rng(12)
    force = clean + rng.normal(0.0, sigma, t.size)
    current = np.zeros(t.size)
    stamps = t + rng.uniform(-JITTER_S, JITTER_S, t.size)
    path = tmp_path_factory.mktemp("logger") / "wn_0A_3k.csv"
    write_logger_3k(path, stamps, x, force, current)
    # white noise keeps fit_rate / rate of its power below the fit band's edge
    return path, {"time": t, "stroke": x, "force": force}, {"in_band_n": sigma * math.sqrt(FIT_RATE / LOGGER_RATE)}


# --------------------------------------------------------------------------- press: header-less 200 Hz, filtered

def test_press_file_without_header_is_read_by_position_to_the_files_precision(press):
    path, truth, _ = press["sine_200_filtered"]
    (g,) = load_files(path, "identification", **PRESS_OPTIONS)
    assert g.time.size == truth.time.size  # the first line is a sample, not a header
    np.testing.assert_allclose(g.time, truth.time, rtol=0, atol=_half_step(3))
    np.testing.assert_allclose(g.stroke, truth.stroke, rtol=0, atol=1e-3 * _half_step(5))
    np.testing.assert_allclose(g.force, truth.force, rtol=0, atol=_half_step(3))
    assert g.sample_rate == pytest.approx(200.0, rel=1e-9)
    read = g.metadata["read"]
    assert read["columns"] == {"time": "column 1", "stroke": "column 2", "force": "column 4"}
    assert read["units"] == {"stroke": "mm", "force": "N", "time": "s"}
    assert read["delimiter"] is None  # runs of blanks
    # the unused columns are channels by position, without a unit (the file declares none)
    np.testing.assert_allclose(g.channels["column 3"], 1e3 * truth.stroke, rtol=0, atol=_half_step(2))
    np.testing.assert_array_equal(g.channels["column 5"], 0.0)
    assert g.channel_units == {"column 3": "", "column 5": ""}
    assert not g.metadata.get("warnings")


def test_pandas_column_numbers_stay_a_header(tmp_path, press):
    """What pandas writes for an unnamed table ('0,1,2') is a header, not the first sample."""
    _, truth, _ = press["sine_200_filtered"]
    p = tmp_path / "unnamed.csv"
    pd.DataFrame(np.column_stack([truth.time, truth.stroke, truth.force])).to_csv(p, index=False)
    g = load_test(p, time_col=1, stroke_col=2, force_col=3)
    assert g.metadata["read"]["columns"] == {"time": "0", "stroke": "1", "force": "2"}
    np.testing.assert_allclose(g.force, truth.force, rtol=1e-12)


def test_filtered_periodic_press_file_gives_the_cycle_scatter_within_a_factor_2(press):
    """The filtered sine: the quiet band is empty (not credible, saying why); the cycle scatter reads
    the noise in the fit band within a factor 2 of the truth."""
    path, _, truth = press["sine_200_filtered"]
    n = force_noise(load_test(path, **PRESS_OPTIONS), FIT_RATE)
    assert n["credible"] and n["method"] == "cycle_scatter"
    assert _within_factor_2(n["in_band_n"], truth["in_band_n"]), (n["in_band_n"], truth["in_band_n"])
    band = n["all"]["quiet_band"]
    assert not band["credible"] and "low-pass filtered" in " ".join(band["reasons"])


def test_filtered_random_press_file_has_no_credible_noise_and_says_why(press):
    """A random stroke does not repeat and the filter emptied the quiet band: nothing in the data shows
    the noise."""
    path, _, _ = press["random_200_filtered"]
    n = force_noise(load_test(path, **PRESS_OPTIONS), FIT_RATE)
    assert not n["credible"]
    reasons = " ".join(n["reasons"])
    assert "cycle scatter:" in reasons and "quiet band:" in reasons and "not white" in reasons


def test_inspect_on_the_press_file_names_positions_units_and_rate(press, capsys):
    path, truth, _ = press["sine_200_filtered"]
    assert main(["inspect", str(path)] + PRESS_ARGS) == 0
    out = capsys.readouterr().out
    assert "columns: time <- 'column 1', stroke <- 'column 2', force <- 'column 4'" in out
    assert "stroke in mm, force in N, time in s" in out
    assert f"{truth.time.size} samples at 200 Hz" in out
    assert "force noise" in out and "cycle scatter" in out


# --------------------------------------------------------------------------- heat gun: stamps, volts, incomplete columns

def test_heat_gun_file_is_read_as_written(heat_gun):
    path, frame, _ = heat_gun
    g = load_test(path, time_col="Timestamp", stroke_col="Displacement", force_col="Force (N)")
    t = frame["time"].to_numpy()
    assert g.time.size == t.size
    assert g.sample_rate == pytest.approx(300.0, rel=1e-5)  # the clock behind the ms stamps
    np.testing.assert_allclose(g.time, t, rtol=0, atol=_half_step(3))
    np.testing.assert_allclose(g.stroke, frame["stroke"].to_numpy(), rtol=0, atol=1e-3 * _half_step(4))
    np.testing.assert_allclose(g.force, frame["force"].to_numpy(), rtol=0, atol=_half_step(2))
    # the temperature in degC is the oil temperature; its volt twin is a channel in V, and so is the force's
    np.testing.assert_allclose(g.channels["temperature"], heat_gun_temperature(t), rtol=0, atol=_half_step(2))
    assert g.channel_units["temperature"] == "degC"
    assert g.channel_units["Force (V)"] == "V" and g.channel_units["Temperature (V)"] == "V"
    np.testing.assert_allclose(g.channels["Force (V)"], FORCE_GAIN_V_PER_N * frame["force"].to_numpy()
                               + FORCE_OFFSET_V, rtol=0, atol=_half_step(5))
    np.testing.assert_allclose(g.channels["Temperature (V)"], TEMP_GAIN_V_PER_C * heat_gun_temperature(t)
                               + TEMP_OFFSET_V, rtol=0, atol=_half_step(5))
    read = g.metadata["read"]
    assert read["time"] == "timestamp" and read["columns"]["temperature"] == "Temperature (degC)"
    assert {"Sample Rate (Hz)", ""} <= set(read["ignored"])
    assert set(g.channels) == {"temperature", "Force (V)", "Temperature (V)"}
    warnings = " ".join(g.metadata["warnings"])
    assert "'Sample Rate (Hz)' not read" in warnings and "regular 300 Hz clock" in warnings


def test_heat_gun_noise_is_credible_within_a_factor_2(heat_gun):
    path, _, truth = heat_gun
    n = force_noise(load_test(path, time_col="Timestamp", stroke_col="Displacement", force_col="Force (N)"),
                    FIT_RATE)
    assert n["credible"], n["reasons"]
    assert _within_factor_2(n["in_band_n"], truth["in_band_n"]), (n["in_band_n"], truth["in_band_n"])


def test_inspect_on_the_heat_gun_file_names_the_stamps_and_the_volt_channels(heat_gun, capsys):
    path, _, _ = heat_gun
    assert main(["inspect", str(path), "--time-col", "Timestamp", "--stroke-col", "Displacement",
                 "--force-col", "Force (N)"]) == 0
    out = capsys.readouterr().out
    assert "force <- 'Force (N)'" in out and "temperature <- 'Temperature (degC)'" in out
    assert "time: timestamp" in out and "samples at 300 Hz, 96 s" in out
    assert "channel Force (V):" in out and out.split("channel Force (V):")[1].split("\n")[0].endswith(" V")


# --------------------------------------------------------------------------- logger: 3004.8 Hz, jittered, cm

def test_logger_file_in_cm_with_jittered_stamps_is_read_on_its_clock(logger):
    path, truth, _ = logger
    g = load_test(path)
    assert g.sample_rate == pytest.approx(LOGGER_RATE, rel=1e-5)
    # the regular clock through the stamps: within their jitter and rounding of the truth
    np.testing.assert_allclose(g.time, truth["time"], rtol=0, atol=2 * JITTER_S + _half_step(6))
    np.testing.assert_allclose(g.stroke, truth["stroke"], rtol=0, atol=1e-2 * _half_step(5))
    np.testing.assert_allclose(g.force, truth["force"], rtol=0, atol=1e3 * _half_step(5))
    assert g.metadata["read"]["units"] == {"stroke": "cm", "force": "kN", "time": "s"}
    assert g.channel_units == {"Current [A]": "A", "Valve command [V]": "V"}
    np.testing.assert_array_equal(g.channels["Current [A]"], 0.0)
    assert any("regular 3004.8 Hz clock" in w for w in g.metadata["warnings"])


def test_logger_noise_is_credible_within_a_factor_2_and_the_file_resamples_to_the_fit_rate(logger):
    path, truth, known = logger
    g = load_test(path)
    n = force_noise(g, FIT_RATE)
    assert n["credible"] and n["method"] == "quiet_band", n["reasons"]
    assert _within_factor_2(n["in_band_n"], known["in_band_n"]), (n["in_band_n"], known["in_band_n"])
    p = prepare(g, FIT_RATE)
    assert p.sample_rate == pytest.approx(FIT_RATE, rel=1e-9)
    assert "interpolated (cubic spline)" in p.describe()
    # the stroke (content below 15 Hz) at the fit rate's times is the truth there
    x_true = np.interp(p.time, truth["time"], truth["stroke"])
    assert np.max(np.abs(p.stroke - x_true)) < 1e-3 * np.ptp(truth["stroke"])


def test_inspect_on_the_logger_file_names_cm_and_the_logger_clock(logger, capsys):
    path, _, _ = logger
    assert main(["inspect", str(path)]) == 0
    out = capsys.readouterr().out
    assert "stroke in cm, force in kN" in out
    assert "samples at 3004.8 Hz" in out and "regular 3004.8 Hz clock" in out
    assert "channel Current [A]: 0 .. 0 A" in out


# --------------------------------------------------------------------------- end to end

def test_fit_on_header_less_press_files(tmp_path):
    """`python -m tuner fit` on two header-less press files (one damper: the first 8 s identify, the
    next 8 s validate) with the position and unit options, a tiny budget: exit 0, outputs written."""
    test, _ = noise_case("sine_200_filtered", 6, duration_s=16.0, fit_rate_hz=FIT_RATE)
    half = test.time.size // 2
    files = []
    for role, rows in (("id", slice(0, half)), ("val", slice(half, None))):
        part = type(test)(role, None, "", test.time[rows] - test.time[rows][0], test.stroke[rows], test.force[rows],
                          sample_rate=test.sample_rate)
        files.append(tmp_path / f"press_{role}.txt")
        write_press_200(files[-1], part)
    out = tmp_path / "fit"
    code = main(["fit", "--identification", str(files[0]), "--validation", str(files[1]), "--out", str(out)]
                + PRESS_ARGS + ["--models", "lumped", "--population", "4", "--iterations", "1", "--polish", "2",
                                "--no-diagnose", "--workers", "0", "--quiet",
                                "--engine", "inprocess" if native_reason() else "native"])
    assert code == 0
    for name in ("report.html", "parameters.json", "metrics.json"):
        assert (out / name).is_file(), name
    assert next((out / "fmu").glob("DamperLumped*_tuned.fmu"))
    assert "lumped" in json.loads((out / "parameters.json").read_text())
    # the force low-passed before writing, said per file at the top of the log, is among the warnings at the end
    warnings = json.loads((out / "summary.json").read_text())["warnings"]
    filtered = [w.split(": the force looks filtered")[0] for w in warnings if "the force looks filtered" in w]
    assert filtered == [str(f) for f in files] and all("--prefilter" in w for w in warnings)
