"""Residual analysis for the diagnosis: evidence numbers per catalogue effect (pure computation; the
figures that show the residual are drawn by ``tuner.results.diagnosis_figures``, into the files named here,
``figure_files``, which the diagnosis's record lists).

``evidence`` gathers, for the base model's residual r = measured - simulated force [N] on every test
(``tuner.diagnosis.residual_tests.TestResidual``): each catalogue effect's signature fitted alone and all of
them at once (``tuner.diagnosis.residual_signatures``), where on the restoring-force plane the residual lives
(``tuner.diagnosis.residual_map``), and general numbers per test and pooled (``residual_summary``: rms, band
shares of the residual power, its share linear in the stroke; where in the F-v loop it lies).
Stroke [m] + in extension, force [N] + in tension, time [s], temperature [degC].
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy import signal

from damper_fmu.effect_catalogue import ALL_EFFECTS

from tuner.diagnosis.residual_map import identification_only, map_summary
from tuner.diagnosis.residual_signatures import (EFFECTS, effect_evidence, evidence_sentence, joint_screen,
                                                 knee_velocity)
from tuner.diagnosis.residual_tests import PreparedTest, TestResidual, pooled_samples

__all__ = ["evidence", "residual_summary", "spectra", "true_runs", "figure_files", "FIGURE_TOPICS", "BANDS_HZ"]

BANDS_HZ = {"<1 Hz": (0.0, 1.0), "1-5 Hz": (1.0, 5.0), "5-20 Hz": (5.0, 20.0), ">20 Hz": (20.0, np.inf)}
#: the figures of a base model's residual, one file each (``figure_files``; drawn by
#: ``tuner.results.diagnosis_figures``): in time, against velocity and stroke, around velocity reversals,
#: spectra, drift against time and temperature, the restoring-force map (``residual_map``)
FIGURE_TOPICS = ("time", "loops", "reversals", "spectra", "drift", "map")


def figure_files(folder: str | Path, prefix: str = "diag") -> list[str]:
    """The residual figures' files in ``folder`` (``<folder>/<prefix>_residual_<topic>.png``, one per
    ``FIGURE_TOPICS``): the names the diagnosis's record lists and the figures are drawn into."""
    return [str(Path(folder) / f"{prefix}_residual_{topic}.png") for topic in FIGURE_TOPICS]


