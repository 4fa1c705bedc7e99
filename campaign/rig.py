"""Virtual damper test rig: impose a stroke history, return what the rig records.

``measure`` drives the physically based twin-tube damper (``campaign.rig_damper``) with
the stroke (displacement-controlled actuator, cubic spline through the samples), adds
the switched-on hidden effects (``campaign.effects``) and passes stroke, force and oil
temperature through the sensor chain (``campaign.sensors``). The static reservoir gas
force is tared at the start, as on a real rig. Output columns: ``time`` [s], ``stroke``
[m] (extension +), ``force`` [N] (tension +), ``temperature`` [degC].
"""
from __future__ import annotations

import math
from typing import Mapping

import numpy as np
import pandas as pd

from campaign import effects as fx
from campaign.rig_damper import DamperParams, RigDamper
from campaign.sensors import SensorChain


def _check_inputs(t, stroke, sample_rate, seed):
    try:
        t = np.asarray(t, dtype=float)
        stroke = np.asarray(stroke, dtype=float)
    except (TypeError, ValueError):
        raise ValueError("t and stroke must be numeric arrays") from None
    if t.ndim != 1 or stroke.ndim != 1:
        raise ValueError(f"t and stroke must be 1-D, got shapes {t.shape} and {stroke.shape}")
    if t.size != stroke.size:
        raise ValueError(f"t and stroke differ in length: {t.size} vs {stroke.size}")
    if t.size < 2:
        raise ValueError("need at least 2 samples of t and stroke")
    if not np.all(np.isfinite(t)):
        raise ValueError("t contains NaN or inf")
    if not np.all(np.isfinite(stroke)):
        raise ValueError("stroke contains NaN or inf")
    if np.any(np.diff(t) <= 0):
        i = int(np.argmax(np.diff(t) <= 0))
        raise ValueError(f"t must be strictly increasing "
                         f"(t[{i}] = {t[i]!r}, t[{i + 1}] = {t[i + 1]!r})")
    numeric = (int, float, np.floating, np.integer)
    if isinstance(sample_rate, bool) or not isinstance(sample_rate, numeric) \
            or not math.isfinite(sample_rate) or sample_rate <= 0:
        raise ValueError(f"sample_rate must be a finite positive number [Hz], got {sample_rate!r}")
    if t[-1] - t[0] < 2.0 / sample_rate:
        raise ValueError(f"the stroke history ({t[-1] - t[0]:g} s) is shorter than two "
                         f"samples at {sample_rate:g} Hz")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative int, got {seed!r}")
    return t, stroke, float(sample_rate), int(seed)


def measure(t, stroke, effects: Mapping[str, float | None] | None = None, seed: int = 0,
            sample_rate: float = 1000.0, *, sensors: SensorChain | None = None,
            params: DamperParams | None = None, rtol: float = 1e-7) -> pd.DataFrame:
    """Run the virtual rig.

    t [s] (strictly increasing), stroke [m] (extension +, from mid-stroke, |stroke| <=
    75 mm); effects: {name: value or None (= default)} from ``campaign.effects.EFFECTS``;
    seed: noise seed; sample_rate [Hz] of the recorded channels (time starts at t[0]).
    Keyword-only: sensors (default ``SensorChain()``), params (damper, default
    ``DamperParams()``), rtol (integrator tolerance). Returns a DataFrame with columns
    time [s], stroke [m], force [N], temperature [degC]; ``attrs`` holds the effects,
    seed and sample rate. Bad input raises ValueError naming the problem.
    """
    t, stroke, fs, seed = _check_inputs(t, stroke, sample_rate, seed)
    eff = fx.validate_effects(effects)
    chain = sensors or SensorChain()
    n_out = int(math.floor((t[-1] - t[0]) * fs + 1e-9)) + 1
    os_ = chain.oversampling
    t_int = t[0] + np.arange(os_ * (n_out - 1) + 1) / (os_ * fs)
    t_int[-1] = min(t_int[-1], t[-1])
    damper = RigDamper(params, fx.physics_config(eff))
    resp = damper.simulate(t, stroke, t_int, rtol=rtol)
    force = fx.apply_channel_effects(t_int, resp.force, eff)
    s_out, f_out, temp_out = chain.acquire(resp.stroke, force, resp.temperature, seed=seed)
    df = pd.DataFrame({"time": t[0] + np.arange(n_out) / fs, "stroke": s_out,
                       "force": f_out, "temperature": temp_out})
    df.attrs.update({"effects": dict(eff), "seed": seed, "sample_rate": fs})
    return df
