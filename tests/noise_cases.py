"""Rig tests of known force noise, for checking the tuner's noise estimators (``tests/test_noise.py``,
``benchmarks/noise_estimate.py``; test support, beside the tests: the campaign does not import the tuner).

A random lumped damper of the model's class (``campaign.damper_class.random_damper``) driven by a
stroke, simulated on the rig's internal grid and acquired through its sensor chain
(``campaign.sensors.SensorChain``: load-cell noise, FIR anti-alias filter, decimation, ADC), then
optionally low-pass filtered as a rig's software does before it writes the file. The noise is known
exactly: the same acquisition with no load-cell noise and an ideal ADC gives the noise-free force
(the noise is load-cell noise plus quantisation), and the filter (linear) acts on the difference
alike. SI units.

Shapes (``SHAPES``): ``sine_500`` / ``sine_2k``: a sine stroke (0.5-3 Hz, 30-150 mm/s, 1 s fade-in)
at 500 Hz / 2 kHz; ``sine_200_filtered``: the same at 200 Hz with force and stroke filtered
(Butterworth, 4th order, zero-phase, cut-off 0.1 x the sample rate: the filtered MR-damper files);
``random_500``: a random multisine stroke (``campaign.damper_class.random_stroke``) at 500 Hz;
``random_200_filtered``: that at 200 Hz, filtered; ``sine_500_quantised``: the sine at 500 Hz
through a 10-bit ADC over +-``force_range`` (steps of 2 x range / 1024) with 1 N of load-cell noise;
``replay_500``: a random multisine drive replayed twice in one test (``replay_stroke``: faded in and
out, 1 s at rest between) at 500 Hz; ``replay_200_filtered``: that at 200 Hz, filtered;
``replay_500_shifted``: at 500 Hz with the rest a quarter to three quarters of a sample longer (the
replay starts between the file's samples).
"""
from __future__ import annotations

import math

import numpy as np
from scipy import signal

from campaign.damper_class import OVERSAMPLING, random_damper, random_stroke
from campaign.sensors import SensorChain
from damper_fmu import REPLAY, SolverOptions, simulate
from damper_fmu.integrator import DEFAULT_MAX_STEP
from tuner.data.preprocess import Resampler
from tuner.data.reading import RigTest

__all__ = ["SHAPES", "noise_case", "sine_stroke", "replay_stroke"]

SHAPES = ("sine_500", "sine_2k", "sine_200_filtered", "random_500", "random_200_filtered", "sine_500_quantised",
          "replay_500", "replay_200_filtered", "replay_500_shifted")


