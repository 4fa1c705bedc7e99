"""Rig tests of a lumped damper with known parameters, for the parameter-interval tests
(tests/test_intervals.py) and benchmarks/interval_coverage.py. SI units.

The truth is the paper's Table 2 damper with the masses of the held-out damper the identifiability
question came from (M_P 12, M_O 9, M_C 14 kg). The force is the model's own at 1 kHz plus white
load-cell noise, integrated far more finely than the identification does (``TRUTH_STEPS['fine']``:
the integrator's default tolerance, 1e-4 of the force scale = 2.5 N here, moved M_P by 0.2 kg on
noise-free data), or as the identification engine does (``TRUTH_STEPS['identification']``). The fit
keeps the truth's table abscissae and polishes from the truth (the local optimum nearest to it, which is
what a local interval describes), so no Firefly search is needed.

Stroke kinds (``stroke``):
  'multisine' campaign.synthetic.random_stroke: 0.1-0.8 Hz (``slow_amp``) plus 1.5-8 Hz (1 mm);
  'slow'      the slow part alone: the accelerations are a few tenths of m/s^2;
  'fast'      the multisine plus 12-20 Hz harmonics of ``FAST_AMP`` (accelerations of several m/s^2).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.interpolate import CubicSpline

from campaign.synthetic import random_stroke
from damper_fmu import SolverOptions, defaults, simulate
from tuner.data.reading import RigTest
from tuner.identification.engine import (IDENTIFICATION_STEP, IDENTIFICATION_TOLERANCE, Engine, fastest_engine,
                                         simulate_signals)
from tuner.identification.intervals import parameter_intervals, reached_ranges
from tuner.identification.polish import polish
from tuner.identification.problem import DataSettings, Problem

FS = 1000.0
#: the four 12-20 Hz harmonics of the 'fast' stroke have amplitudes of FAST_AMP / 2 [m] each
FAST_AMP = 1.0e-3
KINDS = ("multisine", "slow", "fast")
#: the truth's integration: 'fine' (internal steps of at most 0.1 ms, local error 1e-7 of the force scale:
#: the model itself) or 'identification' (the identification engine's fixed 1 ms steps: what the fit can
#: represent exactly, which separates the intervals' statistics from the identification grid's own error)
TRUTH_STEPS = {"fine": SolverOptions(max_step=1e-4, tolerance=1e-7),
               "identification": SolverOptions(max_step=IDENTIFICATION_STEP, tolerance=IDENTIFICATION_TOLERANCE)}


def truth() -> dict:
    """The known lumped damper (SI)."""
    p = defaults("lumped")
    p.update({"M_P": 12.0, "M_O": 9.0, "M_C": 14.0})
    return p


def stroke(kind: str, seed: int, duration: float, slow_amp: float = 0.015):
    """(time [s], stroke [m], stroke velocity [m/s]) of a stroke ``kind`` (module docstring)."""
    if kind not in KINDS:
        raise ValueError(f"unknown stroke kind {kind!r}, expected one of {KINDS}")
    t, x, v = random_stroke(seed, duration, FS, slow_amp=slow_amp, fast_amp=0.0 if kind == "slow" else 1.0e-3)
    if kind == "fast":
        rng = np.random.default_rng(seed + 5000)
        ramp = np.where(t < 1.0, 0.5 - 0.5 * np.cos(np.pi * np.minimum(t, 1.0)), 1.0)
        dramp = np.where(t < 1.0, 0.5 * np.pi * np.sin(np.pi * t), 0.0)
        for f, ph in zip(rng.uniform(12.0, 20.0, 4), rng.uniform(0, 2 * np.pi, 4)):
            w, a = 2 * np.pi * f, FAST_AMP / 2.0
            x = x + a * np.sin(w * t + ph) * ramp
            v = v + a * (w * np.cos(w * t + ph) * ramp + np.sin(w * t + ph) * dramp)
    return t, x, v


def rig_tests(params: dict, kind: str, seed: int, durations=(10.0,), noise_n: float = 25.0,
              slow_amp: float = 0.015, truth_steps: str = "fine", measured_velocity: bool = False) -> list[RigTest]:
    """Identification tests: the model's force (integrated as ``TRUTH_STEPS[truth_steps]``) under strokes
    of ``kind`` plus ``noise_n`` rms [N]; with ``measured_velocity`` the exact stroke velocity as the rig's
    velocity channel (else the tuner differentiates the stroke)."""
    rng = np.random.default_rng(seed + 10_000)
    tests = []
    for i, duration in enumerate(durations):
        t, x, v = stroke(kind, 100 * seed + i, duration, slow_amp)
        f = (simulate("lumped", t, x, v, params=params, solver=TRUTH_STEPS[truth_steps])
             + rng.normal(0.0, noise_n, t.size))
        tests.append(RigTest(name=f"{kind}{i + 1}", role="identification", scenario=f"{kind} stroke", time=t,
                             stroke=x, force=f, sample_rate=FS, velocity=v if measured_velocity else None))
    return tests


def fitted(params: dict, tests: list[RigTest], *, jacobians: int = 20, fit_rate_hz: float = 200.0,
           noise_free: list[RigTest] | None = None):
    """(problem, parametrization, fitted values, ModelIntervals, refinement: a PolishResult or None) of the lumped model
    refined from ``params`` on ``tests`` at ``fit_rate_hz`` (jacobians: the refinement's budget; 0: the
    intervals at ``params``). noise_free: the same tests without noise; then the fit sees the
    identification's own simulated force at ``params`` plus the tests' noise as resampled to the fit rate
    (data the identification represents exactly: what is left is the intervals' statistics)."""
    axes = {k: tuple(params[f"{k}_{a}{i:02d}"] for i in range(1, n + 1)) for k, a, n in (("Fc", "v", 14), ("Fk", "x", 10))}
    settings = DataSettings(fit_rate_hz=fit_rate_hz, damping_abscissae_m_s=axes["Fc"], elastic_abscissae_m=axes["Fk"])
    problem = Problem.build(tests, [], settings)
    par = problem.parametrization("lumped")
    start = par.to_params(par.from_params(params))
    if noise_free is not None:
        clean = Problem.build(noise_free, [], settings).sig_id
        problem.sig_id = [replace(s, force=simulate_signals("lumped", start, s, engine=fastest_engine()) + s.force - c.force)
                          for s, c in zip(problem.sig_id, clean)]
    with Engine("lumped", problem.sig_id, engine=fastest_engine(), workers=0) as eng:
        refined = None
        est = start
        if jacobians:
            refined = polish(eng, par, par.from_params(start), max_jacobians=jacobians, log=lambda m: None)
            est = par.to_params(refined.z)
        iv = parameter_intervals(eng, par, est, reached=reached_ranges("lumped", est, problem.sig_id))
    return problem, par, est, iv, refined


def run_on_truth(params: dict, candidate, seed: int, noise_n: float = 25.0) -> RigTest:
    """The rig test a designed ``candidate`` (``tuner.identification.rig_test_design.Candidate``) gives on the damper
    ``params``: the model's force, finely integrated, under its stroke, plus ``noise_n`` rms [N] of white noise."""
    c = candidate
    # the stroke's own velocity (a cubic spline's derivative: error ~(w h)^4; central differences lose
    # (w h)^2 / 6 = 1.7e-3 of a 16 Hz sine at 1 kHz, a damping force error that biased the masses)
    v = CubicSpline(c.time, c.stroke)(c.time, 1)
    force = simulate("lumped", c.time, c.stroke, v, params=params, solver=TRUTH_STEPS["fine"])
    force = force + np.random.default_rng(seed + 20_000).normal(0.0, noise_n, c.time.size)
    return RigTest(name=c.name, role="identification", scenario=c.description, time=c.time, stroke=c.stroke,
                   force=force, sample_rate=(c.time.size - 1) / (c.time[-1] - c.time[0]))
