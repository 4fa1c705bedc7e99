"""Residual analysis for the diagnosis: evidence numbers per catalogue effect (pure computation; the
figures that show the residual are drawn by ``tuner.results.diagnosis_figures``, into the files named here,
``figure_files``, which the diagnosis's record lists).

Residual r = measured - simulated force [N]; stroke [m] + in extension, force [N] + in tension,
time [s], temperature [degC]. Catalogue and signatures: design.md, "Effects a real damper shows
that the base model lacks"; each effect's record (``damper_fmu.effect_catalogue``) names its signature,
the symbol and unit of its magnitude and whether the coefficient must be positive. ``evidence`` fits r (masked samples, identification and validation
pooled, and per test) by one signature regressor g per effect, least squares without intercept;
the explained fraction is the uncentred R^2 = (g.r)^2 / (g.g r.r), i.e. the share of residual
power (mean square) the term removes (for ``preload`` that is mean(r)^2 / mean(r^2)).
Regressors: friction tanh(v / 0.5 mm/s); preload 1; inertia x''; time_delay -dF_sim/dt (value =
delay, > 0 when the measured force lags); valve_lag -dF_sim/dt beyond the blow-off knee (tau, same
sign; the coefficient below the knee is reported too); free_play -F_sim in the apparent gap after
velocity reversals; thermal_drift the law m ~ g exp(-b x) F_sim with a free gain g, x = time since
the test start or temperature (its r2 includes the constant gain: see r2_gain_only, r2_drift_only).

``joint_screen`` regresses r on all these signatures at once (sequentially thresholded least
squares, terms below the noise or of unphysical sign dropped): a ranking of candidates and of
their combination before the diagnosis' refits, and the share of r any linear mix of them explains.

The restoring-force map (``residual_map``, ``map_summary``) says where the residual lives: r of the
identification tests (the fit's samples, at the fit rate) binned over stroke x velocity and over velocity on
the two branches of the loop (acceleration >= 0 and < 0), and the shares of its power near velocity
reversal, at the stroke ends, in one band of the stroke, above the blow-off knee and in the difference
between the branches at equal velocity (a hysteresis), each beside its share of the samples.

Derivatives use Savitzky-Golay filters over ~20 ms (as ``tuner.data.differentiator`` does for the velocity):
dF_sim/dt cubic (polyorder 3), stroke acceleration polyorder 4 (for a symmetric window that is the
second-derivative counterpart of the cubic first derivative: error O(f^4)). Samples within half a
window of either end are left out of every regression.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import optimize, signal

from damper_fmu.effect_catalogue import ALL_EFFECTS

__all__ = ["TestResidual", "PreparedTest", "evidence", "joint_screen", "residual_summary", "spectra", "true_runs",
           "figure_files", "dot", "EFFECTS", "FIGURE_TOPICS", "ResidualMap", "residual_map", "map_summary",
           "identification_only"]

#: the effects with a residual signature (``Effect.signature``): the catalogue's; their regressors are
#: ``_signature`` and ``_signatures`` here
EFFECTS = tuple(e.name for e in ALL_EFFECTS.values() if e.signature)
ROLES = ("identification", "validation")
V_EPS = 0.5e-3                   # friction regressor velocity scale [m/s]
DIFF_WINDOW_S = 0.020            # Savitzky-Golay window [s]
KNEE_FALLBACK = 0.015            # blow-off knee velocity when the F-v scatter shows none [m/s]
GAP_WINDOW_S = 0.050             # free-play window after a velocity reversal [s]
REVERSAL_ACC = 0.2               # reversal counts if |a| > 0.2 x rms acceleration
BANDS_HZ = {"<1 Hz": (0.0, 1.0), "1-5 Hz": (1.0, 5.0), "5-20 Hz": (5.0, 20.0), ">20 Hz": (20.0, np.inf)}
MIN_T_SPAN_K = 0.5               # temperature span needed for the beta regression [K]
#: the figures of a base model's residual, one file each (``figure_files``; drawn by
#: ``tuner.results.diagnosis_figures``): in time, against velocity and stroke, around velocity reversals,
#: spectra, drift against time and temperature, the restoring-force map (``residual_map``)
FIGURE_TOPICS = ("time", "loops", "reversals", "spectra", "drift", "map")


def figure_files(folder: str | Path, prefix: str = "diag") -> list[str]:
    """The residual figures' files in ``folder`` (``<folder>/<prefix>_residual_<topic>.png``, one per
    ``FIGURE_TOPICS``): the names the diagnosis's record lists and the figures are drawn into."""
    return [str(Path(folder) / f"{prefix}_residual_{topic}.png") for topic in FIGURE_TOPICS]


