"""Does a fit made at the fit rate hold on the data at its own (full) sample rate?

The identification low-passes every test to the fit rate (200 Hz by default, ``tuner.data.preprocess.prepare``):
what the damper does above the fit band (``fit_rate / 2``) is not seen by the fit. This check
compares the fitted model with the data at twice the fit rate, with the same band-limited
comparison as the fit (``tuner.identification.engine``: the model on a fine grid, low-passed like the data; at the
file's own rate the model would be driven by the differentiator's velocity noise, which the
rubber mounts turn into hundreds of N of force), and splits the residual (measured - simulated
force [N]) by frequency (Welch PSD, Hann windows of 2 s):

* below the fit band's edge: what the fit itself reported, computed another way;
* from there to the comparison's flat passband edge (0.4 x the comparison rate): set against the
  white measurement noise expected there (``tuner.metrics.noise_std`` of the file's force).

The force the fit band hides is ``hidden = sqrt(max(above^2 - noise_above^2, 0))``; it raises the
RMSE over both bands from ``sqrt(in^2 + noise_above^2)`` to ``sqrt(in^2 + above^2)``. The fit holds
at full rate when that increase is at most the noise the fit reached in its own band: a fit at the
full rate could not then do better by more than the noise (a model already far from the data in
its band is not judged again by a few N above it). The check needs a file rate of
at least ``MIN_RATE_RATIO`` x the fit rate (at 300 Hz the band above a 200 Hz fit's is the rig's
anti-alias roll-off, where there is nothing to see).
"""
from __future__ import annotations

import math

import numpy as np

from tuner.identification.engine import Signals, fastest_engine, simulate_signals

__all__ = ["full_rate_check", "comparison_rate", "MIN_RATE_RATIO"]

#: file rate / fit rate from which the check applies (the compared band, up to 0.8 x the fit rate,
#: then stays below 0.3 x the file rate, under the rig's anti-alias roll-off)
MIN_RATE_RATIO = 2.7


def comparison_rate(sample_rate_hz: float, fit_rate_hz: float) -> float | None:
    """Rate [Hz] of the full-rate comparison (twice the fit rate), None when it does not apply."""
    return 2.0 * fit_rate_hz if sample_rate_hz >= MIN_RATE_RATIO * fit_rate_hz else None


def _band_rms(x: np.ndarray, rate: float, lo: float, hi: float) -> float:
    """RMS [unit of x] of the part of ``x`` between ``lo`` and ``hi`` [Hz] (Welch PSD integrated)."""
    from scipy.signal import welch

    f, p = welch(x - x.mean(), fs=rate, nperseg=min(len(x), max(64, int(2.0 * rate))))
    sel = (f >= lo) & (f < hi)
    return float(math.sqrt(np.sum(p[sel]) * (f[1] - f[0])))


def full_rate_check(model: str, params: dict, s: Signals, fit_rate_hz: float, file_rate_hz: float,
                    file_noise_n: float, *, engine: str | None = None) -> dict:
    """The check for one test.

    ``s``: the test prepared at ``comparison_rate`` (``tuner.data.preprocess.prepare`` then
    ``tuner.identification.fit.to_signals``, band-limited); ``file_noise_n``: the white-equivalent force noise
    of the file [N] over 0 .. ``file_rate_hz`` / 2 (``tuner.metrics.noise_std``).
    Returns forces [N] and frequencies [Hz]: ``fit_band_hz``, ``upper_hz``, ``rmse_in_fit_band_n``,
    ``noise_in_fit_band_n``, ``rmse_above_n`` (residual between the two), ``noise_above_n``,
    ``hidden_n``, ``rmse_increase_n`` and ``holds`` (``rmse_increase_n <= noise_in_fit_band_n``).
    """
    rate = (len(s.time) - 1) / (s.time[-1] - s.time[0])
    fit_band, upper = fit_rate_hz / 2.0, 0.4 * rate
    # as the validation (tuner.identification.fit.validation_run): the model at its own default, converged steps
    sim = simulate_signals(model, params, s, engine=engine or fastest_engine(), max_internal_step=None,
                           tolerance=None)
    idx = np.flatnonzero(s.mask)
    resid = (s.force - sim)[idx[0]:idx[-1] + 1]

    def noise(lo, hi):
        return file_noise_n * math.sqrt((hi - lo) / (file_rate_hz / 2.0))

    above, noise_above = _band_rms(resid, rate, fit_band, upper), noise(fit_band, upper)
    inside = _band_rms(resid, rate, 0.0, fit_band)
    increase = math.hypot(inside, above) - math.hypot(inside, noise_above)
    return {"comparison_rate_hz": rate, "fit_band_hz": fit_band, "upper_hz": upper,
            "rmse_in_fit_band_n": inside, "noise_in_fit_band_n": noise(0.0, fit_band), "rmse_above_n": above,
            "noise_above_n": noise_above, "hidden_n": math.sqrt(max(above ** 2 - noise_above ** 2, 0.0)),
            "rmse_increase_n": increase, "holds": bool(increase <= noise(0.0, fit_band))}