def true_runs(b):
    """(start, stop) index pairs of the True runs of a boolean array."""
    d = np.diff(np.concatenate([[0], b.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def spectra(p):
    """Welch PSDs [N^2/Hz] of residual and measured force on the longest usable run (4 s Hann
    segments, no detrending, so a mean offset counts below 1 Hz): (f [Hz], P_r, P_F) or None."""
    a, b = max(true_runs(p.use), key=lambda ab: ab[1] - ab[0])
    if b - a < 16:
        return None
    kw = dict(fs=p.fs, nperseg=min(b - a, int(round(4 * p.fs))), detrend=False)
    return (*signal.welch(p.r[a:b], **kw), signal.welch(p.t.measured[a:b], **kw)[1])


def _linear_share(p):
    """(f [Hz], P_r, coherence of residual and stroke) on the longest usable run, or None. The
    coherence is the share of residual power at f that some linear time-invariant filter of the
    stroke explains: a missing linear branch (spring, Maxwell element, delay) shows near 1, a
    nonlinear or time-varying error low."""
    a, b = max(true_runs(p.use), key=lambda ab: ab[1] - ab[0])
    n = min(b - a, int(round(4 * p.fs)))
    if b - a < 4 * n // 2 or n < 16:  # coherence needs several segments
        n = (b - a) // 4
    if n < 16:
        return None
    kw = dict(fs=p.fs, nperseg=n)
    f, pr = signal.welch(p.r[a:b] - p.r[a:b].mean(), **kw)
    return f, pr, signal.coherence(p.r[a:b], p.t.stroke[a:b], **kw)[1]


def _where_in_loop(ps, knee: float) -> dict:
    """Share of residual power [0-1] at low speed (|v| < knee: reversals and the bleed region) and
    beyond the knee, each split by the sign of v (extension/compression), and their shares of time."""
    v, r = pooled_samples(ps, lambda p: p.t.velocity), pooled_samples(ps, lambda p: p.r)
    tot = float(np.sum(r ** 2)) or 1.0
    out = {}
    for name, sel in (("below_knee_extension", (np.abs(v) < knee) & (v >= 0)),
                      ("below_knee_compression", (np.abs(v) < knee) & (v < 0)),
                      ("beyond_knee_extension", (np.abs(v) >= knee) & (v >= 0)),
                      ("beyond_knee_compression", (np.abs(v) >= knee) & (v < 0))):
        out[name] = {"power_share": float(np.sum(r[sel] ** 2) / tot), "time_share": float(sel.mean())}
    return out


def residual_summary(ps):
    """rms and mean residual [N], % of force rms, band shares of residual power and residual / force
    power per band (band powers of several tests weighted by their sample counts), and the share
    of residual power linear in the stroke (pooled and per band; see ``_linear_share``)."""
    r, m = pooled_samples(ps, lambda p: p.r), pooled_samples(ps, lambda p: p.t.measured)
    d = {"samples": int(r.size), "rms_residual": float(np.sqrt(np.mean(r ** 2))),
         "rms_measured": float(np.sqrt(np.mean(m ** 2))), "mean_residual": float(r.mean())}
    d["residual_pct"] = 100 * d["rms_residual"] / d["rms_measured"] if d["rms_measured"] > 0 else None
    pw = np.zeros((2, len(BANDS_HZ)))
    for p, s in ((p, spectra(p)) for p in ps):
        if s is not None:
            pw += p.use.sum() * np.array([[P[(s[0] >= lo) & (s[0] < hi)].sum() * s[0][1]
                                           for lo, hi in BANDS_HZ.values()] for P in s[1:]])
    if pw[0].sum() > 0:
        d["band_fraction"] = dict(zip(BANDS_HZ, (pw[0] / pw[0].sum()).tolist()))
        d["band_residual_to_force_power"] = {k: float(a / b) if b > 0 else None
                                             for k, a, b in zip(BANDS_HZ, *pw)}
    lin = np.zeros((2, len(BANDS_HZ)))  # coherent and total residual power per band
    for p, c in ((p, _linear_share(p)) for p in ps):
        if c is not None:
            f, pr, coh = c
            for j, (lo, hi) in enumerate(BANDS_HZ.values()):
                sel = (f >= lo) & (f < hi)
                lin[:, j] += p.use.sum() * np.array([np.sum(coh[sel] * pr[sel]), np.sum(pr[sel])])
    if lin[1].sum() > 0:
        d["linear_share"] = float(lin[0].sum() / lin[1].sum())
        d["band_linear_share"] = {k: float(a / b) if b > 0 else None for k, a, b in zip(BANDS_HZ, *lin)}
    return d


def _clean(v):
    """JSON-friendly value: finite float, int, str, None."""
    if v is None or isinstance(v, (str, int)):
        return v
    return float(v) if np.isfinite(v) else None


def evidence(tests: list[TestResidual], noise_n: float | None = None) -> dict:
    """Residual evidence for every effect of the catalogue (see module docstring).

    ``noise_n``: measurement noise [N] in the compared band, the joint screen's threshold
    (None: 5 % of the residual's rms).

    Returns {"effects": {name: {"quantity", "unit", "value" [unit], "r2" (0-1: share of residual
    power explained by that regressor), "sentence", extra numbers (SI), "per_test": {test: same
    numbers}}}, "ranking_by_r2": [names], "knee_velocity" [m/s], "general": {"per_test": {test:
    {role, rms_residual [N], residual_pct [%], band_fraction, linear_share, ...}}, "pooled": {...,
    "loop": where in the F-v loop the residual power lies}}, "joint_screen": ``joint_screen``,
    "residual_map": where on the restoring-force plane the identification tests' residual lives (``map_summary``;
    None without an identification test)}.
    time_delay delay and valve_lag tau [s] > 0 when the measured force lags the simulated one;
    thermal beta [1/K] > 0 and gain changes < 0 when the damping falls as the oil heats."""
    if not tests:
        raise ValueError("no tests given")
    names = [t.name for t in tests]
    if len(set(names)) != len(names):
        raise ValueError(f"test names must be unique, got {names}")
    preps = [PreparedTest(t) for t in tests]
    knee = knee_velocity(preps)
    pooled, per = effect_evidence(preps, knee), {p.t.name: effect_evidence([p], knee) for p in preps}
    effects = {}
    for e in EFFECTS:
        d = pooled[e]
        q, u = ((ALL_EFFECTS[e].symbol, ALL_EFFECTS[e].unit) if e != "thermal_drift" or d["beta"] is not None
                else ("gain_change_per_100s", "1/(100 s)"))
        effects[e] = {"quantity": q, "unit": u, **{k: _clean(v) for k, v in d.items()},
                      "sentence": evidence_sentence(e, d),
                      "per_test": {n: {k: _clean(v) for k, v in per[n][e].items()} for n in per}}
    rms = float(np.sqrt(np.mean(np.concatenate([p.r[p.use] for p in preps]) ** 2)))
    screen = joint_screen(preps, knee, max(pooled["free_play"]["gap_time"], 1e-3),
                          noise_n if noise_n is not None else 0.05 * rms)
    general = {"per_test": {p.t.name: {"role": p.t.role, **residual_summary([p])} for p in preps},
               "pooled": {**residual_summary(preps), "loop": _where_in_loop(preps, knee)}}
    fitted = identification_only(preps)
    return {"effects": effects, "ranking_by_r2": sorted(EFFECTS, key=lambda e: -effects[e]["r2"]),
            "joint_screen": screen, "knee_velocity": knee, "general": general,
            "residual_map": map_summary(fitted, knee) if fitted else None}