def replay_stroke(seed: int, duration: float, fs: float, extra_samples: int = 0
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(time [s], stroke [m], velocity [m/s]) at ``fs`` [Hz] of ``duration`` [s]: a random multisine
    drive (``campaign.damper_class.random_stroke``, faded in and out over 1 s) of (duration - 1) / 2 s,
    at rest for 1 s plus ``extra_samples`` samples, then the same drive again (cut at ``duration``)."""
    seg = 0.5 * (duration - 1.0)
    t, x, v = random_stroke("multisine", seed, seg, fs)
    fade = np.clip((t[-1] - t) / 1.0, 0.0, 1.0)               # 1 -> 0 over the last second
    r = 0.5 - 0.5 * np.cos(np.pi * fade)
    dr = np.where(fade < 1.0, -0.5 * np.pi * np.sin(np.pi * fade), 0.0)   # d r / dt (fade falls at 1 / s)
    x, v = x * r, v * r + x * dr
    n = int(round(duration * fs)) + 1
    rest = int(round(1.0 * fs)) - 1 + int(extra_samples)      # the drive replayed 1 + (duration - 1) / 2 s on
    xs, vs = np.zeros(n), np.zeros(n)
    k = min(x.size, n)
    xs[:k], vs[:k] = x[:k], v[:k]
    k2 = x.size + rest
    if k2 < n:
        m = min(x.size, n - k2)
        xs[k2:k2 + m], vs[k2:k2 + m] = x[:m], v[:m]
    return np.arange(n) / fs, xs, vs


def sine_stroke(seed: int, duration: float, fs: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(time [s], stroke [m], velocity [m/s]) at ``fs`` [Hz]: a sine of 0.5-3 Hz and 30-150 mm/s
    velocity amplitude (stroke at most 40 mm) drawn from ``seed``, faded in over 1 s."""
    rng = np.random.default_rng([seed, 31])
    f, vamp = rng.uniform(0.5, 3.0), rng.uniform(0.03, 0.15)
    amp = min(vamp / (2 * np.pi * f), 0.04)
    t = np.arange(int(round(duration * fs)) + 1) / fs
    w = 2 * np.pi * f
    r = np.where(t < 1.0, 0.5 - 0.5 * np.cos(np.pi * np.minimum(t, 1.0)), 1.0)
    dr = np.where(t < 1.0, 0.5 * np.pi * np.sin(np.pi * np.minimum(t, 1.0)), 0.0)
    return t, amp * np.sin(w * t) * r, amp * w * np.cos(w * t) * r + amp * np.sin(w * t) * dr


def noise_case(shape: str, seed: int, *, noise_n: float | None = None, duration_s: float = 12.0,
               fit_rate_hz: float = 200.0):
    """(``tuner.data.reading.RigTest``, truth) of one ``SHAPES`` case. noise_n: load-cell noise [N rms
    after the anti-alias filter] (default log-uniform in 5-50 N from ``seed``). truth: {"shape",
    "noise_n" (rms of the noise in the file [N]), "in_band_n" (rms of that noise after the tuner's
    resampling to ``fit_rate_hz``, ``tuner.data.preprocess.Resampler``), "load_cell_noise_n",
    "filtered", "step_n" (ADC step [N]), "sample_rate_hz", "periodic"}."""
    if shape not in SHAPES:
        raise ValueError(f"unknown noise case {shape!r}; known: {', '.join(SHAPES)}")
    rng = np.random.default_rng([seed, 8111, SHAPES.index(shape)])
    fs = {"500": 500.0, "2k": 2000.0, "200": 200.0}[shape.split("_")[1]]
    filtered, periodic, quantised = shape.endswith("filtered"), shape.startswith("sine"), shape.endswith("quantised")
    replay = shape.startswith("replay")
    if noise_n is None:
        noise_n = 1.0 if quantised else math.exp(rng.uniform(math.log(5.0), math.log(50.0)))
    fs_int = OVERSAMPLING * fs
    if periodic:
        t, x, v = sine_stroke(seed, duration_s, fs_int)
    elif replay:      # shifted: 1-3 internal samples more at rest, a quarter to three quarters of a file sample
        extra = 1 + seed % (OVERSAMPLING - 1) if shape.endswith("shifted") else 0
        t, x, v = replay_stroke(seed, duration_s, fs_int, extra)
    else:
        t, x, v = random_stroke("multisine", seed, duration_s, fs_int)
    n = (t.size - 1) // OVERSAMPLING * OVERSAMPLING + 1
    t, x, v = t[:n], x[:n], v[:n]
    force = simulate("lumped", t, x, v, params=random_damper("lumped", seed),
                     solver=SolverOptions(max_step=min(DEFAULT_MAX_STEP, 1.0 / fs_int), input_mode=REPLAY))
    peak = float(np.abs(force).max())
    sensors = dict(oversampling=OVERSAMPLING, force_range=max(5e3, 2.0 ** math.ceil(math.log2(1.25 * peak))))
    if quantised:
        sensors["adc_bits"] = 10
    temp = np.full(n, 20.0)
    s_out, f_out, _ = SensorChain(force_noise=noise_n, **sensors).acquire(x, force, temp, seed=seed)
    ideal = {**sensors, "adc_bits": 32, "force_range": 1e6}     # the force as a perfect load cell reads it
    _, f_clean, _ = SensorChain(force_noise=0.0, **ideal).acquire(x, force, temp, seed=seed)
    if filtered:
        sos = signal.butter(4, 0.2, output="sos")          # 0.1 x the sample rate
        s_out, f_out, f_clean = (signal.sosfiltfilt(sos, a) for a in (s_out, f_out, f_clean))
    noise = f_out - f_clean
    in_band = (float(np.std(Resampler.design(fs, fit_rate_hz).apply(noise))) if fit_rate_hz < fs
               else float(np.std(noise)))
    test = RigTest(name=f"{shape}_{seed}", role="identification", scenario=f"noise case {shape}, seed {seed}",
                   time=t[::OVERSAMPLING].copy(), stroke=s_out, force=f_out, sample_rate=fs)
    truth = {"shape": shape, "noise_n": float(np.std(noise)), "in_band_n": in_band, "load_cell_noise_n": float(noise_n),
             "filtered": filtered, "step_n": SensorChain(**sensors).lsb(sensors["force_range"]),
             "sample_rate_hz": fs, "periodic": periodic, "replay": replay}
    return test, truth
