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
  white measurement noise expected there. The noise level is the lower of two estimates: the
  file's force (``tuner.metrics.noise_std``, biased high by broadband force content the model
  reproduces, e.g. the harmonics of the characteristic's kinks) and the residual's own median
  PSD in the compared band (the median ignores a narrowband hidden force such as a rig resonance;
  a broadband one raises it). Only a hidden force that is broadband AND sits on force content the
  model reproduces above the fit band can pass unseen.

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


def _psd(x: np.ndarray, rate: float):
    """Welch PSD of ``x`` [unit^2/Hz] (Hann windows of 2 s, mean removed)."""
    from scipy.signal import welch

    return welch(x - x.mean(), fs=rate, nperseg=min(len(x), max(64, int(2.0 * rate))))


def _band_rms(f: np.ndarray, p: np.ndarray, lo: float, hi: float) -> float:
    """RMS of the part of a signal between ``lo`` and ``hi`` [Hz] from its PSD ``p`` on ``f``
    (mean removed: a constant offset does not count)."""
    sel = (f >= lo) & (f < hi)
    return float(math.sqrt(np.sum(p[sel]) * (f[1] - f[0])))


def full_rate_check(model: str, params: dict, s: Signals, fit_rate_hz: float, file_rate_hz: float,
                    file_noise_n: float, *, engine: str | None = None) -> dict:
    """The check for one test.

    ``s``: the test prepared at ``comparison_rate`` (``tuner.identification.problem.prepared_signals``,
    band-limited); ``file_noise_n``: the white-equivalent force noise
    of the file [N] over 0 .. ``file_rate_hz`` / 2 (``tuner.metrics.noise_std``).
    Returns forces [N] and frequencies [Hz]: ``fit_band_hz``, ``upper_hz``, ``rmse_in_fit_band_n``
    (mean removed), ``noise_std_n`` (the white-equivalent noise used: the lower of
    ``noise_std_force_n`` and ``noise_std_residual_n``), ``noise_in_fit_band_n``, ``rmse_above_n``
    (residual between the two bands), ``noise_above_n``, ``hidden_n``, ``rmse_increase_n`` and
    ``holds`` (``rmse_increase_n <= noise_in_fit_band_n``).
    """
    rate = (len(s.time) - 1) / (s.time[-1] - s.time[0])
    fit_band, upper = fit_rate_hz / 2.0, 0.4 * rate
    # as the validation (tuner.identification.fit.validation_run): the model at its own default, converged steps
    sim = simulate_signals(model, params, s, engine=engine or fastest_engine(), max_internal_step=None,
                           tolerance=None)
    idx = np.flatnonzero(s.mask)
    resid = (s.force - sim)[idx[0]:idx[-1] + 1]

    f, p = _psd(resid, rate)
    band = (f >= fit_band) & (f < upper)
    # white noise keeps its PSD level sigma^2 / (file_rate / 2) through the flat resampler passband
    sigma_resid = math.sqrt(float(np.median(p[band])) * file_rate_hz / 2.0)
    sigma = min(file_noise_n, sigma_resid)

    def noise(lo, hi):
        return sigma * math.sqrt((hi - lo) / (file_rate_hz / 2.0))

    above, noise_above = _band_rms(f, p, fit_band, upper), noise(fit_band, upper)
    inside = _band_rms(f, p, 0.0, fit_band)
    increase = math.hypot(inside, above) - math.hypot(inside, noise_above)
    return {"comparison_rate_hz": rate, "fit_band_hz": fit_band, "upper_hz": upper,
            "noise_std_n": sigma, "noise_std_residual_n": sigma_resid, "noise_std_force_n": file_noise_n,
            "rmse_in_fit_band_n": inside, "noise_in_fit_band_n": noise(0.0, fit_band), "rmse_above_n": above,
            "noise_above_n": noise_above, "hidden_n": math.sqrt(max(above ** 2 - noise_above ** 2, 0.0)),
            "rmse_increase_n": increase, "holds": bool(increase <= noise(0.0, fit_band))}