@dataclass
class TestResidual:
    """One rig test on a uniform time grid: time [s], stroke [m], velocity [m/s], measured and
    simulated (base model) force [N], mask (bool, samples that count: warm-up excluded),
    optional temperature [degC]; role "identification" or "validation"."""
    __test__ = False  # not a pytest test class

    name: str
    role: str
    time: np.ndarray
    stroke: np.ndarray
    velocity: np.ndarray
    measured: np.ndarray
    simulated: np.ndarray
    mask: np.ndarray
    temperature: np.ndarray | None = None

    def __post_init__(self):
        def bad(msg):
            raise ValueError(f"test {self.name!r}: {msg}")
        if self.role not in ROLES:
            bad(f"role must be one of {ROLES}, got {self.role!r}")
        n = np.size(self.time)
        for k in ("time", "stroke", "velocity", "measured", "simulated", "temperature"):
            a = getattr(self, k)
            if a is None and k == "temperature":
                continue
            a = np.asarray(a, dtype=float)
            if a.shape != (n,):
                bad(f"{k} must be a 1-D array of {n} samples (as time), got shape {a.shape}")
            if not np.all(np.isfinite(a)):
                bad(f"{k} has non-finite values")
            setattr(self, k, a)
        m = np.asarray(self.mask)
        if m.dtype != bool or m.shape != (n,):
            bad(f"mask must be a boolean array of {n} samples")
        self.mask = m
        if n < 20:
            bad(f"{n} samples, at least 20 needed")
        dt = np.diff(self.time)
        if np.any(dt <= 0) or np.ptp(dt) > 0.01 * dt.mean():
            bad("time must be strictly increasing and uniformly sampled (1 % tolerance)")
        if m.sum() < 10:
            bad("mask selects fewer than 10 samples")


