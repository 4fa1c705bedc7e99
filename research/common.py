"""Shared helpers of the model-form research (issue 12): data loading the tuner's way, base fit."""
from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from damper_fmu.parameters import EFFECT_PARAMETERS, defaults
from tuner.data.reading import load_dataset
from tuner.data.preprocess import prepare
from tuner.identification.engine import Engine
from tuner.identification.fit import FitSettings, identify, validation_run
from tuner.identification.problem import data_digest, table_abscissae, to_signals
from tuner.metrics import noise_std
from tuner.identification.parametrization import Parametrization

FIT_RATE = 200.0
WARMUP = 0.5


def load(folder):
    tests = load_dataset(folder)
    ident = [t for t in tests if t.role == "identification"]
    val = [t for t in tests if t.role == "validation"]
    prep_id = [prepare(t, FIT_RATE) for t in ident]
    prep_val = [prepare(t, FIT_RATE) for t in val]
    sig_id = [to_signals(p, WARMUP) for p in prep_id]
    sig_val = [to_signals(p, WARMUP) for p in prep_val]
    noise = float(np.median([noise_std(t.force, t.sample_rate) * math.sqrt(min(1.0, FIT_RATE / t.sample_rate))
                             for t in ident]))
    return dict(ident=ident, val=val, prep_id=prep_id, prep_val=prep_val, sig_id=sig_id, sig_val=sig_val,
                noise=noise)


def base_fit(d, out: Path, iterations=0, polish_jac=100, log=print):
    sig_id = d["sig_id"]
    peak = max(float(np.abs(s.force[s.mask]).max()) for s in sig_id)
    axes = table_abscissae(sig_id, peak)
    par = Parametrization("lumped", "improved", force_limit=float(f"{1.5 * peak:.2g}"), fixed=axes)
    out.mkdir(parents=True, exist_ok=True)
    ck = out / "base_ckpt.json"
    if ck.exists():
        ck.unlink()
    fs = FitSettings(models=("lumped",), fit_rate_hz=FIT_RATE, warmup_s=WARMUP, iterations=iterations, workers=0,
                     engine="native", polish_jacobians=polish_jac)
    t0 = time.perf_counter()
    best, hist = identify("lumped", sig_id, fs, par, ck, data_digest(d["ident"]), log)
    base = defaults("lumped")
    base.update({k: v for k, v in best.items() if k in base})
    for p in EFFECT_PARAMETERS:
        base[p.name] = p.default
    return base, time.perf_counter() - t0


def rmse_sets(model, params, d, engine="native"):
    """(identification RMSE, held-out RMSE) [N] in the band-limited validation definition."""
    out = []
    for key in ("sig_id", "sig_val"):
        se, n = 0.0, 0
        for s in d[key]:
            sim, m = validation_run(model, params, s, engine)
            r = s.force[s.mask] - sim[s.mask]
            se += float(r @ r)
            n += r.size
        out.append(math.sqrt(se / n))
    return tuple(out)
