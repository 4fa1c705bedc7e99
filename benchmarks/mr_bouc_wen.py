"""The lab's own model of the real MR damper (Spencer's modified Bouc-Wen) on its sine tests, compared as
our validation compares our models.

The lab that measured the damper (``../shared/realdata/README.md``) fitted Spencer's modified Bouc-Wen
model (Spencer, Dyke, Sain, Carlson, J. Eng. Mech. 123(3), 1997) to its sine tests at five currents at
once. In the lab's units - stroke x [mm], its rate x' [mm/s], internal states y [mm] and z [mm], force F
[N], time [s] - with the current i [A]::

    y' = (alpha z + k0 (x - y) + c0 x') / (c0 + c1)
    z' = -gamma |x' - y'| |z|^(n-1) z - beta (x' - y') |z|^n + A (x' - y')
    F  = c1 y' + k1 (x - x0)

    alpha = p4 i^2 + p5 i + p6 [N/mm]   beta = gamma = p7 exp(p8 i) [1/mm^2]
    c0 = p9 i + p10 [N s/mm]            c1 = p11 i + p12 [N s/mm]      A = 300, n = 2

k0 = p1 [N/mm], k1 = p2 [N/mm], x0 = p3 [mm]. Signs as the files write them: the force rises with the
stroke rate (F ~ c1 y' at speed); the reader keeps the files' signs (ours: + extension, + tension) and the
output states the correlation of the model's force with the measured one (positive: the conventions agree).
y starts at the stroke, z at 0; the first 0.5 s do not count.

Each test is run three ways (the ``comparison`` and ``rate`` of every row):

* ``ours`` / ``file velocity``: as our validation (``tuner.identification.validation.validation_run``)
  compares our models: the test read with the project's reader and its mapping file
  (``docs/real-data/mr-sine*.toml``: the lab's causal moving average declared per file as ``prefilter``),
  prepared as our fits prepare it (``tuner.identification.problem.prepared_signals``: resampled to the fit
  rate, the declared filter undone on stroke and rate), the model driven on the simulation grid, its force
  passed through the declared filter and the anti-aliasing low-pass (``Signals.band_limit``, the one place
  the project makes a simulated force comparable), the same counted samples (warm-up 0.5 s and the
  filter's settling at both ends). The rate is the file's own velocity column (the lab's finite difference).
* ``ours`` / ``reader derivative``: the same with the rate our reader makes (the stroke differentiated).
* ``as exported`` / ``file velocity``: the lab's own setting: the smoothed stroke and velocity columns in,
  at the file's samples, the force compared with no filter (how the lab fitted it); the first 0.5 s out.

RMSE [N] and AME [% of the test's peak force] are the project's (``tuner.metrics.error_metrics``;
``tuner.identification.fit.quality_gate`` for the AME as % of peak); pooled RMSE over several tests is
``tuner.metrics.pooled_mse`` (sample-weighted). The ODE is integrated with scipy's ``solve_ivp`` (LSODA,
rtol 1e-8 by default) with x and x' interpolated linearly between the grid's samples, the step at most one
sample interval.

    python benchmarks/mr_bouc_wen.py [--realdata ../shared/realdata] [--currents 0.25,0.5,0.75]
        [--ours 'results/mr-{tag}'] [--out bouc_wen.json]

``--ours`` (``{tag}``: 0x25A, 0x5A, 0x75A) names our fits' output folders: their settings (fit rate,
warm-up) and roles are used, and their held-out figures are printed beside the lab's model.
"""
from __future__ import annotations

import argparse
import bisect
import math
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tuner import strict_json  # noqa: E402
from tuner.data.read_options import ReadOptions, read_column_mapping  # noqa: E402
from tuner.data.reading import load_files  # noqa: E402
from tuner.identification.fit import quality_gate  # noqa: E402
from tuner.identification.problem import DataSettings, prepared_signals, split_data_settings  # noqa: E402
from tuner.metrics import error_metrics, pooled_mse  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
#: the lab's fitted values (README of ../shared/realdata, from the lab's ``parametros.mat``)
LAB_P = {"p1": 1.50133e-4, "p2": 1.23880, "p3": 2.30914e-3, "p4": -38.1520, "p5": 41.5084, "p6": 15.2211,
         "p7": 1.89408, "p8": -3.65611, "p9": 7.62596, "p10": 0.924911, "p11": 78.3367, "p12": 9.86713}
