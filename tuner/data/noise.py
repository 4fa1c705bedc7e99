"""Measurement noise of a rig test's channels, from what the data itself shows, and whether to trust it.

The diagnosis compares the residual RMS of a model at the fit rate with a residual floor made of the
force noise in the fit band (``tuner.diagnosis.diagnose``); an effect whose force is below the noise is
not resolved. A floor that is wrong by a factor of 100 turns either statement into nonsense (a real
MR damper's filtered 200 Hz force read 0.039 N from its spectrum while the same sine repeated cycle
after cycle scattered by 0.5-17 N, and the residual came out "368.8 x the floor"). So every estimate
here says whether it is credible and why, and :func:`force_noise` -- the one place that chooses --
records which one was used.

Estimators of the noise of one channel [its unit, rms]:

* ``cycle_scatter`` (:func:`cycle_scatter_noise`): periodic tests repeat the same cycle. The period
  comes from the stroke (its spectral peak, refined by a least-squares sine fit, and found again from
  the first cycle like the others until that is the first: a fade-in biases it); after the warm-up,
  every whole cycle is put on one phase grid (windowed-sinc interpolation, which keeps band-limited
  noise's variance) and the noise is the rms deviation from the cycle mean times sqrt(n/(n-1)) (n
  cycles). It measures everything that does not repeat, whatever its spectrum -- on filtered data too.
  Cycles whose stroke or force is off the median cycle by more than ``OUTLIER_FACTOR`` x the typical
  deviation (the fade-in, a transient) are left out. Not available with fewer than ``MIN_CYCLES``
  cycles or when the stroke does not repeat (random strokes). A stroke that repeats only nearly (a
  rig controller's drift) makes force differences of its own: the force deviations are regressed on
  the stroke's slow differences and their rate (coefficients per eighth of the cycle) and what that
  explains is taken out; the stroke's measurement noise, to which the force does not respond,
  explains nothing (it is taken out only above ``STROKE_EXPLAINS`` x the scatter). Not credible when
  that force exceeds ``STROKE_FORCE_LIMIT`` x what is left.
* ``repeats`` (:func:`repeat_noise`, "repeated segments"): a rig that replays the same non-periodic drive
  (a random stroke, a measured track section) several times in one test repeats a segment without a
  cycle. After the warm-up, the shift at which the stroke best matches itself later (at least
  ``MIN_REPEAT_S`` on: shorter is a cycle) is the least normalised squared difference of the stroke and
  its shifted self (FFT cross-correlation at the sample rate). The matched stretch is the longest run
  where the two agree within ``REPEAT_FIND`` x the stroke's rms in windows of ``REPEAT_WINDOW`` s, over
  the whole stretch too (relative to its own rms: else a random stroke's chance likeness), while the
  stroke moves (its rms there at least ``REPEAT_MOVING`` x the record's: a replayed drive, not the rig at
  rest). The shift is refined to a sub-sample one by least squares of the stroke difference on that
  stretch; the stretch is then cut to where the aligned strokes differ at their typical level (within
  ``OUTLIER_FACTOR`` x the median window; a fade-in, a transient are left out: a stroke 1 % off made a
  stiff damper's force differ by 2.5-4x the noise); and the shift is refined once more, within half a
  sample, on the force difference itself (one parameter over thousands of samples takes a negligible
  share of the noise, while a stroke stored in coarse steps left a tenth of a sample of misalignment:
  2.8x the noise of a stiff damper's force). The noise is the rms of the force difference between the
  aligned repeats (its mean, a load-cell offset, taken out) / sqrt(2): like the cycle scatter it
  measures everything that does not repeat, on filtered data too. The shifted repeat is read by
  windowed-sinc interpolation (as the cycle scatter's grid), not linear: linear interpolation half-way
  between samples keeps only half of white noise's variance, which would read the noise up to 13 % low
  (at a whole number of samples the kernel is a unit impulse: no interpolation in effect). Not
  available when nothing repeats over at least ``MIN_REPEAT_S`` / 2. Not credible when the aligned
  strokes differ by more than ``STROKE_REPEAT`` x the stroke's rms over the stretch (the drive was not
  the same, so neither is the force), with fewer than ``MIN_REPEAT_SAMPLES`` samples or ``MIN_REPEAT_S``
  of repeat, or when the difference's power below ``DRIFT_HZ`` is more than ``DRIFT_FACTOR`` x its mean
  level up to ``DRIFT_BAND_TOP`` x the sample rate (Welch, segments of about 2 s). The damper's own
  differences between the repeats (temperature drift, a stroke that was not replayed exactly) are not
  taken out here (unlike the cycle scatter's regression, which has many cycles to fit): they inflate
  the estimate (an upper bound), and when they come in slow -- a damper warming up -- that rule sees
  them.
* ``quiet_band`` (:func:`quiet_band_noise`): the residual of a flexible smoother -- the force
  band-passed to four sub-bands of 0.1-0.3 x the sample rate (above a damper's force content, below
  rigs' anti-alias filters) -- measured in its quietest stretches: the mean square in windows of
  ``WINDOW`` samples, its ``QUANTILE`` quantile, calibrated on white noise through the same steps.
  The force's own high-frequency content (the harmonics of a characteristic's kinks) comes in bursts
  where the velocity crosses a knee; the quiet windows leave it out, where a spectrum's median did
  not (28.4 N for 9.9 N on 500 Hz campaign data). The estimate is the level in ``ESTIMATE_BAND``
  (0.2-0.3 x the sample rate, where the force's content is least), white-equivalent over the
  Nyquist band. Not credible when the sub-band levels differ by more
  than ``FLATNESS`` x (white noise is flat: the data were low-pass filtered or smoothed, or the force's
  own content fills the band) or with fewer than ``MIN_BAND_SAMPLES`` samples.
* ``resolution`` (:func:`resolution_noise`): a channel stored in steps q carries at least the
  quantisation noise q / sqrt(12): a lower bound on any estimate.

In the fit band (``in_band``): white noise keeps sqrt(fit_rate / sample_rate) of its rms after the
anti-aliased resampling to the fit rate (``tuner.data.preprocess``). The cycle scatter is not assumed
white (filtered data's is not): its in-band part is its own power below fit_rate / 2 (Welch spectrum of
the deviations); the repeats' likewise (Welch spectrum of the force difference). That is what the floor
needs: the residual RMS of a model at the fit rate can fall to the noise inside the fit band, not below.
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from scipy import signal

__all__ = ["Estimate", "cycle_scatter_noise", "repeat_noise", "quiet_band_noise", "resolution_noise", "force_noise",
           "pooled_noise", "noise_text", "channel_noise", "in_band", "SUB_BANDS", "ESTIMATE_BAND", "MIN_CYCLES",
           "MIN_BAND_SAMPLES", "FLATNESS", "MIN_REPEAT_S", "MIN_REPEAT_SAMPLES", "REPEAT_FIND",
           "STROKE_REPEAT", "DRIFT_HZ", "DRIFT_FACTOR"]

#: sub-bands [fraction of the sample rate] of the quiet-band estimate
SUB_BANDS = ((0.10, 0.15), (0.15, 0.20), (0.20, 0.25), (0.25, 0.30))
#: band [fraction of the sample rate] of the quiet-band value: the upper part, where a damper's force
#: content is least (the lowest of the sub-bands instead would read 7-10 % low on white noise)
ESTIMATE_BAND = (0.20, 0.30)
#: samples per window of the quiet-band estimate, and the quantile of the windows' mean squares used
WINDOW = 32
QUANTILE = 0.05
#: fewest samples for a credible quiet-band estimate (at 2000 its scatter over seeds is about 5 %)
MIN_BAND_SAMPLES = 2000
#: largest ratio between the sub-band levels of white noise (they agree within 20 % on campaign data;
#: low-pass filtered data differ by 10^3, a 5-sample moving average by 3-7x)
FLATNESS = 3.0
#: fewest whole cycles for the cycle scatter
MIN_CYCLES = 3
#: a cycle off the median cycle by more than this multiple of the median deviation is left out
OUTLIER_FACTOR = 3.0
#: the stroke repeats when its cycle-to-cycle scatter is below this fraction of its rms about the mean
STROKE_REPEAT = 0.05
#: harmonics of the cycle kept in the stroke's cycle-to-cycle differences when their force is estimated
#: (a rig's motion differs slowly; above, the stroke's differences are its measurement noise)
STROKE_HARMONICS = 10
#: half length [samples] of the windowed-sinc interpolation kernel, and its Kaiser window's beta
_HALF = 16
_BETA = 8.0
#: the force the stroke's cycle-to-cycle differences make is taken out of the scatter when it is above this
#: fraction of it (below, 16 regressors on filtered noise took 5-10 % of its rms for nothing)
STROKE_EXPLAINS = 0.3
#: largest ratio of the force the stroke's cycle-to-cycle differences make to the scatter left when
#: they are taken out, for a credible estimate (a 5 % amplitude drift: 51 N taken out, 10 N left)
STROKE_FORCE_LIMIT = 10.0
#: parts of the cycle with their own coefficients when the force of the stroke's differences is regressed
_PHASE_BINS = 8
#: a repeated segment is credible from this long [s] and from this many samples (half as long: available,
#: not credible); the shift between repeats is at least MIN_REPEAT_S (shorter is a cycle)
MIN_REPEAT_S = 2.0
MIN_REPEAT_SAMPLES = 400
#: the stroke repeats where the rms of its difference from its shifted self, in windows of REPEAT_WINDOW
#: [s], is below REPEAT_FIND x the stroke's rms (after the warm-up); credible needs the whole stretch's
#: difference within STROKE_REPEAT x the stretch's stroke rms
REPEAT_FIND = 0.2
REPEAT_WINDOW = 0.5
#: the matched stretch's stroke rms is at least this fraction of the record's (a drive, not the rig at rest)
REPEAT_MOVING = 0.25
#: the repeats' force difference is not credible when its mean power density below DRIFT_HZ [Hz] is above
#: DRIFT_FACTOR x its mean density from DRIFT_HZ up to DRIFT_BAND_TOP x the sample rate (noise, even
#: low-pass filtered at 0.1 x the rate, is flat there; the damper drifting between repeats is slow). On
#: noise alone the ratio scatters about 1 (at most 2.8 over 60 replayed noise cases, tests/noise_cases.py);
#: a force gain drifting by 1 % over the test read 13-60 (and inflated the estimate 2-12x)
DRIFT_HZ = 1.0
DRIFT_FACTOR = 4.0
DRIFT_BAND_TOP = 0.05


class Estimate(dict):
    """One noise estimate (a dict, JSON-serialisable): ``value_n`` [channel unit rms, over the file's
    band], ``in_band_n`` (in the fit band, None without a fit rate), ``available`` (an estimate could be
    made), ``credible``, ``reasons`` (why not, or notes) and method-specific figures."""

    @classmethod
    def make(cls, method: str, value: float | None, in_band_value: float | None, available: bool, credible: bool,
             reasons: list[str], **details) -> "Estimate":
        return cls(method=method, value_n=None if value is None else float(value),
                   in_band_n=None if in_band_value is None else float(in_band_value), available=bool(available),
                   credible=bool(credible and available), reasons=list(reasons), **details)


def in_band(white_rms: float, sample_rate_hz: float, fit_rate_hz: float | None) -> float | None:
    """Rms of white noise [its unit] left after the anti-aliased resampling from ``sample_rate_hz`` to
    ``fit_rate_hz`` [Hz]: white_rms x sqrt(min(1, fit_rate / sample_rate)); None without a fit rate.
    It counts the resampler's transition band (0.8-1.0 x the fit band's edge) in full: 6.6-7 % above
    what ``tuner.data.preprocess.Resampler`` leaves of white noise, the conservative side."""
    if fit_rate_hz is None:
        return None
    return float(white_rms) * math.sqrt(min(1.0, float(fit_rate_hz) / float(sample_rate_hz)))


def _checked(x, sample_rate_hz: float, what: str) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.ndim != 1:
        raise ValueError(f"{what}: need a 1-D array, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what}: contains non-finite values")
    if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
        raise ValueError(f"{what}: sample rate must be positive, got {sample_rate_hz!r} Hz")
    return a


# --------------------------------------------------------------------------- quiet band

def _sos(band: tuple[float, float]):
    return signal.butter(4, [2.0 * band[0], 2.0 * band[1]], btype="band", output="sos")


def _checked_pair(stroke, force, sample_rate_hz: float, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Stroke [m] and force [N] of one test as ``_checked`` arrays of equal length (ValueError naming ``what``)."""
    x = _checked(stroke, sample_rate_hz, f"{what}: stroke")
    F = _checked(force, sample_rate_hz, f"{what}: force")
    if x.size != F.size:
        raise ValueError(f"{what}: stroke and force differ in length ({x.size} vs {F.size})")
    return x, F


