"""Diagnosis: what the fitted lumped model gets wrong, which physical effect causes it, the model
extended by that effect, and the gain measured on held-out data.

Procedure (``diagnose``):
1. Base model: the lumped model identified on the identification tests (taken from an earlier fit
   or identified here: seeded Firefly + least-squares polish, as ``tuner.fit``).
2. Residuals (measured - simulated force) of the base model on every test: evidence numbers and
   figures (``tuner.residuals``): in time, against velocity and stroke, around velocity reversals,
   against frequency, drift over the test and against the temperature channel.
3. For every candidate of the catalogue (``damper_fmu.effects``): extend the model by that effect,
   refit on the identification tests, and measure the validation MSE. The refit (``_refit``) runs
   a profile line search on the effect parameter (each grid value with the base re-balanced by
   Levenberg-Marquardt steps on the base Jacobian, since the base fit may have absorbed part of
   the effect into its tables) and a joint least-squares polish, from two
   starts: the fitted base, and the data-driven initial guess, which has absorbed nothing (plain
   grid there); the better identification fit wins. The leading candidate's refit is continued
   (``final_jacobians``) before the decision.
   Score = -ln(MSE_ext / MSE_base) - 0.02 x (extra parameters), pooled over the
   validation tests. The cause is the best-scoring extension if its score exceeds 0.05 (at least
   ~7 % held-out MSE reduction for one parameter), else ``none``. The decision rests on held-out
   gain, not on residual shape: residual evidence is reported alongside as explanation.
4. Output: ``diagnosis.json`` (cause, ranking, effect parameters with units and plausible ranges,
   validation MSE/AME before and after per test, evidence), figures, and the extended model as a
   tuned FMU (``fmu/DamperLumped_<cause>_tuned.fmu``).

Search bounds come from the data where they are force scales (friction and preload up to 10 %
of the peak measured force) and are generic time and mass scales otherwise, so the procedure is
not tied to one damper.
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from damper_fmu.parameters import EFFECT_IDENTIFIED, EFFECT_PARAMETERS, defaults

from .data import RigTest, prepare
from .engine import Engine
from .metrics import error_metrics, noise_std
from .parametrization import Parametrization
from .polish import polish
from .report import fmt_quantity

__all__ = ["DiagnosisSettings", "diagnose", "decide", "cross_check", "CANDIDATES", "ExtendedParametrization"]

CANDIDATES = tuple(EFFECT_IDENTIFIED)
PENALTY_PER_PARAMETER = 0.02
ACCEPT_SCORE = 0.05
#: typical magnitudes (design notes' catalogue), reported next to the fitted values
PLAUSIBLE = {"friction_force": (50.0, 300.0), "preload_force": (30.0, 400.0), "free_play": (1e-4, 1e-3),
             "thermal_beta": (0.002, 0.02), "valve_tau": (1e-3, 1e-2), "time_delay": (1e-3, 1e-2),
             "inertia_mass": (20.0, 200.0)}
UNITS = {p.name: p.unit for p in EFFECT_PARAMETERS}
NOTES = {"time_delay": "a skew between the force and stroke channels (DAQ, filters): fix the acquisition; "
                       "the exported co-simulation model should not contain it",
         "preload": "an un-tared gas force or load-cell offset: check the rig's zero before the test"}


def search_bounds(name: str, peak_force: float) -> tuple[float, float]:
    """Refit bounds of an effect parameter (SI), force scales from the measured peak force [N]."""
    f = 0.1 * peak_force
    return {"friction_force": (0.0, f), "preload_force": (-f, f), "free_play": (0.0, 2e-3),
            "thermal_beta": (0.0, 0.05), "valve_tau": (0.0, 0.02), "time_delay": (0.0, 0.02),
            "inertia_mass": (0.0, 400.0)}[name]


class ExtendedParametrization:
    """The base design vector followed by the identified parameters of one effect (linear)."""

    def __init__(self, base: Parametrization, effect: str, peak_force: float):
        self.base, self.effect = base, effect
        self.extra = list(EFFECT_IDENTIFIED[effect])
        self.extra_bounds = [search_bounds(n, peak_force) for n in self.extra]
        self.dimension = base.dimension + len(self.extra)
        self.names = base.names + self.extra

    def to_params(self, z) -> dict:
        z = np.clip(np.asarray(z, dtype=float), 0.0, 1.0)
        p = self.base.to_params(z[: self.base.dimension])
        for i, (n, (lo, hi)) in enumerate(zip(self.extra, self.extra_bounds)):
            p[n] = lo + z[self.base.dimension + i] * (hi - lo)
        return p

    def from_params(self, params: dict) -> np.ndarray:
        zb = self.base.from_params(params)
        ze = [(params.get(n, 0.0) - lo) / (hi - lo) for n, (lo, hi) in zip(self.extra, self.extra_bounds)]
        return np.concatenate([zb, np.clip(ze, 0.0, 1.0)])

    def describe(self) -> str:
        return f"{self.base.describe()}; plus {', '.join(self.extra)} (linear within the search bounds)"


@dataclass
class DiagnosisSettings:
    """Settings of a diagnosis run (units in the names)."""

    fit_rate_hz: float = 200.0
    warmup_s: float = 0.5
    workers: int = 2
    engine: str = "fmu"
    seed: int = 0
    base_iterations: int = 30
    base_polish_jacobians: int = 100  # a cap: the base refinement stops when converged
    polish_jacobians: int = 16  # per candidate, split between the two starts
    grid_points: int = 7
    guess_start: bool = True
    profile_steps: int = 8
    final_jacobians: int = 100  # continued refit of the leading candidate: a cap, it stops when converged
    candidates: tuple = CANDIDATES
    extra: dict = field(default_factory=dict)


def _split_mse(residual: np.ndarray | None, lengths: list[int]) -> list[tuple[float, float]]:
    """(MSE [N^2], AME [N]) per test from a concatenated residual vector."""
    if residual is None:
        return [(math.inf, math.inf)] * len(lengths)
    out, k = [], 0
    for n in lengths:
        r = residual[k:k + n]
        out.append((float(r @ r) / n, float(np.mean(np.abs(r)))))
        k += n
    return out


def _grid(lo: float, hi: float, n: int) -> list[float]:
    """Candidate values for the line search: both signs when the range straddles zero."""
    if lo < 0.0 < hi:
        return list(np.linspace(lo, hi, 2 * (n // 2) + 1))
    return [lo + (hi - lo) * f for f in np.geomspace(0.02, 1.0, n)]


def _base_jacobian(eid: Engine, par: Parametrization, z0: np.ndarray, step: float = 1e-4):
    """SVD (U, s, Vt) of the identification residual's Jacobian [N per scaled unit] with respect
    to the scaled base coordinates at z0 (forward differences, one parallel batch of
    dimension + 1 runs); None when the base cannot be simulated."""
    steps = np.where(z0 + step <= 1.0, step, -step)
    pts = [z0] + [z0 + np.eye(len(z0))[i] * steps[i] for i in range(len(z0))]
    res = eid.residuals_batch([par.to_params(p) for p in pts])
    if res[0] is None:
        return None
    cols = [(r - res[0]) / h if r is not None else np.zeros_like(res[0]) for r, h in zip(res[1:], steps)]
    return np.linalg.svd(np.column_stack(cols), full_matrices=False)


def _refit(eid: Engine, ext: ExtendedParametrization, z0: np.ndarray, sse0: float, jac_svd,
           settings: DiagnosisSettings, jacobians: int) -> tuple[np.ndarray, float, int]:
    """Profile line search on the effect parameter(s) from z0 (identification SSE sse0 [N^2]),
    then a joint polish of at most ``jacobians`` Jacobians; returns (z, fitness G = N / SSE,
    evaluations).

    Line search: for each grid value, the effect parameter is set with the base fixed, then the
    base is re-balanced (what it had absorbed of the effect) by Levenberg-Marquardt steps with the
    base Jacobian ``jac_svd`` at z0 kept fixed (at most ``profile_steps`` batches, while the fit
    improves by more than 1 %; none when ``jac_svd`` is None); the best point seen starts the
    polish.
    """
    dim = ext.base.dimension
    pts = []
    for i, (lo, hi) in enumerate(ext.extra_bounds):
        for val in _grid(lo, hi, settings.grid_points):
            z = z0.copy()
            z[dim + i] = (val - lo) / (hi - lo)
            pts.append(z)
    res = eid.residuals_batch([ext.to_params(z) for z in pts])
    evals = len(pts)
    if jac_svd is not None:
        u, sv, vt = jac_svd
        # Levenberg-Marquardt with the fixed base Jacobian, per grid value: a step that does not
        # lower the SSE is retried with 10x the damping, a successful one relaxes it 3x
        active = [[z, r, float(r @ r), (1e-3 * sv[0]) ** 2] for z, r in zip(pts, res) if r is not None]
        for _ in range(settings.profile_steps):
            trial = []
            for z, r, _, lam in active:
                zc = z.copy()
                zc[:dim] = np.clip(z[:dim] - vt.T @ ((sv / (sv * sv + lam)) * (u.T @ r)), 0.0, 1.0)
                trial.append(zc)
            res_t = eid.residuals_batch([ext.to_params(z) for z in trial])
            evals += len(trial)
            pts += trial
            res += res_t
            still = []
            for a, zc, rc in zip(active, trial, res_t):
                sse_c = float(rc @ rc) if rc is not None else math.inf
                if sse_c < a[2]:
                    if sse_c > 0.99 * a[2]:
                        continue  # converged: less than 1 % gain
                    still.append([zc, rc, sse_c, a[3] / 3.0])
                elif a[3] < 1e3 * sv[0] ** 2:
                    still.append([a[0], a[1], a[2], a[3] * 10.0])
            active = still
            if not active:
                break
    sse = [float(r @ r) if r is not None else math.inf for r in res]
    k = int(np.argmin(sse))
    z_start = pts[k] if sse[k] < sse0 else z0
    z, g, n, _ = polish(eid, ext, z_start, max_jacobians=jacobians, log=lambda m: None)
    return z, g, evals + n


def cross_check(ranking: list[dict], evidence: dict) -> list[dict]:
    """Mark a fitted force-channel delay that disagrees (beyond a factor 3, or in sign) with the
    delay the base model's residual shows (``evidence['effects']['time_delay']['value']`` [s]) as
    not resolved; return the rows so marked."""
    ev_delay = ((evidence or {}).get("effects", {}).get("time_delay") or {}).get("value")
    marked = []
    for r in ranking:
        fitted = r["parameters"].get("time_delay", 0.0) if r["effect"] == "time_delay" else 0.0
        if fitted > 0.0:
            agrees = ev_delay is not None and ev_delay > 0 and 1 / 3 <= fitted / ev_delay <= 3
            r["evidence_agrees"] = bool(agrees)
            if not agrees:
                r["resolved"] = False
                marked.append(r)
    return marked


def decide(ranking: list[dict]) -> tuple[str, dict, list[dict]]:
    """(cause, its ranking row, rows that scored enough but whose force is below the noise).

    A cause is the best-scoring extension whose score exceeds ACCEPT_SCORE against the base
    refitted alike AND whose force contribution is resolved (at or above the measurement noise);
    otherwise 'none' (with the best row of the ranking)."""
    ranked = sorted((r for r in ranking if r["effect"] != "none"), key=lambda r: -r["score"])
    named = [r for r in ranked if r["score"] > ACCEPT_SCORE and r["resolved"]]
    unresolved = [r for r in ranked if r["score"] > ACCEPT_SCORE and not r["resolved"]]
    if named:
        return named[0]["effect"], named[0], unresolved
    return "none", next((r for r in ranking if r["effect"] == "none"), ranking[0]), unresolved


def diagnose(identification: list[RigTest], validation: list[RigTest], out: Path,
             settings: DiagnosisSettings | None = None, *, base_params: dict | None = None, log=print) -> dict:
    """Run the diagnosis and write ``diagnosis.json`` (and figures, extended FMU) into ``out``."""
    from .fit import FitSettings, data_digest, identify, initial_guess, to_signals, validation_run

    settings = settings or DiagnosisSettings()
    if not identification or not validation:
        raise ValueError("the diagnosis needs identification AND validation tests (the decision is held-out gain)")
    out = Path(out)
    (out / "checkpoints").mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    prep_id = [prepare(t, settings.fit_rate_hz) for t in identification]
    prep_val = [prepare(t, settings.fit_rate_hz) for t in validation]
    sig_id = [to_signals(p, settings.warmup_s) for p in prep_id]
    sig_val = [to_signals(p, settings.warmup_s) for p in prep_val]
    peak = max(float(np.abs(s.force[s.mask]).max()) for s in sig_id)
    par = Parametrization("lumped", "improved", force_limit=float(f"{1.5 * peak:.2g}"))
    engine_path = None
    if settings.engine == "fmu":
        from build_fmu import ensure_fmu

        engine_path = ensure_fmu("lumped")

    if base_params is None:
        log("diagnosis: identifying the base lumped model ...")
        fs = FitSettings(models=("lumped",), fit_rate_hz=settings.fit_rate_hz, warmup_s=settings.warmup_s,
                         iterations=settings.base_iterations, workers=settings.workers, seed=settings.seed,
                         engine=settings.engine, polish_jacobians=settings.base_polish_jacobians)
        base_params, _ = identify("lumped", sig_id, fs, par, out / "checkpoints" / "diagnosis_base.json",
                                   data_digest(identification), log)
    base = defaults("lumped")
    base.update({k: v for k, v in base_params.items() if k in base})
    guess = {**defaults("lumped"), **initial_guess("lumped", sig_id, par)}
    for p in EFFECT_PARAMETERS:  # the base model has every effect off
        base[p.name] = guess[p.name] = p.default

    # measurement noise of the force [N] within the fit band, from the spectrum of the measured force
    # (tuner.metrics.noise_std; broadband signal such as the harmonics of a characteristic's kinks
    # biases it high, the conservative side); white noise keeps the share fit_rate / sample_rate of
    # its power after the anti-aliased resampling to the fit rate. The base model's residual is no
    # better a source: its model-form error is broadband at the velocity reversals (measured: 10x the
    # noise on lumped-damper data). An effect whose force is below the noise is not resolved.
    noise = float(np.median([noise_std(t.force, t.sample_rate) * math.sqrt(min(1.0, settings.fit_rate_hz / t.sample_rate))
                             for t in identification]))
    log(f"diagnosis: force measurement noise about {noise:.1f} N rms in the {settings.fit_rate_hz / 2:g} Hz fit band "
        f"(from the spectrum of the identification tests)")
    kw = dict(engine=settings.engine, workers=settings.workers, fmu_path=engine_path)
    lengths = [int(s.mask.sum()) for s in sig_val]
    n_val = sum(lengths)
    ranking = []
    with Engine("lumped", sig_id, **kw) as eid, Engine("lumped", sig_val, **kw) as ev:
        r_base_val = ev.residuals_batch([base])[0]
        mse_base = float(r_base_val @ r_base_val) / n_val
        sse_base_id = eid.sse_batch([base])[0]
        log(f"diagnosis: base model RMSE identification {math.sqrt(sse_base_id / eid.n_samples):.1f} N, "
            f"validation {math.sqrt(mse_base):.1f} N")

        def _held_out(effect, params, extra, g, evals, mse_ref) -> dict:
            """Ranking entry of a refitted model: validation MSE/AME, score against the validation
            MSE ``mse_ref`` [N^2] of the refitted base, and the effect's force contribution [N rms]
            on the identification tests (the fitted model minus the same with the effect off)."""
            r_val = ev.residuals_batch([params])[0]
            per_test = _split_mse(r_val, lengths)
            mse = math.inf if r_val is None else float(r_val @ r_val) / n_val
            ratio = mse / mse_ref
            score = -math.log(ratio) - PENALTY_PER_PARAMETER * len(extra) if math.isfinite(ratio) else -math.inf
            values = {n: params[n] for n in extra}
            contribution = 0.0
            if extra:
                off = {**params, **{n: 0.0 for n in extra}}
                r_on, r_off = eid.residuals_batch([params, off])
                if r_on is not None and r_off is not None:
                    contribution = float(np.sqrt(np.mean((r_off - r_on) ** 2)))
            return {"effect": effect, "score": score, "validation_mse": mse,
                    "validation_mse_change_pct": 100 * (ratio - 1),
                    "identification_rmse_n": 1 / math.sqrt(g) if g > 0 else math.inf,
                    "parameters": values, "units": {n: UNITS[n] for n in values},
                    "effect_rms_n": contribution, "resolved": bool(contribution >= noise) if extra else True,
                    "validation": {s.name: {"mse": m, "ame": a} for s, (m, a) in zip(sig_val, per_test)},
                    "evaluations": int(evals)}

        refits = {}
        jac_base = _base_jacobian(eid, par, par.from_params(base))  # shared by every candidate
        # 'none' is a candidate like the others: the base model refitted from the same starts with
        # the same local effort (an unfinished base fit would otherwise be credited to any effect)
        starts = [(base, sse_base_id, jac_base)] + ([(guess, math.inf, None)] if settings.guess_start else [])
        share = max(1, settings.polish_jacobians // len(starts))  # the Jacobian budget, split
        z_none, g_none, ev_none = None, -math.inf, 0
        for start, _, _ in starts:
            z, g_s, n, _ = polish(eid, par, par.from_params(start), max_jacobians=share, log=lambda m: None)
            ev_none += n
            if g_s > g_none:
                z_none, g_none = z, g_s
        r_none = ev.residuals_batch([par.to_params(z_none)])[0]
        mse_none = float(r_none @ r_none) / n_val if r_none is not None else mse_base
        none_row = _held_out("none", par.to_params(z_none), [], g_none, ev_none, mse_none)
        log(f"  {'none':14s} (base refitted alike)  identification RMSE {none_row['identification_rmse_n']:.1f} N, "
            f"validation MSE {100 * (mse_none / mse_base - 1):+6.1f} % vs the base fit")
        for effect in settings.candidates:
            ext = ExtendedParametrization(par, effect, peak)
            # the fitted base may have absorbed part of the effect into its tables: a profile line
            # search re-balances it (``_refit``); a second start from the data-driven initial guess,
            # which has not absorbed it, is kept when its refit fits the identification data better
            best_z, g, evals = None, -math.inf, 0
            for start, sse_start, svd in starts:
                z, g_s, n = _refit(eid, ext, ext.from_params(start), sse_start, svd, settings, share)
                evals += n
                if g_s > g:
                    best_z, g = z, g_s
            row = _held_out(effect, ext.to_params(best_z), ext.extra, g, evals, mse_none)
            refits[effect] = (ext, best_z, evals)
            ranking.append(row)
            log(f"  {effect:14s} " + ", ".join(f"{n} = {v:.4g} {UNITS[n]}" for n, v in row["parameters"].items())
                + f"  validation MSE {row['validation_mse_change_pct']:+6.1f} %  score {row['score']:+.3f}"
                + f"  effect {row['effect_rms_n']:.3g} N rms{'' if row['resolved'] else ' (below the noise)'}")
        # the leading candidate's refit is continued to convergence (absorbed effects converge slowly),
        # and so is the base refit, so that the continuation is not credited to the effect
        lead = max(ranking, key=lambda r: r["score"] if r["resolved"] else -math.inf)
        if lead["score"] > ACCEPT_SCORE and lead["resolved"] and settings.final_jacobians > 0:
            z_none, g_none, n, _ = polish(eid, par, z_none, max_jacobians=settings.final_jacobians,
                                          log=lambda m: None)
            r_none = ev.residuals_batch([par.to_params(z_none)])[0]
            mse_none = float(r_none @ r_none) / n_val if r_none is not None else mse_none
            none_row = _held_out("none", par.to_params(z_none), [], g_none, ev_none + n, mse_none)
            ext, z, evals = refits[lead["effect"]]
            z, g, n, _ = polish(eid, ext, z, max_jacobians=settings.final_jacobians, log=lambda m: None)
            refits[lead["effect"]] = (ext, z, evals + n)
            ranking[ranking.index(lead)] = row = _held_out(lead["effect"], ext.to_params(z), ext.extra, g,
                                                           evals + n, mse_none)
            log(f"  {lead['effect']:14s} refined (base refit continued alike): " + ", ".join(
                f"{k} = {v:.4g} {UNITS[k]}" for k, v in row["parameters"].items())
                + f"  validation MSE {row['validation_mse_change_pct']:+6.1f} %  score {row['score']:+.3f}"
                + f"  identification RMSE {row['identification_rmse_n']:.1f} N (none: "
                + f"{none_row['identification_rmse_n']:.1f} N)")
    # residual analysis of the base model (evidence and figures)
    evidence, figures = {}, []
    try:
        from .residuals import TestResidual, evidence as residual_evidence, residual_figures

        tr = [TestResidual(p.name, p.role or "", p.time, p.stroke, p.stroke_velocity, p.force,
                           validation_run("lumped", base, s, settings.engine)[0], s.mask, s.temperature)
              for p, s in zip([*prep_id, *prep_val], [*sig_id, *sig_val])]
        evidence = residual_evidence(tr)
        figures = [str(Path(f).relative_to(out)) for f in residual_figures(tr, out / "figures")]
    except ImportError:  # residual analysis module not available
        pass

    # cross-check with the residual evidence: a force-channel delay must agree with the delay the
    # base model's residual shows (regression on -dF/dt); the refit alone can trade a delay for
    # table changes
    for r in cross_check(ranking, evidence):
        log(f"  time_delay {1e3 * r['parameters']['time_delay']:.3g} ms disagrees with the residual's delay: "
            f"not a cause")
    ranking.sort(key=lambda r: -r["score"])
    ranking.append(none_row)
    cause, best, unresolved = decide(ranking)
    # reported before/after figures: the validation definition of Table 3 (tuner.fit.validation_run:
    # the FMU at its own steps), so that "before" is the Table 3 figure of the same base model
    after_params = refits[cause][0].to_params(refits[cause][1]) if cause != "none" else base
    validation = {}
    for s in sig_val:
        mb = validation_run("lumped", base, s, settings.engine)[1]
        ma = validation_run("lumped", after_params, s, settings.engine)[1] if cause != "none" else mb
        validation[s.name] = {"mse_before": mb["mse"], "ame_before": mb["ame"], "mse_after": ma["mse"],
                              "ame_after": ma["ame"], "mse_change_pct": 100 * (ma["mse"] / mb["mse"] - 1)}
    effect_parameters = {}
    if cause != "none":
        for n, v in best["parameters"].items():
            lo, hi = PLAUSIBLE[n]
            effect_parameters[n] = {"value": v, "unit": UNITS[n], "plausible_range": [lo, hi],
                                    "plausible": bool(lo <= abs(v) <= hi)}

    pooled_change = 100 * (math.exp(-(best["score"] + PENALTY_PER_PARAMETER * len(best["parameters"]))) - 1) \
        if cause != "none" else 0.0
    verdict = ("cause: none (no extension earns its parameters on held-out data"
               + ("; " + ", ".join(f"{r['effect']} scored {r['score']:+.3f} but " + (
                   "its delay disagrees with the residual's" if r.get("evidence_agrees") is False else
                   f"its force, {r['effect_rms_n']:.2g} N rms, is below the measurement noise ({noise:.2g} N)")
                   for r in unresolved)
                  if unresolved else "") + ")") if cause == "none" else (
        f"cause: {cause} (" + ", ".join(f"{n} = {fmt_quantity(v, UNITS[n])}" for n, v in best["parameters"].items())
        + f"); validation MSE {pooled_change:+.0f} % against the base refitted alike")
    result = {"cause": cause, "verdict": verdict, "ranking": ranking, "effect_parameters": effect_parameters,
              "validation": validation, "evidence": evidence, "figures": figures,
              "note": NOTES.get(cause, ""), "noise_std_n": noise,
              "settings": {**{k: v for k, v in settings.__dict__.items() if k != "extra"},
                           "penalty_per_parameter": PENALTY_PER_PARAMETER, "accept_score": ACCEPT_SCORE,
                           "elapsed_s": time.perf_counter() - t_start},
              "base_parameters": {k: base[k] for k in par.names}}
    (out / "diagnosis.json").write_text(json.dumps(result, indent=2, default=_json_default))
    if cause != "none":
        from build_fmu import build

        ext, z, _ = refits[cause]
        path = build("lumped", out / "fmu", start_values=ext.to_params(z),
                     filename=f"DamperLumped_{cause}_tuned.fmu")
        log(f"extended model exported: {path}")
    log(verdict)
    return result


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, tuple):
        return list(o)
    return str(o)