class PreparedTest:
    """Derived signals of one test: residual r [N], acceleration [m/s^2], dF_sim/dt [N/s],
    usable samples (mask without the filter edges), velocity reversals."""

    def __init__(self, t: TestResidual):
        self.t, n = t, t.time.size
        self.dt = float(np.mean(np.diff(t.time)))
        self.fs = 1.0 / self.dt
        w = max(5, int(round(DIFF_WINDOW_S * self.fs)) | 1)
        w = min(w, n - 1 + n % 2)
        self.acc = signal.savgol_filter(t.stroke, w, 4, deriv=2, delta=self.dt)
        self.dF = signal.savgol_filter(t.simulated, w, 3, deriv=1, delta=self.dt)
        self.r = t.measured - t.simulated
        self.use = t.mask.copy()
        self.use[:w // 2] = self.use[n - w // 2:] = False
        if self.use.sum() < 10:
            raise ValueError(f"test {t.name!r}: fewer than 10 masked samples away from the ends")
        v, a = t.velocity, self.acc
        i = np.flatnonzero(np.signbit(v[:-1]) != np.signbit(v[1:])) + 1   # first sample after
        thr = REVERSAL_ACC * np.sqrt(np.mean(a[self.use] ** 2))
        i = i[(np.abs(a[i]) > thr) & self.use[i]]
        keep, last = [], -np.inf
        for k in i:                           # one reversal per free-play window
            if k - last >= GAP_WINDOW_S * self.fs:
                keep.append(k)
                last = k
        self.rev = np.array(keep, dtype=int)
        self.rev_sign = np.where(np.signbit(v[self.rev]), -1.0, 1.0)

    def stack(self, tau):
        """Sample indices (reversals x tau [s]) fully inside the usable samples, and the sign of v after."""
        idx = self.rev[:, None] + np.rint(np.asarray(tau) * self.fs).astype(int)[None, :]
        ok = (idx.min(1) >= 0) & (idx.max(1) < self.t.time.size)
        ok[ok] = self.use[idx[ok]].all(1)
        return idx[ok], self.rev_sign[ok]


def dot(a, b) -> float:
    """The dot product of two 1-D arrays, not through BLAS."""
    return float(np.einsum("i,i", a, b))   # not BLAS: its threads stall on a loaded machine


def _cat(preps, fn):
    """fn(prep) (full-length array or scalar) on the usable samples, concatenated over preps."""
    return np.concatenate([np.broadcast_to(fn(p), p.r.shape)[p.use] for p in preps])


def _fit(y, g):
    """y ~ c g without intercept: (c, uncentred R^2 in [0, 1])."""
    gg, yy, gy = dot(g, g), dot(y, y), dot(g, y)
    return (gy / gg, gy * gy / (gg * yy)) if gg > 0 and yy > 0 else (0.0, 0.0)


def _regress(preps, fn):
    """Pooled fit of r on the regressor fn(prep) over the usable samples: (c, R^2)."""
    return _fit(_cat(preps, lambda p: p.r), _cat(preps, fn))


def knee_velocity(preps) -> float:
    """Blow-off knee [m/s]: first |v| where the slope of the binned median of sign(v) x measured
    force falls below 1/3 of its low-speed slope (origin to the first 3 of 20 bins up to the 98th
    percentile of |v|); KNEE_FALLBACK when no such point is found."""
    v = _cat(preps, lambda p: np.abs(p.t.velocity))
    f = _cat(preps, lambda p: np.sign(p.t.velocity) * p.t.measured)
    vmax = np.percentile(v, 98)
    if not vmax > 0:
        return KNEE_FALLBACK
    edges = np.linspace(0.0, vmax, 21)
    b, c = np.digitize(v, edges) - 1, 0.5 * (edges[1:] + edges[:-1])
    med = np.array([np.median(f[b == j]) if np.sum(b == j) >= 10 else np.nan for j in range(20)])
    if np.isnan(med).any():
        return KNEE_FALLBACK
    low = dot(c[:3], med[:3]) / dot(c[:3], c[:3])
    slope = np.convolve(np.gradient(med, c), np.ones(3) / 3, mode="same")
    j = np.flatnonzero(slope[3:-1] < low / 3)
    return float(c[3 + j[0]]) if low > 0 and j.size else KNEE_FALLBACK


def _free_play(preps):
    """r on -F_sim per lag (1 ms grid) 0-50 ms after reversals, and elsewhere: apparent gap time
    [s] = integral of the excess coefficient, gap [m] = gap time x mean |v| within it."""
    tau = np.arange(int(round(GAP_WINDOW_S * 1e3))) * 1e-3
    num, den, num_e, den_e, vabs = np.zeros(tau.size), np.zeros(tau.size), 0.0, 0.0, []
    for p in preps:
        idx, _ = p.stack(tau)
        F = p.t.simulated[idx]
        num += (-p.r[idx] * F).sum(0)
        den += (F * F).sum(0)
        vabs.append(np.abs(p.t.velocity[idx]))
        win = np.zeros(p.r.size + 1)
        np.add.at(win, p.rev, 1.0)
        np.add.at(win, np.minimum(p.rev + int(round(GAP_WINDOW_S * p.fs)), p.r.size), -1.0)
        el = p.use & (np.cumsum(win)[:-1] <= 0)
        num_e -= dot(p.r[el], p.t.simulated[el])
        den_e += dot(p.t.simulated[el], p.t.simulated[el])
    n_rev = sum(len(a) for a in vabs)
    ok = den > 1e-9 * den.max(initial=0.0)
    if n_rev == 0 or not ok.any():
        return {"value": 0.0, "r2": 0.0, "gap_time": 0.0, "reversals": n_rev}
    rho = np.interp(tau, tau[ok], num[ok] / den[ok])
    rho_e = num_e / den_e if den_e > 0 else 0.0
    t_gap = float(np.clip(np.sum(rho - rho_e) * 1e-3, 0.0, GAP_WINDOW_S))
    span = max(t_gap, 1e-3)
    vbar = float(np.concatenate(vabs)[:, tau < span].mean())

    return {"value": t_gap * vbar, "r2": _regress(preps, lambda p: _signature(p, "free_play", gap_span=span))[1], "gap_time": t_gap, "reversals": n_rev,
            "coef_window": float(np.sum(num) / np.sum(den)), "coef_elsewhere": rho_e,
            "mean_speed_after_reversal": vbar}


def _gain_law(m, f, x):
    """Fit m ~ g exp(-b x) f (variable projection: g in closed form, b by bounded Brent):
    (b [1/unit of x], R^2 of the law, R^2 of a constant gain alone), R^2 relative to r = m - f."""
    xs, rr = max(float(np.ptp(x)), 1e-12), dot(m - f, m - f) or 1.0

    def sse(b):
        e = np.exp(-b * x) * f
        res = m - dot(e, m) / dot(e, e) * e
        return dot(res, res)
    b = optimize.minimize_scalar(sse, bounds=(-3 / xs, 3 / xs), method="bounded",
                                 options={"xatol": 1e-7 / xs}).x
    return float(b), max(1 - sse(b) / rr, 0.0), max(1 - sse(0.0) / rr, 0.0)


def _thermal(preps):
    """Gain drift: exp law in time since each test's first usable sample and, where the
    temperature spans > 0.5 K, in temperature; gain of the second vs first half of every test."""
    m, f = _cat(preps, lambda p: p.t.measured), _cat(preps, lambda p: p.t.simulated)
    b, r2t, r2g = _gain_law(m, f, _cat(preps, lambda p: p.t.time - p.t.time[p.use][0]))
    out = {"gain_change_per_100s": float(np.expm1(-100 * b)), "r2_time": r2t, "r2_gain_only": r2g,
           "beta": None, "r2_temperature": None, "temperature_span": None}
    gains = []
    for h in (0, 1):
        ii = [np.array_split(np.flatnonzero(p.use), 2)[h] for p in preps]
        mm, ff = (np.concatenate([getattr(p.t, k)[i] for p, i in zip(preps, ii)]) for k in ("measured", "simulated"))
        gains.append(dot(mm, ff) / dot(ff, ff))
    out["half_gain_change"] = gains[1] / gains[0] - 1
    hot = [p for p in preps if p.t.temperature is not None]
    if hot:
        T = _cat(hot, lambda p: p.t.temperature)
        out["temperature_span"] = float(np.ptp(T))
        if np.ptp(T) > MIN_T_SPAN_K:
            m, f = _cat(hot, lambda p: p.t.measured), _cat(hot, lambda p: p.t.simulated)
            out["beta"], out["r2_temperature"], out["r2_gain_only"] = _gain_law(m, f, T - T[0])
    out["value"] = out["beta"] if out["beta"] is not None else out["gain_change_per_100s"]
    out["r2"] = out["r2_temperature"] if out["beta"] is not None else r2t
    out["r2_drift_only"] = max(out["r2"] - out["r2_gain_only"], 0.0)
    return out


def _signature(p, effect: str, knee: float = 0.0, gap_span: float = 0.0) -> np.ndarray:
    """The regressor of a catalogue effect for one test (module docstring), full length: friction
    tanh(v / V_EPS), preload 1, inertia x'', time_delay -dF_sim/dt, valve_lag -dF_sim/dt beyond the
    knee [m/s], free_play -F_sim within ``gap_span`` [s] after each reversal."""
    t = p.t
    if effect == "free_play":
        gap = np.zeros(p.r.size)
        for k in p.rev:
            gap[k:k + max(1, int(round(gap_span * p.fs)))] = 1.0
        return -t.simulated * gap
    return {"friction": lambda: np.tanh(t.velocity / V_EPS), "preload": lambda: np.ones(p.r.size),
            "inertia": lambda: p.acc, "time_delay": lambda: -p.dF,
            "valve_lag": lambda: -p.dF * (np.abs(t.velocity) > knee)}[effect]()


def _effects(preps, knee):
    """Every catalogue effect on the pooled usable samples of ``preps``: {name: {value, r2, ...}}."""
    one = {e: dict(zip(("value", "r2"), _regress(preps, lambda p, e=e: _signature(p, e, knee))))
           for e in ("friction", "preload", "inertia", "time_delay", "valve_lag")}   # -dF: coefficient = lag
    one["below"] = dict(zip(("value", "r2"), _regress(preps, lambda p: -p.dF * (np.abs(p.t.velocity) <= knee))))
    below = one.pop("below")
    one["valve_lag"].update(tau_below_knee=below["value"], r2_below_knee=below["r2"], knee_velocity=knee)
    one["preload"]["mean_to_rms"] = np.sign(one["preload"]["value"]) * np.sqrt(one["preload"]["r2"])
    return {**one, "free_play": _free_play(preps), "thermal_drift": _thermal(preps)}


def _sentence(e, d):
    """One line of evidence for effect e from its pooled numbers."""
    x = f"explains {100 * d['r2']:.0f} % of the residual power"
    if e == "free_play" and not d["reversals"]:
        return "no velocity reversal with enough acceleration: no free-play evidence"
    if e == "thermal_drift":
        s = (f"force gain changes {100 * d['gain_change_per_100s']:+.1f} % per 100 s, second vs first "
             f"half {100 * d['half_gain_change']:+.1f} %")
        if d["beta"] is not None:
            s += f"; gain ~ exp(-beta (T - T0)), beta = {d['beta']:.4f} 1/K over {d['temperature_span']:.1f} K"
        return s + f"; the drift law {x} ({100 * d['r2_gain_only']:.0f} % by a constant gain alone)"
    return {"friction": lambda: f"r ~ Ff tanh(v / 0.5 mm/s) with Ff = {d['value']:.0f} N",
            "preload": lambda: f"constant residual F0 = {d['value']:.0f} N (mean / rms {d['mean_to_rms']:+.2f})",
            "inertia": lambda: f"r ~ m_eq x'' with m_eq = {d['value']:.1f} kg",
            "time_delay": lambda: f"r ~ -delay dF_sim/dt with delay = {1e3 * d['value']:.2f} ms",
            "valve_lag": lambda: (
                f"beyond the knee (|v| > {1e3 * d['knee_velocity']:.1f} mm/s) r ~ -tau dF_sim/dt with tau = "
                f"{1e3 * d['value']:.2f} ms, below it {1e3 * d['tau_below_knee']:.2f} ms (a valve effect "
                "lives beyond the knee, a delay shifts both alike)"),
            "free_play": lambda: (
                f"{d['reversals']} reversals: r follows -F_sim for {1e3 * d['gap_time']:.1f} ms after them "
                f"(coefficient on -F_sim {d['coef_window']:.2f} in the first 50 ms vs {d['coef_elsewhere']:.2f} "
                f"elsewhere), apparent gap {1e3 * d['value']:.2f} mm"),
            }[e]() + _against_physics(e, d) + f"; {x}"


def _against_physics(e, d) -> str:
    """A word when the coefficient of an effect with a physical sign (``Effect.positive``) came out
    negative: not that effect."""
    noun = ALL_EFFECTS[e].positive
    if noun and d.get("value") is not None and d["value"] < 0:
        return f" (negative: opposite to {noun}, so this correlation is not evidence for it)"
    return ""


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
    v, r = _cat(ps, lambda p: p.t.velocity), _cat(ps, lambda p: p.r)
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
    r, m = _cat(ps, lambda p: p.r), _cat(ps, lambda p: p.t.measured)
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


# --------------------------------------------------------------------------- the restoring-force map

#: the map's bins over the identification tests' range: stroke x velocity; the velocity's edges are symmetric
#: about 0 and their number even, so that v = 0 is an edge and no bin mixes extension and compression
MAP_STROKE_BINS = 12
MAP_VELOCITY_BINS = 16
#: a bin with fewer samples is left empty (NaN): the rms of 25 independent samples scatters by 1/sqrt(2 x 25) =
#: 14 % (one sigma), so a bin at twice the overall rms stands out of it; fewer would read scatter as structure
MIN_BIN_SAMPLES = 25
#: near velocity reversal: |v| below this share of the test's peak |v| (a sine spends 13 % of its time there);
#: friction, a free play or a valve's crack-open that the base's tables cannot follow live there
REVERSAL_SPEED_SHARE = 0.2
#: at the stroke ends: within this share of the test's stroke range from either end (a sine spends 29 % of its
#: time there, it dwells at the ends); an end stop, a top-out spring or a gas spring's rise live there
STROKE_END_SHARE = 0.05
#: the stroke range is cut into this many bands of equal width, to find one position holding a disproportionate
#: share (a groove, a worn or scored stretch of the tube); each band needs MIN_BIN_SAMPLES samples to count
STROKE_BANDS = 10
#: a region holds the residual when its power share is at least CONCENTRATED_RATIO x its time share (an even
#: spread gives 1; the share of a residual correlated over a few cycles scatters by tens of percent, not 2x) and
#: at least CONCENTRATED_SHARE of the power: removing less than a third would cut the rms by less than 18 %, which
#: is not where the error lives
CONCENTRATED_RATIO = 2.0
CONCENTRATED_SHARE = 1 / 3
#: the branches differ (a hysteresis) when the part of the residual that differs between the a >= 0 and a < 0
#: branches at equal velocity holds at least this share of the power: the same third as a region's (independent
#: noise gives about (velocity bins) / (samples): 16 / 1000 = 1.6 % on 5 s at 200 Hz)
HYSTERESIS_SHARE = 1 / 3


@dataclass
class ResidualMap:
    """The residual r = measured - simulated force [N] binned over the restoring-force plane (``residual_map``):
    ``rms_n``, ``count`` over stroke [m] (rows, + extension) x velocity [m/s] (columns, + extension), and
    ``branch_rms_n``, ``branch_mean_n``, ``branch_count`` over velocity on each branch of the loop (row 0:
    acceleration >= 0, row 1: < 0). A bin with fewer than MIN_BIN_SAMPLES samples holds NaN (its count stays)."""

    stroke_edges_m: np.ndarray
    velocity_edges_m_s: np.ndarray
    rms_n: np.ndarray
    count: np.ndarray
    branch_rms_n: np.ndarray
    branch_mean_n: np.ndarray
    branch_count: np.ndarray


def identification_only(preps: list) -> list:
    """The identification tests of ``preps``: the ones the model was fitted on, whose residual the map shows."""
    return [p for p in preps if p.t.role == "identification"]


def _edges(x: np.ndarray, n: int, symmetric: bool = False) -> np.ndarray:
    """n equal bins' edges over the range of x (symmetric: over +-max |x|, 0 an edge when n is even)."""
    if symmetric:
        top = max(float(np.abs(x).max()), 1e-12)
        return np.linspace(-top, top, n + 1)
    lo, hi = float(x.min()), float(x.max())
    return np.linspace(lo, max(hi, lo + 1e-12), n + 1)


def _bin_of(x: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Bin index of every x (the last bin closed on the right)."""
    return np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2)


def _binned(r: np.ndarray, k: np.ndarray, n: int):
    """(rms [N], mean [N], count) of r in each bin k of n; NaN where a bin has fewer than MIN_BIN_SAMPLES."""
    count = np.bincount(k, minlength=n)
    ok = count >= MIN_BIN_SAMPLES
    rms, mean = np.full(n, np.nan), np.full(n, np.nan)
    rms[ok] = np.sqrt(np.bincount(k, r * r, n)[ok] / count[ok])
    mean[ok] = np.bincount(k, r, n)[ok] / count[ok]
    return rms, mean, count


def residual_map(preps: list) -> ResidualMap:
    """The residual of ``preps`` (their usable samples, pooled) binned over stroke x velocity and over velocity
    on the a >= 0 and a < 0 branches (``ResidualMap``); the bins span the samples' range."""
    if not preps:
        raise ValueError("no tests to map")
    r, x, v = (_cat(preps, f) for f in (lambda p: p.r, lambda p: p.t.stroke, lambda p: p.t.velocity))
    negative_a = _cat(preps, lambda p: p.acc < 0)
    xe, ve = _edges(x, MAP_STROKE_BINS), _edges(v, MAP_VELOCITY_BINS, symmetric=True)
    kx, kv = _bin_of(x, xe), _bin_of(v, ve)
    rms, _, count = _binned(r, kx * MAP_VELOCITY_BINS + kv, MAP_STROKE_BINS * MAP_VELOCITY_BINS)
    b_rms, b_mean, b_count = _binned(r, negative_a * MAP_VELOCITY_BINS + kv, 2 * MAP_VELOCITY_BINS)
    shape = (MAP_STROKE_BINS, MAP_VELOCITY_BINS)
    return ResidualMap(xe, ve, rms.reshape(shape), count.reshape(shape), b_rms.reshape(2, -1),
                       b_mean.reshape(2, -1), b_count.reshape(2, -1))


def _share(r2: np.ndarray, sel: np.ndarray) -> dict:
    """A region's share of the residual power (r2: r^2 per sample) and of the samples [0-1], and their ratio."""
    power, time = float(r2[sel].sum() / (r2.sum() or 1.0)), float(sel.mean())
    return {"power_share": power, "time_share": time, "ratio": power / time if time > 0 else None}


def _at_stroke_ends(p) -> np.ndarray:
    """The samples of one test within STROKE_END_SHARE of its stroke range (usable samples) from either end."""
    x = p.t.stroke
    lo, hi = float(x[p.use].min()), float(x[p.use].max())
    return (x <= lo + STROKE_END_SHARE * (hi - lo)) | (x >= hi - STROKE_END_SHARE * (hi - lo))


def _stroke_band(x: np.ndarray, r2: np.ndarray) -> dict:
    """Of STROKE_BANDS equal bands of the stroke x [m], the one whose power share is the largest multiple of its
    time share (bands of MIN_BIN_SAMPLES samples or more): ``_share`` with its ends [m]."""
    edges = _edges(x, STROKE_BANDS)
    k = _bin_of(x, edges)
    n, power = np.bincount(k, minlength=STROKE_BANDS), np.bincount(k, r2, STROKE_BANDS)
    ratio = np.where(n >= MIN_BIN_SAMPLES, power / np.maximum(n, 1), -np.inf)
    j = int(np.argmax(ratio))
    return {**_share(r2, k == j), "stroke_from_m": float(edges[j]), "stroke_to_m": float(edges[j + 1])}


def _branch_asymmetry(m: ResidualMap, r2: np.ndarray) -> dict:
    """The residual power that differs between the a >= 0 and a < 0 branches at equal velocity: the between-branch
    sum of squares of the branch means in every velocity bin where both branches hold MIN_BIN_SAMPLES, over the
    whole residual power; its time share is those bins' samples."""
    both = (m.branch_count >= MIN_BIN_SAMPLES).all(axis=0)
    n, mean = m.branch_count[:, both], m.branch_mean_n[:, both]
    pooled = (n * mean).sum(axis=0) / np.maximum(n.sum(axis=0), 1)
    power = float((n * (mean - pooled) ** 2).sum() / (r2.sum() or 1.0))
    return {"power_share": power, "time_share": float(n.sum() / r2.size),
            "hysteresis": bool(power >= HYSTERESIS_SHARE)}


def map_summary(preps: list, knee: float) -> dict:
    """Where the residual of ``preps`` lives (their usable samples, pooled): each region's share of the residual
    power and of the samples [0-1] and their ratio: ``near_reversal`` (|v| < REVERSAL_SPEED_SHARE x the test's
    peak |v|), ``stroke_ends`` (within STROKE_END_SHARE of the test's stroke range from either end),
    ``stroke_band`` (the band of the stroke with the largest ratio, its ends [m]) and ``above_knee`` (|v| >=
    ``knee`` [m/s]); ``branch_asymmetry`` (the power that differs between the a >= 0 and a < 0 branches at equal
    velocity: a hysteresis when at least HYSTERESIS_SHARE); ``concentrated_in``: the regions holding at least
    CONCENTRATED_SHARE of the power at CONCENTRATED_RATIO x their time share or more, largest ratio first."""
    r, x = _cat(preps, lambda p: p.r), _cat(preps, lambda p: p.t.stroke)
    r2 = r * r
    slow = _cat(preps, lambda p: np.abs(p.t.velocity) < REVERSAL_SPEED_SHARE * np.abs(p.t.velocity[p.use]).max())
    regions = {"near_reversal": _share(r2, slow), "stroke_ends": _share(r2, _cat(preps, _at_stroke_ends)),
               "stroke_band": _stroke_band(x, r2),
               "above_knee": {**_share(r2, _cat(preps, lambda p: np.abs(p.t.velocity) >= knee)),
                              "knee_velocity_m_s": float(knee)}}
    held = [k for k, d in regions.items() if d["power_share"] >= CONCENTRATED_SHARE
            and d["ratio"] is not None and d["ratio"] >= CONCENTRATED_RATIO]
    return {"tests": [p.t.name for p in preps], "samples": int(r.size), "rms_residual_n": float(np.sqrt(r2.mean())),
            "regions": regions, "branch_asymmetry": _branch_asymmetry(residual_map(preps), r2),
            "concentrated_in": sorted(held, key=lambda k: -regions[k]["ratio"]),
            "thresholds": {"reversal_speed_share": REVERSAL_SPEED_SHARE, "stroke_end_share": STROKE_END_SHARE,
                           "stroke_bands": STROKE_BANDS, "min_bin_samples": MIN_BIN_SAMPLES,
                           "concentrated_ratio": CONCENTRATED_RATIO, "concentrated_share": CONCENTRATED_SHARE,
                           "hysteresis_share": HYSTERESIS_SHARE}}


# --------------------------------------------------------------------------- joint screen

def _signatures(p, knee, gap_span, use_temperature: bool):
    """Linearised signature of every catalogue effect for one test (columns in EFFECTS order):
    the regressors of the single-effect evidence, free play as -F_sim within ``gap_span`` [s] after
    each reversal, thermal drift as -F_sim x (T - T at the first usable sample) [K] when
    ``use_temperature``, else x the time since that sample [s]: a damping gain falling as the oil
    heats, linearised."""
    t = p.t
    first = int(np.argmax(p.use))
    x = (t.temperature - t.temperature[first]) if use_temperature else (t.time - t.time[first])
    return np.column_stack([-t.simulated * x if e == "thermal_drift" else _signature(p, e, knee, gap_span)
                            for e in EFFECTS])


def joint_screen(preps, knee, gap_span: float, threshold_n: float) -> dict:
    """Sparse regression of the residual on all catalogue signatures at once (sequentially
    thresholded least squares, as PySINDy's STLSQ): solve, drop every term whose force
    contribution (|coefficient| x rms of its signature [N]) is below ``threshold_n`` or whose
    coefficient has the wrong physical sign, re-solve with the rest, until nothing changes.

    Returns {"kept": [effects, largest contribution first], "terms": {effect: {"coefficient",
    "contribution_n"}} of the kept ones, "r2_kept": share of the residual power they explain
    together, "r2_all": the share all seven signatures explain at once (least squares, signs
    free): the most any combination of linearised catalogue effects can remove, "threshold_n"}.
    A cheap ranking before the refits; its coefficients are linearisations, not magnitudes."""
    # one drift variable for every test, by the rule of the single-effect evidence (_thermal)
    use_temperature = all(p.t.temperature is not None for p in preps) and \
        float(np.ptp(_cat(preps, lambda p: p.t.temperature))) > MIN_T_SPAN_K
    X = np.concatenate([_signatures(p, knee, gap_span, use_temperature)[p.use] for p in preps])
    r = np.concatenate([p.r[p.use] for p in preps])
    scale = np.sqrt(np.mean(X ** 2, axis=0))
    live = scale > 0
    rr = dot(r, r) or 1.0

    def solve(cols):
        if not cols.any():
            return np.zeros(X.shape[1]), 0.0
        Z = X[:, cols] / scale[cols]
        b, *_ = np.linalg.lstsq(Z, r, rcond=None)
        full = np.zeros(X.shape[1])
        full[cols] = b / scale[cols]
        e = r - Z @ b
        return full, 1.0 - dot(e, e) / rr

    _, r2_all = solve(live)
    keep = live.copy()
    for _ in range(len(EFFECTS)):
        coef, r2 = solve(keep)
        contrib = np.abs(coef) * scale
        # a coefficient must be positive to count when the signature's sign is the effect's (Effect.positive)
        wrong = np.array([bool(ALL_EFFECTS[e].positive) and c < 0 for e, c in zip(EFFECTS, coef)])
        new = keep & (contrib >= threshold_n) & ~wrong
        if (new == keep).all():
            break
        keep = new
    coef, r2 = solve(keep)
    terms = {e: {"coefficient": float(coef[j]), "contribution_n": float(abs(coef[j]) * scale[j])}
             for j, e in enumerate(EFFECTS) if keep[j]}
    return {"kept": sorted(terms, key=lambda e: -terms[e]["contribution_n"]), "terms": terms,
            "r2_kept": float(r2), "r2_all": float(r2_all), "threshold_n": float(threshold_n)}


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
    pooled, per = _effects(preps, knee), {p.t.name: _effects([p], knee) for p in preps}
    effects = {}
    for e in EFFECTS:
        d = pooled[e]
        q, u = ((ALL_EFFECTS[e].symbol, ALL_EFFECTS[e].unit) if e != "thermal_drift" or d["beta"] is not None
                else ("gain_change_per_100s", "1/(100 s)"))
        effects[e] = {"quantity": q, "unit": u, **{k: _clean(v) for k, v in d.items()},
                      "sentence": _sentence(e, d),
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
