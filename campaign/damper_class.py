"""Random members of each damper model's class and rig-like datasets made from them.

The identification must converge on any damper the model can represent, not on one near its
preset: ``benchmarks/convergence.py`` fits many dampers drawn here blind. SI units; stroke and
rate positive in extension, forces positive in tension.

Priors (wide, documented, one draw per damper from ``numpy.random.default_rng(seed)``):

* damping table (each side on its own: asymmetric): the blow-off knee at any abscissa among the
  first ten rates of the table, the knee force log-uniform in 3-20 kN (compression side), the
  pieces below the knee at slopes scattered by a factor 0.6-1.6 around the knee's mean slope
  (progressive or degressive), above it 1-30 % of that slope; the extension side is the compression
  side's shape drawn anew, scaled by an extension/compression force ratio uniform in 0.6-1.6;
* elastic table (lumped): each side a stiffness log-uniform in 0.3-2.5 x the paper's 1.5e7 N/m
  reference, each piece scattered by a factor 0.8-1.25 (soft to stiff, progressive or not);
* lumped: masses 3-20 kg each (the paper's bound: a larger mass at the actuator absorbs the
  catalogue's inertia effect; with 40 kg bounds a hidden 58.6 kg inertia was fitted as 37.6 kg),
  k_B 5e7-1e9 N/m and c_B 3e5-5e6 N s/m (log-uniform);
* two-chamber: mounts k_M 1e7-1e8 N/m and c_M 1e4-3e5 N s/m, chamber stiffnesses 1e7-2e8 N/m,
  area ratio 0.2-0.6, chamber lengths 0.06-0.2 m, entrained air 0-10, reservoir force 300-3000 N,
  gas spring 0-5000 N/m;
* data: load-cell noise 5-50 N rms (log-uniform), 500 Hz through the rig's sensor chain
  (``campaign.sensors``: FIR anti-alias filter, 16-bit ADC), four identification and two
  validation tests of 12-16 s, each stroke from one of four generators (``STROKE_KINDS``): the
  campaign's vehicle scenarios, random multisines, sweeps and hunting-like narrow-band motion on
  a slow curving component, scaled down where needed to a peak velocity of 140 mm/s (``MAX_VELOCITY``:
  the tuner then keeps Table 2's abscissae, on which the tables are drawn, so the data are in the
  model's class exactly; damping ordinates above 35 kN are drawn again for the same reason).
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from damper_dataset.writer import write_dataset
from damper_fmu import REPLAY, SolverOptions, simulate
from damper_fmu.integrator import DEFAULT_MAX_STEP
from damper_fmu.parameters import (FC_ABSCISSAE, FK_ABSCISSAE, FK_REFERENCE_STIFFNESS, TWOCHAMBER_FC_ABSCISSAE,
                                   defaults)
from campaign.scenarios import SCENARIOS, damper_stroke
from campaign.sensors import SensorChain

__all__ = ["random_damper", "random_stroke", "class_tests", "write_class_dataset", "STROKE_KINDS", "CLASS_MODELS",
           "NOISE_RANGE_N", "SAMPLE_RATE_HZ", "capped", "MAX_VELOCITY", "OVERSAMPLING"]

CLASS_MODELS = ("lumped", "twochamber")
STROKE_KINDS = ("campaign", "multisine", "sweep", "hunting")
NOISE_RANGE_N = (5.0, 50.0)
SAMPLE_RATE_HZ = 500.0
#: peak stroke velocity [m/s]: below 1.5 x Table 2's last rate (100 mm/s), so that the tuner keeps the
#: paper's abscissae, on which the random tables are drawn (``tuner.identification.problem.STRETCH_BEYOND``)
MAX_VELOCITY = 0.14
#: largest damping-table ordinate [N] of a draw (redrawn above): the elastic abscissae stay Table 2's too
MAX_TABLE_FORCE = 3.5e4
#: internal grid of the simulated rig: this many times the sample rate (the sensor chain's oversampling)
OVERSAMPLING = 4


def _loguniform(rng, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _damping_side(rng, rates: list[float], knee_force: float) -> list[float]:
    """Ordinates [N, >= 0] at the increasing rates [m/s] of one side: a knee at a random rate."""
    k = int(rng.integers(0, min(10, len(rates) - 1)))  # index of the knee rate
    base = knee_force / rates[k]
    forces, f, x0 = [], 0.0, 0.0
    for i, x in enumerate(rates):
        slope = base * rng.uniform(0.6, 1.6) if i <= k else base * rng.uniform(0.01, 0.3)
        f += slope * (x - x0)
        forces.append(f)
        x0 = x
    # scale the part up to the knee so that the knee force is the one drawn
    scale = knee_force / forces[k]
    return [f * scale for f in forces]


def _damping_table(rng, abscissae) -> dict[str, float]:
    neg = sorted((-x for x in abscissae if x < 0))
    pos = sorted(x for x in abscissae if x > 0)
    knee = _loguniform(rng, 3e3, 2e4)
    comp = _damping_side(rng, neg, knee)
    ext = _damping_side(rng, pos, rng.uniform(0.6, 1.6) * knee)  # extension/compression ratio
    ordinates = [-f for f in comp][::-1] + ext
    return {f"Fc_{i:02d}": v for i, v in enumerate(ordinates, start=1)}


def _elastic_table(rng) -> dict[str, float]:
    out = {}
    for sign in (-1.0, 1.0):
        xs = sorted(abs(x) for x in FK_ABSCISSAE if x * sign > 0)
        k = _loguniform(rng, 0.3, 2.5) * FK_REFERENCE_STIFFNESS
        f, x0 = 0.0, 0.0
        for x in xs:
            f += k * rng.uniform(0.8, 1.25) * (x - x0)
            i = FK_ABSCISSAE.index(sign * x) + 1
            out[f"Fk_{i:02d}"] = sign * f
            x0 = x
    return out


def random_damper(model: str, seed: int) -> dict[str, float]:
    """Parameters (SI) of a random damper of ``model``'s class (module docstring: the priors)."""
    if model not in CLASS_MODELS:
        raise ValueError(f"no class prior for model {model!r}; known: {', '.join(CLASS_MODELS)}")
    rng = np.random.default_rng([seed, CLASS_MODELS.index(model)])
    p = defaults(model)
    abscissae = FC_ABSCISSAE if model == "lumped" else TWOCHAMBER_FC_ABSCISSAE
    while True:
        table = _damping_table(rng, abscissae)
        if max(abs(f) for f in table.values()) <= MAX_TABLE_FORCE:
            break
    p.update(table)
    if model == "lumped":
        p.update(_elastic_table(rng))
        p.update({"M_C": rng.uniform(3, 20), "M_O": rng.uniform(3, 20), "M_P": rng.uniform(3, 20),
                  "k_B": _loguniform(rng, 5e7, 1e9), "c_B": _loguniform(rng, 3e5, 5e6)})
    else:
        p.update({"k_M": _loguniform(rng, 1e7, 1e8), "c_M": _loguniform(rng, 1e4, 3e5),
                  "k_R": _loguniform(rng, 1e7, 2e8), "k_C": _loguniform(rng, 1e7, 2e8),
                  "area_ratio": rng.uniform(0.2, 0.6), "L_R": rng.uniform(0.06, 0.2), "L_C": rng.uniform(0.06, 0.2),
                  "air": rng.uniform(0.0, 10.0), "f_res": _loguniform(rng, 300.0, 3000.0),
                  "k_gas": rng.uniform(0.0, 5000.0)})
    return p


