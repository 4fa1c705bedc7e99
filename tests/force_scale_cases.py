"""Test support: a damper scaled to another force (issue 63) and every FMU run on it through fmpy.

Scaling every parameter whose SI unit carries a kilogram by s (forces, stiffnesses, dampings, masses, heat
capacity and conductance) and nothing else (lengths, times, ratios, table abscissae) gives the same damper s
times stronger: every equation of the models is then s times the original's, with the same time scales, so
under the same stroke the force is s times the original's (a physics identity, whatever the model). Its rig
tests are the original's with the force times s (``scaled_tests``: the bundled data's damper scaled, issue 74).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from damper_fmu import defaults, make_model
from damper_fmu.parameters import EFFECT_MODELS, MODEL_PARAMETERS, UNIT_DEFINITIONS

KINDS = ("lumped", "maxwell", "maxwell_table", "twochamber")
#: peak forces [N] (the model's force scale: the largest damping-table ordinate, c x 0.1 m/s for Maxwell); 1 MN: the
#: two-chamber gas spring 40 times the preset's (its range ended at 2e4 N/m, about 290 kN, until issue 74)
PEAKS_N = (1.0, 1e3, 1e5, 1e6)
#: the effect elements every effect model runs with here: a seal friction of 1 % of the preset's force scale
#: (the two-chamber stage's steepest solve, at each reversal) and the thermal drift on its internal balance
#: (the heat capacity and conductance scale with the damper), a small heat capacity so that the damping falls
#: by about 1 % over a run
EFFECTS = {"friction_force": 250.0, "thermal_beta": 0.01, "thermal_capacity": 400.0}
#: the issue's damper: the two-chamber preset with its damping table 1000 x smaller (25 N) and a mount at its
#: stiffest bound, as a fit on an 18 N damper leaves it (a mount that stiff is not seen in the data)
SMALL_STIFF_MOUNT = {**{p.name: 1e-3 * p.default for p in MODEL_PARAMETERS["twochamber"]
                        if p.name.startswith("Fc_") and p.tunable}, "k_M": 1e11}


def base_parameters(kind: str) -> dict[str, float]:
    """The preset of ``kind`` with ``EFFECTS`` on where the model has effect elements."""
    return {**defaults(kind), **(EFFECTS if kind in EFFECT_MODELS else {})}


def scaled(kind: str, params: dict[str, float], factor: float) -> dict[str, float]:
    """``params`` (a full set of ``kind``) with every parameter whose unit carries a kilogram times ``factor``."""
    units = {p.name: p.unit for p in MODEL_PARAMETERS[kind]}
    return {name: value * factor if UNIT_DEFINITIONS[units[name]].get("kg") == 1 else value
            for name, value in params.items()}


def scaled_tests(tests: list, factor: float) -> list:
    """The rig tests ``tests`` (``tuner.data.reading.RigTest``) of a damper scaled consistently by ``factor``: the same
    strokes, the force [N] times ``factor`` (the measured force and its noise alike)."""
    return [replace(t, force=np.asarray(t.force, dtype=float) * factor) for t in tests]


def factor_for_peak(kind: str, params: dict[str, float], peak_n: float) -> float:
    """The factor that gives ``params`` the force scale ``peak_n`` [N]."""
    return peak_n / make_model(kind, params).force_scale()


def sine_signals(kind: str, duration: float = 0.4, freq: float = 5.0, amp: float = 3e-3, offset: float = 0.0,
                 h: float = 1e-3) -> np.ndarray:
    """fmpy input record of the FMU of ``kind``: time [s], stroke [m] (a sine of ``amp`` [m] at ``freq`` [Hz]
    about ``offset`` [m]) and its velocity [m/s] (and a 20 degC oil temperature where the FMU has that input),
    every ``h`` [s] for ``duration`` [s] (5 Hz, 3 mm: up to 94 mm/s, the damping table's peak)."""
    t = np.arange(0.0, duration + 0.5 * h, h)
    w = 2 * np.pi * freq
    columns = [t, offset + amp * np.sin(w * t), amp * w * np.cos(w * t)]
    names = ["time", "stroke", "stroke_velocity"]
    if kind in EFFECT_MODELS:
        columns, names = [*columns, np.full(t.size, 20.0)], [*names, "oil_temperature"]
    return np.rec.fromarrays(columns, names=names)


def run_fmu(path, kind: str, signals: np.ndarray, params: dict[str, float], settings: dict | None = None) -> np.ndarray:
    """The force [N] of the FMU of ``kind`` at ``path`` (with the preset as its start values) through
    ``fmpy.simulate_fmu`` with ``params`` and the FMU ``settings`` (co-simulation, the inputs at the start of
    each step, one step per sample). An error status raises (fmpy; a pythonfmu FMU's refused step, fmi2Discard
    with the simulation terminated, ends fmpy's run early: RuntimeError here)."""
    from fmpy import simulate_fmu

    preset = defaults(kind)
    start = {**{k: v for k, v in params.items() if v != preset[k]}, **(settings or {})}
    h = float(signals["time"][1] - signals["time"][0])
    res = simulate_fmu(str(path), stop_time=float(signals["time"][-1]), step_size=h, output_interval=h,
                       input=signals, output=["force"], start_values=start)
    if res.size != signals.size:
        raise RuntimeError(f"the FMU stopped at t = {res['time'][-1]:g} s")
    return np.asarray(res["force"], dtype=float)