def _quiet_level(x: np.ndarray, band: tuple[float, float]) -> float:
    """Rms of ``x`` band-passed to ``band`` [fraction of the sample rate] in its quietest windows: the
    square root of the QUANTILE quantile of the WINDOW-sample mean squares (edges of the filter dropped)."""
    y = signal.sosfiltfilt(_sos(band), x)[2 * WINDOW:-2 * WINDOW]
    n = (y.size // WINDOW) * WINDOW
    ms = np.mean(y[:n].reshape(-1, WINDOW) ** 2, axis=1)
    return float(np.sqrt(np.quantile(ms, QUANTILE)))


@lru_cache(maxsize=None)
def _white_level(band: tuple[float, float]) -> float:
    """``_quiet_level`` of unit white noise (2^17 samples, seed 0): the calibration of that band."""
    return _quiet_level(np.random.default_rng(0).standard_normal(1 << 17), band)


def quiet_band_noise(x, sample_rate_hz: float, fit_rate_hz: float | None = None) -> Estimate:
    """The quiet-band estimate (module docstring) of the noise of ``x`` sampled at ``sample_rate_hz``
    [Hz]: ``value_n`` white-equivalent over the Nyquist band [unit of x, rms], ``levels_n`` per
    ``SUB_BANDS``. Not available below 8 windows' worth of samples."""
    a = _checked(x, sample_rate_hz, "quiet_band_noise")
    if a.size < 8 * WINDOW:
        return Estimate.make("quiet_band", None, None, False, False,
                             [f"only {a.size} samples: no quiet-band estimate (needs {8 * WINDOW})"])
    a = a - a.mean()
    levels = [_quiet_level(a, b) / _white_level(b) for b in SUB_BANDS]
    value = _quiet_level(a, ESTIMATE_BAND) / _white_level(ESTIMATE_BAND)
    reasons, credible = [], True
    if a.size < MIN_BAND_SAMPLES:
        credible = False
        reasons.append(f"only {a.size} samples (< {MIN_BAND_SAMPLES}): too few quiet windows for a stable estimate")
    if min(levels) <= 0 or max(levels) > FLATNESS * min(levels):
        credible = False
        reasons.append("the force is not white in " + f"{SUB_BANDS[0][0] * sample_rate_hz:.4g}-"
                       f"{SUB_BANDS[-1][1] * sample_rate_hz:.4g} Hz (sub-band levels "
                       + ", ".join(f"{v:.3g}" for v in levels) + f", more than {FLATNESS:g}x apart): "
                       "low-pass filtered or smoothed data, or the force's own content fills the band")
    return Estimate.make("quiet_band", value, in_band(value, sample_rate_hz, fit_rate_hz), True, credible, reasons,
                         levels_n=levels, bands_hz=[[lo * sample_rate_hz, hi * sample_rate_hz] for lo, hi in SUB_BANDS])


# --------------------------------------------------------------------------- resolution

def resolution_noise(x, sample_rate_hz: float, fit_rate_hz: float | None = None) -> Estimate:
    """Quantisation noise q / sqrt(12) of a channel stored in steps q [unit of x]: q is the smallest
    difference between distinct values when (nearly: 99 %) all differences are whole multiples of it.
    A lower bound on the noise (credible as such); not available for continuous values."""
    a = _checked(x, sample_rate_hz, "resolution_noise")
    u = np.unique(a)
    if u.size < 3:
        return Estimate.make("resolution", None, None, False, False, [f"only {u.size} distinct values"])
    d = np.diff(u)
    q = float(d.min())
    k = d / q
    whole = np.abs(k - np.round(k)) <= 1e-6 * np.maximum(1.0, k)
    if q <= 0 or np.mean(whole) < 0.99 or q < 1e-9 * float(np.max(np.abs(u))):
        return Estimate.make("resolution", None, None, False, False,
                             ["values are not on a grid of steps: no resolution bound"])
    value = q / math.sqrt(12.0)
    return Estimate.make("resolution", value, in_band(value, sample_rate_hz, fit_rate_hz), True, True,
                         [f"stored in steps of {q:.3g}: at least q / sqrt(12) of noise (a lower bound)"], step=q)


# --------------------------------------------------------------------------- cycle scatter

def _interpolate(x: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """Band-limited values of ``x`` at fractional sample positions ``pos`` (Kaiser-windowed sinc over
    2 x _HALF samples, weights normalised; every position at least _HALF samples from the ends)."""
    out = np.empty(pos.size)
    k = np.arange(-_HALF + 1, _HALF + 1)
    for s in range(0, pos.size, 1 << 15):
        p = pos[s:s + (1 << 15)]
        i0 = np.floor(p).astype(int)
        idx = i0[:, None] + k[None, :]
        d = p[:, None] - idx
        w = np.sinc(d) * np.i0(_BETA * np.sqrt(np.clip(1.0 - (d / _HALF) ** 2, 0.0, None))) / np.i0(_BETA)
        out[s:s + p.size] = np.sum(x[idx] * w, axis=1) / np.sum(w, axis=1)
    return out


def _period(stroke: np.ndarray, rate: float) -> float | None:
    """Period [s] of the stroke's fundamental: the spectral peak (8x zero-padded), refined by the
    least-squares fit of an offset, a trend and a sine; None without a peak above DC."""
    from scipy.optimize import minimize_scalar

    n = stroke.size
    x = stroke - stroke.mean()
    nfft = 1 << int(math.ceil(math.log2(8 * n)))
    spec = np.abs(np.fft.rfft(x * np.hanning(n), nfft))
    f = np.fft.rfftfreq(nfft, 1.0 / rate)
    lo = 2.0 * rate / n                        # at least two cycles in the record
    sel = f >= lo
    if not np.any(sel) or spec[sel].max() <= 0:
        return None
    f0 = float(f[sel][np.argmax(spec[sel])])
    t = np.arange(n) / rate

    def sse(freq):
        w = 2 * np.pi * freq * t
        A = np.column_stack([np.ones(n), t, np.cos(w), np.sin(w)])
        c, *_ = np.linalg.lstsq(A, x, rcond=None)
        r = x - A @ c
        return float(r @ r)

    df = rate / nfft * 2.0
    res = minimize_scalar(sse, bounds=(max(lo / 2, f0 - df), f0 + df), method="bounded",
                          options={"xatol": 1e-9 * f0})
    return 1.0 / float(res.x)


def _typical(Z: np.ndarray) -> np.ndarray:
    """Cycles (rows of Z) within OUTLIER_FACTOR x the median rms deviation from the median cycle."""
    r = np.sqrt(np.mean((Z - np.median(Z, axis=0)) ** 2, axis=1))
    return r <= OUTLIER_FACTOR * np.median(r) + 1e-300


def _force_from_stroke(dX: np.ndarray, dY: np.ndarray, period_s: float) -> np.ndarray:
    """The part [N] of the cycles' force deviations ``dY`` (cycles x samples per cycle) that the stroke's own
    cycle-to-cycle differences ``dX`` [m] make (a rig controller that does not repeat exactly), flattened: the
    force deviations regressed on the stroke's slow differences and their rate, with coefficients per eighth of
    the cycle of ``period_s`` [s]; the stroke's measurement noise, to which the force does not respond, explains
    nothing and leaves the estimate as it is."""
    m = dX.shape[1]
    h = np.fft.rfftfreq(m, 1.0 / m)            # harmonic numbers
    DX = np.fft.rfft(dX, axis=1)
    DX[:, h > STROKE_HARMONICS] = 0.0
    slow = [np.fft.irfft(DX, m, axis=1), np.fft.irfft(DX * (2j * np.pi * h / period_s), m, axis=1)]
    bins = (np.arange(m) * _PHASE_BINS) // m
    cols = [np.where(bins[None, :] == b, z, 0.0).ravel() for z in slow for b in range(_PHASE_BINS)]
    A = np.column_stack([c / (np.sqrt(np.mean(c ** 2)) or 1.0) for c in cols])
    coef, *_ = np.linalg.lstsq(A, dY.ravel(), rcond=None)
    return A @ coef


def cycle_scatter_noise(stroke, force, sample_rate_hz: float, fit_rate_hz: float | None = None,
                        warmup_s: float = 0.5) -> Estimate:
    """The cycle-scatter estimate (module docstring) of the force noise [N rms] of a periodic test:
    stroke [m] and force [N] sampled at ``sample_rate_hz`` [Hz]; samples in the first ``warmup_s`` [s]
    do not count. Figures: ``period_s``, ``cycles`` (used), ``cycles_left_out``, ``stroke_scatter_m``,
    ``force_from_stroke_n`` (the force the stroke's cycle-to-cycle differences make, linearised)."""
    x, F = _checked_pair(stroke, force, sample_rate_hz, "cycle_scatter_noise")
    rate = float(sample_rate_hz)

    def unavailable(why: str, **details) -> Estimate:
        return Estimate.make("cycle_scatter", None, None, False, False, [why], **details)

    k0 = int(math.ceil(warmup_s * rate))
    if x.size - k0 < 4 * _HALF + 16:
        return unavailable(f"only {max(0, x.size - k0)} samples after the {warmup_s:g} s warm-up")
    start, n_before = k0, 0
    for _ in range(4):      # again from the first cycle alike, until it is the first (a fade-in biases the period)
        T = _period(x[start:], rate)
        if T is None:
            return unavailable("no periodic component in the stroke")
        m = int(round(T * rate))
        if m < 8:
            return unavailable(f"period {T:.4g} s is fewer than 8 samples")
        first = start + _HALF
        n_cycles = int(math.floor((x.size - 1 - _HALF - first) / (T * rate)))
        if n_cycles < MIN_CYCLES:
            return unavailable(f"{max(n_cycles, 0) + n_before} whole cycles of {T:.4g} s after the warm-up "
                               f"(needs {MIN_CYCLES})", period_s=T)
        pos = first + (np.arange(n_cycles)[:, None] * T + np.arange(m)[None, :] * (T / m)) * rate
        X = _interpolate(x, pos.ravel()).reshape(n_cycles, m)
        Y = _interpolate(F, pos.ravel()).reshape(n_cycles, m)
        keep = _typical(X) & _typical(Y)
        lead = int(np.argmax(keep)) if keep.any() else 0
        if lead == 0:
            break
        start, n_before = start + int(math.floor(lead * T * rate)), n_before + lead
    n = int(keep.sum())
    if n < MIN_CYCLES:
        return unavailable(f"only {n} of {n_cycles + n_before} cycles alike (needs {MIN_CYCLES})", period_s=T)
    X, Y = X[keep], Y[keep]
    corr = n / (n - 1.0)
    xm = X.mean(axis=0)
    dX, dY = X - xm, Y - Y.mean(axis=0)
    stroke_scatter = math.sqrt(float(np.mean(dX ** 2)) * corr)
    stroke_rms = float(np.std(xm))
    details = dict(period_s=T, cycles=n, cycles_left_out=int(n_cycles + n_before - n), stroke_scatter_m=stroke_scatter)
    if stroke_rms <= 0 or stroke_scatter > STROKE_REPEAT * stroke_rms:
        return unavailable(f"the stroke does not repeat (cycle-to-cycle scatter {stroke_scatter:.3g} m, "
                           f"{100 * stroke_scatter / max(stroke_rms, 1e-300):.0f} % of its rms): not a periodic test",
                           **details)
    fitted = _force_from_stroke(dX, dY, T)
    from_stroke = math.sqrt(float(np.mean(fitted ** 2)) * corr)
    details["force_from_stroke_n"] = from_stroke
    reasons, credible = [], True
    if from_stroke > STROKE_EXPLAINS * math.sqrt(float(np.mean(dY ** 2)) * corr):
        dY = dY - fitted.reshape(dY.shape)     # else the regression only took its share of the noise
        reasons.append(f"the stroke's cycle-to-cycle differences ({stroke_scatter:.3g} m rms) made about "
                       f"{from_stroke:.3g} N of the force scatter: taken out (linearised)")
    value = math.sqrt(float(np.mean(dY ** 2)) * corr)
    if from_stroke > STROKE_FORCE_LIMIT * value:
        credible = False
        reasons.append(f"the stroke does not repeat within its noise: its cycle-to-cycle differences "
                       f"({stroke_scatter:.3g} m rms) make about {from_stroke:.3g} N of force, more than "
                       f"{STROKE_FORCE_LIMIT:g} x the {value:.3g} N left (a linearised correction is not to be "
                       f"trusted that far)")

    in_band_value = None
    if fit_rate_hz is not None:
        grid_rate = m / T
        series = dY.ravel()
        f, p = signal.welch(series, fs=grid_rate, nperseg=min(series.size, max(256, 2 * m)))
        total = float(np.sum(p))
        share = float(np.sum(p[f < fit_rate_hz / 2.0])) / total if total > 0 else 1.0
        in_band_value = value * math.sqrt(min(1.0, share)) if fit_rate_hz < grid_rate else value
        details["in_band_share"] = share
    return Estimate.make("cycle_scatter", value, in_band_value, True, credible, reasons, **details)


# --------------------------------------------------------------------------- repeated segments

def _best_shift(x: np.ndarray, lo: int, hi: int) -> int | None:
    """Integer shift L in [lo, hi] minimising the squared difference of ``x`` (mean removed) and ``x``
    shifted by L over their overlap, normalised by the overlap's energy (FFT correlation)."""
    if hi < lo:
        return None
    n = x.size
    X = np.fft.rfft(x, 2 * n)
    r = np.fft.irfft(X * np.conj(X), 2 * n)[:n]          # r[L] = sum_t x[t] x[t + L]
    P = np.concatenate([[0.0], np.cumsum(x * x)])
    L = np.arange(lo, hi + 1)
    e = P[n - L] + (P[n] - P[L])
    d = (e - 2.0 * r[L]) / np.maximum(e, 1e-300)
    return int(L[np.argmin(d)])


def _moving_rms(d: np.ndarray, w: int) -> np.ndarray:
    return np.sqrt(np.maximum(np.convolve(d * d, np.ones(w) / w, mode="same"), 0.0))


def _longest_run(ok: np.ndarray) -> tuple[int, int]:
    """[start, stop) of the longest run of True in ``ok`` ((0, 0) without one)."""
    if not ok.any():
        return 0, 0
    e = np.diff(np.concatenate([[0], ok.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(e == 1), np.flatnonzero(e == -1)
    i = int(np.argmax(stops - starts))
    return int(starts[i]), int(stops[i])


def _repeat_estimate(dF: np.ndarray, value: float, rate: float, fit_rate_hz: float | None, details: dict) -> Estimate:
    """The repeats' estimate from the aligned force difference ``dF`` [N] (mean removed) of a repeat of
    ``details['samples']`` samples at ``rate`` [Hz]: ``value`` [N rms], whether it is credible (long enough, the
    same drive, no drift between the repeats) and its share in the fit band (``repeat_noise``)."""
    n, stroke_diff = details["samples"], details["stroke_difference"]
    reasons, credible = [], True
    if n < MIN_REPEAT_SAMPLES or n < MIN_REPEAT_S * rate:
        credible = False
        reasons.append(f"the repeat is only {n / rate:.3g} s ({n} samples; needs {MIN_REPEAT_S:g} s and "
                       f"{MIN_REPEAT_SAMPLES}): too few samples")
    if stroke_diff > STROKE_REPEAT:
        credible = False
        reasons.append(f"the repeats' strokes differ by {100 * stroke_diff:.1f} % of the stroke's rms after alignment "
                       f"(more than {100 * STROKE_REPEAT:g} %): not the same drive, so not the same force")
    nper = min(n, 1 << int(math.ceil(math.log2(2.0 * rate))))
    f, p = signal.welch(dF, fs=rate, nperseg=nper)
    low = (f > 0) & (f <= DRIFT_HZ)
    ref = (f > DRIFT_HZ) & (f <= DRIFT_BAND_TOP * rate)
    if low.any() and ref.any() and np.mean(p[ref]) > 0:
        ratio = float(np.mean(p[low]) / np.mean(p[ref]))
        details["low_frequency_ratio"] = ratio
        if ratio > DRIFT_FACTOR:
            credible = False
            reasons.append(f"the repeats' force difference is {ratio:.3g} x denser below {DRIFT_HZ:g} Hz than up to "
                           f"{DRIFT_BAND_TOP * rate:.3g} Hz (more than {DRIFT_FACTOR:g}x): the damper drifts between "
                           "the repeats (temperature) or the drive differs; the estimate is an upper bound")
    in_band_value = None
    if fit_rate_hz is not None:
        total = float(np.sum(p))
        share = float(np.sum(p[f < fit_rate_hz / 2.0])) / total if total > 0 else 1.0
        in_band_value = value * math.sqrt(min(1.0, share)) if fit_rate_hz < rate else value
        details["in_band_share"] = share
    return Estimate.make("repeats", value, in_band_value, True, credible, reasons, **details)


def repeat_noise(stroke, force, sample_rate_hz: float, fit_rate_hz: float | None = None,
                 warmup_s: float = 0.5) -> Estimate:
    """The repeated-segments estimate (module docstring) of the force noise [N rms] of a test that
    replays a drive: stroke [m] and force [N] sampled at ``sample_rate_hz`` [Hz]; samples in the first
    ``warmup_s`` [s] do not count. Figures: ``shift_s`` (from the first repeat to the second; the stroke's alone:
    ``stroke_shift_s``), ``start_s`` (the first repeat's start), ``repeat_s`` and ``samples`` (its length),
    ``stroke_difference`` (rms of the aligned strokes' difference / the stroke's rms there),
    ``low_frequency_ratio`` (the drift rule's ratio), ``in_band_share``."""
    x, F = _checked_pair(stroke, force, sample_rate_hz, "repeat_noise")
    rate = float(sample_rate_hz)

    def unavailable(why: str, **details) -> Estimate:
        return Estimate.make("repeats", None, None, False, False, [why], **details)

    k0 = max(int(math.ceil(warmup_s * rate)), _HALF)
    n_min = max(int(math.ceil(MIN_REPEAT_S * rate)), MIN_REPEAT_SAMPLES)
    xs = x[k0:x.size - _HALF - 1] if x.size > k0 + _HALF + 1 else x[:0]
    if xs.size < n_min + n_min // 2:
        return unavailable(f"only {xs.size} samples after the {warmup_s:g} s warm-up: no room for a segment "
                           f"and its repeat {MIN_REPEAT_S:g} s later (needs {n_min + n_min // 2})")
    xs = xs - xs.mean()
    s_rms = float(np.std(xs))
    if s_rms <= 0:
        return unavailable("the stroke does not move")
    L = _best_shift(xs, n_min, xs.size - n_min // 2)
    w = max(8, int(round(REPEAT_WINDOW * rate)))

    def stretch(shift: float, typical: bool = False) -> tuple[int, int]:
        """[a, b) absolute sample indices of the longest stretch that repeats at ``shift`` samples later;
        ``typical``: also where the strokes' difference is within OUTLIER_FACTOR x its median level."""
        m = int(math.floor(x.size - 1 - _HALF - shift)) - k0
        if m <= w:
            return k0, k0
        t = k0 + np.arange(m)
        r = _moving_rms(_interpolate(x, t + shift) - x[t], w)
        ok = r <= REPEAT_FIND * s_rms
        a, b = _longest_run(ok)
        if typical and b > a:
            a, b = _longest_run(ok & (r <= OUTLIER_FACTOR * float(np.median(r[a:b]))))
        return k0 + a, k0 + b

    a, b = stretch(float(L))
    if b - a < n_min // 2:
        return unavailable(f"no stretch of the stroke of {MIN_REPEAT_S / 2:g} s repeats later in the test "
                           f"(the best shift, {L / rate:.4g} s, matches {(b - a) / rate:.3g} s within "
                           f"{REPEAT_FIND:g} x the stroke's rms)")
    from scipy.optimize import minimize_scalar

    t = np.arange(a, b)
    t = t[t + L + 1 <= x.size - 1 - _HALF]
    res = minimize_scalar(lambda s_: float(np.mean((_interpolate(x, t + s_) - x[t]) ** 2)),
                          bounds=(L - 1.0, L + 1.0), method="bounded", options={"xatol": 1e-4})
    shift = float(res.x)
    a, b = stretch(shift, typical=True)
    t = np.arange(a, b)
    if t.size < n_min // 2:
        return unavailable(f"the repeat at {shift / rate:.4g} s falls apart after the sub-sample alignment")
    stroke_shift = shift
    t = t[t + shift + 0.5 <= x.size - 1 - _HALF]
    res = minimize_scalar(lambda s_: float(np.var(_interpolate(F, t + s_) - F[t])),
                          bounds=(shift - 0.5, shift + 0.5), method="bounded", options={"xatol": 1e-4})
    shift = float(res.x)
    X1, X2 = x[t], _interpolate(x, t + shift)
    seg_rms = float(np.std(0.5 * (X1 + X2)))
    if seg_rms < REPEAT_MOVING * s_rms:
        return unavailable(f"only a stretch where the stroke hardly moves repeats (its rms {seg_rms:.3g} m, "
                           f"under {REPEAT_MOVING:g} x the record's {s_rms:.3g} m): the rig at rest, not a replay")
    dX = X2 - X1
    stroke_diff = float(np.std(dX)) / seg_rms
    if stroke_diff > REPEAT_FIND:
        return unavailable(f"nothing repeats: the best match (a {t.size / rate:.3g} s stretch {shift / rate:.4g} s "
                           f"later) differs by {100 * stroke_diff:.0f} % of its stroke's rms (more than "
                           f"{100 * REPEAT_FIND:g} %), a chance likeness", shift_s=shift / rate)
    dF = _interpolate(F, t + shift) - F[t]
    dF = dF - dF.mean()
    value = float(np.sqrt(np.mean(dF ** 2))) / math.sqrt(2.0)
    details = dict(shift_s=shift / rate, stroke_shift_s=stroke_shift / rate, start_s=a / rate, repeat_s=t.size / rate,
                   samples=int(t.size), stroke_difference=stroke_diff)
    return _repeat_estimate(dF, value, rate, fit_rate_hz, details)


# --------------------------------------------------------------------------- the choice

def force_noise(test, fit_rate_hz: float | None = None, warmup_s: float = 0.5) -> dict:
    """The force noise of one rig test (``tuner.data.reading.RigTest``) [N rms], every estimator run and
    one chosen -- the one place that chooses:

    1. the cycle scatter when it is credible (it measures whatever does not repeat, on filtered data
       too);
    2. else the repeated segments when credible (a replayed non-periodic drive: likewise);
    3. else the quiet-band estimate when it is credible;
    4. else no credible estimate: the cycle scatter if available (an upper bound), else the repeats if
       available (likewise), else the quiet-band value, with ``credible`` False and the reasons;
    and never below the resolution bound (``method`` 'resolution' when that bound is the larger).

    Returns {"value_n" (over the file's band), "in_band_n" (in the ``fit_rate_hz`` band; None without),
    "fit_rate_hz", "method", "credible", "reasons", "all": {method: ``Estimate``}}.
    """
    rate = float(test.sample_rate)
    est = {"cycle_scatter": cycle_scatter_noise(test.stroke, test.force, rate, fit_rate_hz, warmup_s),
           "repeats": repeat_noise(test.stroke, test.force, rate, fit_rate_hz, warmup_s),
           "quiet_band": quiet_band_noise(test.force, rate, fit_rate_hz),
           "resolution": resolution_noise(test.force, rate, fit_rate_hz)}
    cyc, rep, band, res = est["cycle_scatter"], est["repeats"], est["quiet_band"], est["resolution"]
    reasons = []
    # why the repeats were not used, when some repeat was found (nothing repeating is the usual case)
    rep_reasons = [f"repeats: {r}" for r in rep["reasons"]] if rep["available"] else []
    if cyc["credible"]:
        chosen, credible = cyc, True
        if band["credible"] and cyc["value_n"] > 3.0 * band["value_n"]:
            reasons.append(f"the cycle scatter ({cyc['value_n']:.3g} N) is more than 3x the quiet-band white "
                           f"noise ({band['value_n']:.3g} N): noise that is not white, or a force that drifts "
                           "from cycle to cycle; the scatter is used (a model cannot fit it either)")
    elif rep["credible"]:
        chosen, credible = rep, True
        reasons += [f"cycle scatter: {r}" for r in cyc["reasons"]]
    elif band["credible"]:
        chosen, credible = band, True
        reasons += [f"cycle scatter: {r}" for r in cyc["reasons"]] + rep_reasons
    else:
        chosen = cyc if cyc["available"] else rep if rep["available"] else band
        credible = False
        reasons += ([f"cycle scatter: {r}" for r in cyc["reasons"]] + rep_reasons
                    + [f"quiet band: {r}" for r in band["reasons"]])
    if not chosen["available"]:
        chosen = res if res["available"] else chosen
    if res["available"] and (chosen["value_n"] is None or res["value_n"] > chosen["value_n"]):
        if chosen["value_n"] is not None:
            reasons.append(f"the {chosen['method']} estimate ({chosen['value_n']:.3g}) is below the channel's "
                           f"resolution bound ({res['value_n']:.3g}): the bound is used")
        chosen = res
    value, in_band_value = chosen["value_n"], chosen["in_band_n"]
    if value is None:
        reasons.append("no estimate of the force noise could be made")
    return {"value_n": value, "in_band_n": in_band_value, "fit_rate_hz": fit_rate_hz, "method": chosen["method"],
            "credible": bool(credible and value is not None), "reasons": reasons, "all": est}


def pooled_noise(tests: list, fit_rate_hz: float, warmup_s: float = 0.5) -> dict:
    """Force noise in the fit band [N rms] of several rig tests: the median of the tests' credible
    ``force_noise`` in-band values (of all of them, not credible, when none is credible; NaN when no
    test allows any estimate).
    Returns {"in_band_n", "fit_rate_hz", "credible", "method" (e.g. 'cycle_scatter x2, quiet_band x1'),
    "reasons" (why not credible, per test), "tests": {name: ``force_noise`` record}, "text"
    (``noise_text``)}."""
    if not tests:
        raise ValueError("pooled_noise: no test given")
    per = {t.name: force_noise(t, fit_rate_hz, warmup_s) for t in tests}
    good = [r for r in per.values() if r["credible"]]
    pool = good or [r for r in per.values() if r["in_band_n"] is not None]
    methods = {}
    for r in pool:
        methods[r["method"]] = methods.get(r["method"], 0) + 1
    reasons = [f"{name}: not credible ({'; '.join(r['reasons']) or 'no estimate'})"
               for name, r in per.items() if not r["credible"]]
    out = {"in_band_n": float(np.median([r["in_band_n"] for r in pool])) if pool else math.nan,
           "fit_rate_hz": float(fit_rate_hz),
           "credible": bool(good), "method": ", ".join(f"{k} x{v}" for k, v in methods.items()),
           "reasons": reasons, "tests": per}
    out["text"] = noise_text(out)
    return out


def noise_text(record: dict) -> str:
    """One line on a ``pooled_noise`` record: the value and how it was estimated, or why it is not
    credible (the first test's reasons; the record has all)."""
    where = (f"{record['in_band_n']:.3g} N rms in the {record['fit_rate_hz'] / 2:g} Hz fit band"
             if math.isfinite(record["in_band_n"]) else "nothing (no test long enough)")
    if record["credible"]:
        return f"{where} ({record['method'].replace('_', ' ')})"
    more = len(record["reasons"]) - 1
    return (f"noise estimate not credible ({record['reasons'][0] if record['reasons'] else 'no estimate'}"
            + (f"; and {more} more test{'s' if more > 1 else ''}" if more > 0 else "") + f"); it read {where}")


def channel_noise(test, fit_rate_hz: float, channel: str = "stroke") -> float:
    """White noise of ``channel`` ('stroke' [m] or 'force' [N]) in the fit band, rms: the quiet-band
    estimate (never below the resolution bound), ``in_band`` scaled. For simulating that noise (the
    force the stroke noise makes through a model); 0 when too short to tell."""
    x, rate = getattr(test, channel), float(test.sample_rate)
    values = [e["in_band_n"] for e in (quiet_band_noise(x, rate, fit_rate_hz), resolution_noise(x, rate, fit_rate_hz))
              if e["available"]]
    return float(max(values)) if values else 0.0