def _ramp(t):
    """1 s cosine fade-in (value, derivative): strokes start from rest."""
    r = np.where(t < 1.0, 0.5 - 0.5 * np.cos(np.pi * np.minimum(t, 1.0)), 1.0)
    dr = np.where(t < 1.0, 0.5 * np.pi * np.sin(np.pi * np.minimum(t, 1.0)), 0.0)
    return r, dr


def _sines(t, amps, freqs, phases):
    w = 2 * np.pi * np.asarray(freqs)[:, None]
    arg = w * t[None, :] + np.asarray(phases)[:, None]
    a = np.asarray(amps)[:, None]
    return (a * np.sin(arg)).sum(axis=0), (a * w * np.cos(arg)).sum(axis=0)


def random_stroke(kind: str, seed: int, duration: float, fs: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(time [s], stroke [m], stroke velocity [m/s]) at ``fs`` [Hz] of one generator of ``STROKE_KINDS``.

    campaign: a yaw damper stroke of one of the paper's six manoeuvres (``campaign.scenarios``, its
    irregularity drawn from ``seed``), cut to ``duration``; multisine: 6 slow (0.1-0.8 Hz, 5-30 mm)
    and 8 fast (1.5-8 Hz, 0.5-3 mm) random-phase harmonics; sweep: a logarithmic chirp
    0.2 -> 8-12 Hz at a constant velocity amplitude of 15-120 mm/s (stroke capped at 40 mm);
    hunting: narrow-band motion (30 harmonics within +-0.4 Hz of a 2-7 Hz centre, 0.5-2.5 mm rms) on
    a slow curving component (0.05-0.2 Hz, 5-30 mm). All but the campaign fade in over 1 s.
    """
    if kind not in STROKE_KINDS:
        raise ValueError(f"unknown stroke kind {kind!r}; known: {', '.join(STROKE_KINDS)}")
    rng = np.random.default_rng([seed, STROKE_KINDS.index(kind)])
    n = int(round(duration * fs)) + 1
    t = np.arange(n) / fs
    if kind == "campaign":

        names = list(SCENARIOS)
        sc = SCENARIOS[names[int(rng.integers(len(names)))]]
        tc, x, v = damper_stroke(sc, seed=int(rng.integers(1 << 30)), fs=fs, t_end=min(duration, sc.duration_s))
        return tc, x, v
    if kind == "multisine":
        x1, v1 = _sines(t, np.full(6, rng.uniform(5e-3, 30e-3) / math.sqrt(6)), rng.uniform(0.1, 0.8, 6),
                        rng.uniform(0, 2 * np.pi, 6))
        x2, v2 = _sines(t, np.full(8, rng.uniform(0.5e-3, 3e-3) / math.sqrt(8)), rng.uniform(1.5, 8.0, 8),
                        rng.uniform(0, 2 * np.pi, 8))
        x, v = x1 + x2, v1 + v2
    elif kind == "sweep":
        f0, f1, vamp = 0.2, rng.uniform(8.0, 12.0), rng.uniform(0.015, 0.12)
        rate = math.log(f1 / f0) / duration
        f = f0 * np.exp(rate * t)
        phase = 2 * np.pi * f0 * (np.exp(rate * t) - 1.0) / rate
        amp = np.minimum(vamp / (2 * np.pi * f), 0.04)
        x = amp * np.sin(phase)
        damp = np.where(vamp / (2 * np.pi * f) < 0.04, -amp * rate, 0.0)  # d(amp)/dt
        v = damp * np.sin(phase) + amp * 2 * np.pi * f * np.cos(phase)
    else:  # hunting
        fc = rng.uniform(2.0, 7.0)
        x1, v1 = _sines(t, np.full(30, rng.uniform(0.5e-3, 2.5e-3) * math.sqrt(2 / 30)),
                        rng.uniform(fc - 0.4, fc + 0.4, 30), rng.uniform(0, 2 * np.pi, 30))
        x2, v2 = _sines(t, [rng.uniform(5e-3, 30e-3)], [rng.uniform(0.05, 0.2)], [rng.uniform(0, 2 * np.pi)])
        x, v = x1 + x2, v1 + v2
    r, dr = _ramp(t)
    return t, x * r, v * r + x * dr


def capped(x, v, vmax: float):
    """Stroke and velocity scaled down so that |velocity| <= vmax [m/s] (unchanged when it is)."""
    peak = float(np.max(np.abs(v)))
    k = min(1.0, vmax / peak) if peak > 0 else 1.0
    return x * k, v * k


def class_tests(model: str, seed: int, *, durations=None, noise_n: float | None = None,
                kinds=None, sample_rate: float = SAMPLE_RATE_HZ, sensors: dict | None = None,
                hidden: dict | None = None) -> tuple[list[dict], dict]:
    """(tests for ``damper_dataset.writer.write_dataset``, truth) of a random damper of ``model``'s class.

    Six tests (four identification, two validation) of 12-16 s unless ``durations`` gives them
    (the first two-thirds identification); strokes of random ``kinds`` (default: drawn from
    ``STROKE_KINDS``); the force simulated at ``OVERSAMPLING`` x ``sample_rate`` with the model's
    reference integrator, then through the rig's sensor chain (noise ``noise_n`` [N rms], default
    drawn log-uniform in ``NOISE_RANGE_N``); ``sensors``: other ``campaign.sensors.SensorChain`` settings
    (default: the rig's stroke channel, 2 um noise and a 16-bit ADC over +-0.1 m); ``hidden``: effect or form
    parameters of the model set on the random damper (SI, e.g. ``{"free_play": 0.35e-3}``: a blind test of the
    diagnosis; the damper drawn is the same with or without them). ``truth``: {"parameters", "noise_n",
    "kinds", ...}.
    """
    rng = np.random.default_rng([seed, 7919, CLASS_MODELS.index(model)])
    params = random_damper(model, seed)
    unknown = sorted(set(hidden or {}) - set(params))
    if unknown:
        raise ValueError(f"hidden: the {model} model has no parameter {', '.join(unknown)}")
    params.update(hidden or {})
    if durations is None:
        durations = [float(rng.uniform(12.0, 16.0)) for _ in range(6)]
    n_id = max(1, (2 * len(durations)) // 3)
    if kinds is None:
        kinds = [STROKE_KINDS[int(rng.integers(len(STROKE_KINDS)))] for _ in durations]
    if noise_n is None:
        noise_n = _loguniform(rng, *NOISE_RANGE_N)
    fs_int = OVERSAMPLING * sample_rate
    tests = []
    for i, (dur, kind) in enumerate(zip(durations, kinds)):
        t, x, v = random_stroke(kind, seed * 100 + i, dur, fs_int)
        x, v = capped(x, v, MAX_VELOCITY)
        n = (t.size - 1) // OVERSAMPLING * OVERSAMPLING + 1
        t, x, v = t[:n], x[:n], v[:n]
        f = simulate(model, t, x, v, params=params,
                     solver=SolverOptions(max_step=min(DEFAULT_MAX_STEP, 1.0 / fs_int), input_mode=REPLAY))
        peak = float(np.abs(f).max())
        chain = SensorChain(**{"force_noise": noise_n, "oversampling": OVERSAMPLING,
                               "force_range": max(5e3, 2.0 ** math.ceil(math.log2(1.25 * peak))), **(sensors or {})})
        s_out, f_out, _ = chain.acquire(x, f, np.full(n, 20.0), seed=seed * 100 + i)
        role = "identification" if i < n_id else "validation"
        tests.append({"name": f"{role[:3]}{i + 1}_{kind}", "role": role,
                      "scenario": f"{kind} stroke, force of a random {model} damper (seed {seed})",
                      "frame": pd.DataFrame({"time": t[::OVERSAMPLING], "stroke": s_out, "force": f_out})})
    truth = {"model": model, "seed": int(seed), "parameters": params, "noise_n": float(noise_n),
             "kinds": list(kinds), "durations_s": [float(d) for d in durations], "sample_rate_hz": sample_rate}
    return tests, truth


def write_class_dataset(out_dir, model: str, seed: int, **kwargs):
    """Write :func:`class_tests` as a dataset folder (the truth in the manifest's generator); return its Path."""
    tests, truth = class_tests(model, seed, **kwargs)
    return write_dataset(out_dir, tests, description=f"a random {model} damper of the model's class (seed {seed})",
                         generator={"command": "campaign.damper_class.write_class_dataset", **truth})