LAB_A, LAB_N = 300.0, 2.0
#: the test frequencies [Hz] our fits hold out (docs/real-data.md: validation on the 0.25, 1 and 5 Hz tests)
HELD_OUT_HZ = (0.25, 1.0, 5.0)
WARMUP_S = 0.5
COMPARISONS = {"ours": "the declared lab filter undone on stroke and rate, the model's force passed through "
                       "it and the fit-rate low-pass (Signals.band_limit), our validation's samples",
               "as exported": "the smoothed stroke and rate as the file holds them, the force compared with no "
                              "filter (the lab's own fitting setting), the file's samples after 0.5 s"}


@dataclass(frozen=True)
class BoucWen:
    """Spencer's modified Bouc-Wen model at one current, lab units: k0, k1 [N/mm], x0 [mm], alpha [N/mm],
    beta, gamma [1/mm^2], c0, c1 [N s/mm], A [-], n [-]."""

    k0: float
    k1: float
    x0: float
    alpha: float
    beta: float
    gamma: float
    c0: float
    c1: float
    A: float = LAB_A
    n: float = LAB_N

    @classmethod
    def at_current(cls, current_a: float, p: dict | None = None) -> "BoucWen":
        """The lab's model at the coil current ``current_a`` [A] (``p``: p1..p12, default the lab's fit)."""
        p, i = p or LAB_P, float(current_a)
        return cls(k0=p["p1"], k1=p["p2"], x0=p["p3"], alpha=p["p4"] * i * i + p["p5"] * i + p["p6"],
                   beta=p["p7"] * math.exp(p["p8"] * i), gamma=p["p7"] * math.exp(p["p8"] * i),
                   c0=p["p9"] * i + p["p10"], c1=p["p11"] * i + p["p12"])

    def rates(self, x: float, v: float, y: float, z: float) -> tuple[float, float]:
        """(y' [mm/s], z' [mm/s]) at stroke x [mm], stroke rate v [mm/s] and states y [mm], z [mm]."""
        yd = (self.alpha * z + self.k0 * (x - y) + self.c0 * v) / (self.c0 + self.c1)
        u = v - yd
        az = abs(z)
        zd = -self.gamma * abs(u) * az ** (self.n - 1.0) * z - self.beta * u * az ** self.n + self.A * u
        return yd, zd

    def force(self, x, v, y, z):
        """Force [N] (arrays or floats): F = c1 y' + k1 (x - x0), y' from :meth:`rates`' first line."""
        yd = (self.alpha * z + self.k0 * (x - y) + self.c0 * v) / (self.c0 + self.c1)
        return self.c1 * yd + self.k1 * (x - self.x0)


def simulate(model: BoucWen, t, x_mm, v_mm_s, rtol: float = 1e-8, method: str = "LSODA") -> dict:
    """Run ``model`` driven by the stroke ``x_mm`` [mm] and its rate ``v_mm_s`` [mm/s] sampled at ``t`` [s]
    (both interpolated linearly between the samples), y starting at x, z at 0. Returns {'force' [N],
    'y' [mm], 'z' [mm]} at ``t``. solve_ivp with ``method`` (LSODA or Radau), ``rtol``, atol 1e-9 rtol-scaled
    per state [mm], the step at most one sample interval (the input's kinks are not stepped over)."""
    t = np.asarray(t, dtype=float)
    x, v = np.asarray(x_mm, dtype=float), np.asarray(v_mm_s, dtype=float)
    tl, xl, vl = t.tolist(), x.tolist(), v.tolist()
    last = len(tl) - 2

    def rhs(tt, s):
        k = min(max(bisect.bisect_right(tl, tt) - 1, 0), last)
        w = (tt - tl[k]) / (tl[k + 1] - tl[k])
        return model.rates(xl[k] + w * (xl[k + 1] - xl[k]), vl[k] + w * (vl[k + 1] - vl[k]), s[0], s[1])

    scale = max(float(np.max(np.abs(x))), 1.0)
    sol = solve_ivp(rhs, (t[0], t[-1]), [x[0], 0.0], method=method, t_eval=t, rtol=rtol,
                    atol=[rtol * scale, rtol * scale], max_step=float(np.max(np.diff(t))))
    if not sol.success:
        raise RuntimeError(f"Bouc-Wen integration failed: {sol.message}")
    y, z = sol.y
    return {"force": model.force(x, v, y, z), "y": y, "z": z}


