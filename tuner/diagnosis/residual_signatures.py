"""The residual's evidence for each catalogue effect, one signature at a time (``effect_evidence``) and all at once
(``joint_screen``); residual r = measured - simulated force [N] of ``PreparedTest``s.

Catalogue and signatures: design.md, "Effects a real damper shows that the base model lacks"; each effect's record
(``damper_fmu.effect_catalogue``) names its signature, the symbol and unit of its magnitude and whether the
coefficient must be positive. r is fitted (masked samples, pooled over the tests given) by one signature regressor
g per effect, least squares without intercept; the explained fraction is the uncentred R^2 = (g.r)^2 / (g.g r.r),
i.e. the share of residual power (mean square) the term removes (for ``preload`` that is mean(r)^2 / mean(r^2)).
Regressors: friction tanh(v / 0.5 mm/s); preload 1; inertia x''; time_delay -dF_sim/dt (value =
delay, > 0 when the measured force lags); valve_lag -dF_sim/dt beyond the blow-off knee (tau, same
sign; the coefficient below the knee is reported too); free_play -F_sim in the apparent gap after
velocity reversals; thermal_drift the law m ~ g exp(-b x) F_sim with a free gain g, x = time since
the test start or temperature (its r2 includes the constant gain: see r2_gain_only, r2_drift_only).

``joint_screen`` regresses r on all these signatures at once (sequentially thresholded least
squares, terms below the noise or of unphysical sign dropped): a ranking of candidates and of
their combination before the diagnosis' refits, and the share of r any linear mix of them explains.
"""
from __future__ import annotations

import numpy as np
from scipy import optimize

from damper_fmu.effect_catalogue import ALL_EFFECTS

from tuner.diagnosis.residual_tests import GAP_WINDOW_S, dot, pooled_samples

__all__ = ["EFFECTS", "knee_velocity", "signature", "effect_evidence", "evidence_sentence", "joint_screen"]

#: the effects with a residual signature (``Effect.signature``): the catalogue's; their regressors are
#: ``signature`` and ``_signatures`` here
EFFECTS = tuple(e.name for e in ALL_EFFECTS.values() if e.signature)
V_EPS = 0.5e-3                   # friction regressor velocity scale [m/s]
KNEE_FALLBACK = 0.015            # blow-off knee velocity when the F-v scatter shows none [m/s]
MIN_T_SPAN_K = 0.5               # temperature span needed for the beta regression [K]


def _fit(y, g):
    """y ~ c g without intercept: (c, uncentred R^2 in [0, 1])."""
    gg, yy, gy = dot(g, g), dot(y, y), dot(g, y)
    return (gy / gg, gy * gy / (gg * yy)) if gg > 0 and yy > 0 else (0.0, 0.0)


def _regress(preps, fn):
    """Pooled fit of r on the regressor fn(prep) over the usable samples: (c, R^2)."""
    return _fit(pooled_samples(preps, lambda p: p.r), pooled_samples(preps, fn))


def knee_velocity(preps) -> float:
    """Blow-off knee [m/s]: first |v| where the slope of the binned median of sign(v) x measured
    force falls below 1/3 of its low-speed slope (origin to the first 3 of 20 bins up to the 98th
    percentile of |v|); KNEE_FALLBACK when no such point is found."""
    v = pooled_samples(preps, lambda p: np.abs(p.t.velocity))
    f = pooled_samples(preps, lambda p: np.sign(p.t.velocity) * p.t.measured)
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

    return {"value": t_gap * vbar, "r2": _regress(preps, lambda p: signature(p, "free_play", gap_span=span))[1], "gap_time": t_gap, "reversals": n_rev,
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
    m, f = pooled_samples(preps, lambda p: p.t.measured), pooled_samples(preps, lambda p: p.t.simulated)
    b, r2t, r2g = _gain_law(m, f, pooled_samples(preps, lambda p: p.t.time - p.t.time[p.use][0]))
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
        T = pooled_samples(hot, lambda p: p.t.temperature)
        out["temperature_span"] = float(np.ptp(T))
        if np.ptp(T) > MIN_T_SPAN_K:
            m, f = pooled_samples(hot, lambda p: p.t.measured), pooled_samples(hot, lambda p: p.t.simulated)
            out["beta"], out["r2_temperature"], out["r2_gain_only"] = _gain_law(m, f, T - T[0])
    out["value"] = out["beta"] if out["beta"] is not None else out["gain_change_per_100s"]
    out["r2"] = out["r2_temperature"] if out["beta"] is not None else r2t
    out["r2_drift_only"] = max(out["r2"] - out["r2_gain_only"], 0.0)
    return out


def signature(p, effect: str, knee: float = 0.0, gap_span: float = 0.0) -> np.ndarray:
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


def effect_evidence(preps, knee):
    """Every catalogue effect on the pooled usable samples of ``preps``: {name: {value, r2, ...}}."""
    one = {e: dict(zip(("value", "r2"), _regress(preps, lambda p, e=e: signature(p, e, knee))))
           for e in ("friction", "preload", "inertia", "time_delay", "valve_lag")}   # -dF: coefficient = lag
    one["below"] = dict(zip(("value", "r2"), _regress(preps, lambda p: -p.dF * (np.abs(p.t.velocity) <= knee))))
    below = one.pop("below")
    one["valve_lag"].update(tau_below_knee=below["value"], r2_below_knee=below["r2"], knee_velocity=knee)
    one["preload"]["mean_to_rms"] = np.sign(one["preload"]["value"]) * np.sqrt(one["preload"]["r2"])
    return {**one, "free_play": _free_play(preps), "thermal_drift": _thermal(preps)}


def evidence_sentence(e, d):
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


def _signatures(p, knee, gap_span, use_temperature: bool):
    """Linearised signature of every catalogue effect for one test (columns in EFFECTS order):
    the regressors of the single-effect evidence, free play as -F_sim within ``gap_span`` [s] after
    each reversal, thermal drift as -F_sim x (T - T at the first usable sample) [K] when
    ``use_temperature``, else x the time since that sample [s]: a damping gain falling as the oil
    heats, linearised."""
    t = p.t
    first = int(np.argmax(p.use))
    x = (t.temperature - t.temperature[first]) if use_temperature else (t.time - t.time[first])
    return np.column_stack([-t.simulated * x if e == "thermal_drift" else signature(p, e, knee, gap_span)
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
        float(np.ptp(pooled_samples(preps, lambda p: p.t.temperature))) > MIN_T_SPAN_K
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