def current_tag(current_a: float) -> str:
    """The files' current tag: 0.25 -> '0x25A', 0.5 -> '0x5A'."""
    return f"{current_a:g}".replace(".", "x") + "A"


def sine_hz(name: str) -> float:
    """The sine frequency [Hz] of a file name '<amplitude>mm<frequency>Hz<current>A' ('x' for the point)."""
    m = re.match(r"^[0-9x]+mm([0-9x]+)Hz", name)
    if not m:
        raise ValueError(f"{name!r}: not a '<amplitude>mm<frequency>Hz...' sine test name")
    return float(m.group(1).replace("x", "."))


def read_current(folder: Path, mapping: Path, file_velocity: bool) -> list:
    """The sine tests of ``folder`` read as ``python -m tuner`` reads them with ``--columns mapping``
    (``tuner.cli.options.column_options``: the defaults, the mapping's [columns], then the file's own entry),
    in SI (stroke [m], velocity [m/s], force [N]); ``file_velocity``: the file's velocity column (3) is the
    rate instead of the differentiated stroke."""
    common, per_file = read_column_mapping(mapping)
    every = ReadOptions().merged(common)
    tests = []
    for p in sorted(folder.glob("*.txt")):
        if p.name not in per_file:
            raise ValueError(f"{mapping}: no entry for {p.name} (its lab filter would go undeclared)")
        opts = every.merged(per_file[p.name])
        tests += load_files([p], "validation", opts.merged(velocity_col=3) if file_velocity else opts)
    return tests


def _figures(name: str, measured, simulated) -> dict:
    """The project's error metrics of one test (forces [N]), its AME as % of peak (``quality_gate``'s) and
    the correlation of the simulated with the measured force [-]."""
    m = error_metrics(measured, simulated).to_dict()
    gate = quality_gate({name: {"role": "validation", "models": {"bw": m}}}, ["bw"])["bw"]
    return {**m, "ame_pct_of_peak": gate["worst_ame_pct_of_peak"],
            "correlation": float(np.corrcoef(measured, simulated)[0, 1])}


def run_ours(model: BoucWen, tests: list, settings: DataSettings, rtol: float) -> dict:
    """Per test name: figures of the model compared as our validation compares ours (module docstring):
    driven on the signals' simulation grid (stroke [m] and rate [m/s] -> mm), force band-limited by
    ``Signals.band_limit`` (the declared prefilter, then the fit-rate low-pass), counted samples ``mask``."""
    out = {}
    for s in prepared_signals(tests, settings)[1]:
        t, x, v = s.fine[:3] if s.oversample > 1 else (s.time, s.stroke, s.stroke_velocity)
        sim = s.band_limit(simulate(model, t, 1e3 * x, 1e3 * v, rtol)["force"])
        out[s.name] = {**_figures(s.name, s.force[s.mask], sim[s.mask]),
                       "prefilter": s.prefilter.spec if s.prefilter else None, "oversample": s.oversample}
    return out


def run_as_exported(model: BoucWen, tests: list, rtol: float) -> dict:
    """Per test name: figures of the model driven by the file's own (smoothed) stroke and velocity at its
    samples, the force compared with no filter, the samples after the first ``WARMUP_S`` s."""
    out = {}
    for t in tests:
        sim = simulate(model, t.time, 1e3 * t.stroke, 1e3 * t.velocity, rtol)["force"]
        mask = t.time - t.time[0] >= WARMUP_S
        out[t.name] = {**_figures(t.name, t.force[mask], sim[mask]), "prefilter": None, "oversample": 1}
    return out
