"""The rig test that would pin down what the identification tests leave open (test design).

For a fitted model whose intervals (``tuner.identification.intervals``) say some parameters are not
determined (the targets), each candidate test is scored by how much it would shrink their intervals if it
were run on the rig and added to the identification:

* candidates (``candidate_tests``), every one within the rig's stroke amplitude, stroke velocity and force
  limits (the force the fitted model predicts), ``duration`` [s] long at ``rate`` [Hz], eased in over the
  first second: sines from 0.5 to 20 Hz at the largest amplitude the limits allow; small-amplitude,
  high-frequency sines (0.5 mm, or what the velocity limit allows, at 10-40 Hz); sweeps (a logarithmic
  chirp 0.5-20 Hz at the velocity limit); steps (raised-cosine ramps between +-amplitude at the velocity
  limit, a hold between them); and the campaign's manoeuvres, i.e. the identification tests' own strokes,
  run once more (``manoeuvres``);
* the information a candidate adds: J_c, the Jacobian of the model's force on the candidate's stroke
  (prepared as the fit prepares a test: differentiated, resampled to the fit rate, the warm-up left out)
  with respect to the identification's coordinates u at the fitted point (``residual_jacobian``: forward
  differences, one simulation per coordinate), over the residual's variance s^2 (the fit's residual rms)
  and its correlation time tau (the fit's, in samples: each sample worth 1/tau of an independent one):
  I_c = J_c^T J_c / (s^2 tau);
* the information the fit has: the inverse of its covariance in u on the resolved coordinates; a
  coordinate without finite variance gets 12, that of a uniform distribution over its bounds (variance
  1/12), so "before" is the bounds and "after" is finite;
* the representation shift (``tuner.identification.intervals``: the force of the model with 10x finer
  internal steps on the stroke with the resampler's ripple undone, minus the identification's, projected
  on the parameters by a Gauss-Newton step), which the intervals hold beside the statistical error: d_c,
  the candidate's difference (``representation_difference``, the fit's own definition, on the candidate's
  prepared stroke); the fit's shift s_0 in u (``LocalCovariance.shift``); the combined fit's shift
  (``combined_shift``) is the Gauss-Newton projection of the stacked differences [d_0; d_c] on the stacked
  Jacobians, weighted per sample by 1/(s^2 tau) as the information is: s' = (I_0 + I_c)^-1 (I_0 s_0 +
  J_c^T d_c / (s^2 tau)) on the coordinates not held (``held_coordinates``: those at a bound, except one
  the fit leaves there undetermined and the candidate determines, which moves where the candidate puts it;
  and those the candidate leaves without information, an interval wider than the bounds; I_0 s_0 stands for
  J_0^T d_0 / (s^2 tau), exact where the fit's covariance is the textbook one, the block sandwich
  differing from it by the residual's colour);
* after: Sigma' = (I_0 + I_c)^-1; each parameter's standard error std' and shift s' by the delta method
  (G = d theta / d u); the expected 95 % interval width before and after as the intervals make it
  (``classify``: 2 Z95 sqrt(std^2 + s^2), log-scaled in the logarithm, clipped to the bounds), each
  target's shrink factor; the score (D-optimal on the targets) on the total covariance Sigma + s s^T (the
  shift as a rank-one term: each target's variance std^2 + s^2, the interval's half-width over Z95, and the
  covariance the draws carried to the vehicle use): 1/2 ln det C_T - 1/2 ln det C'_T, the logarithm of the
  factor by which the targets' joint region shrinks in volume. The shift is in the score, not only in the
  widths, because a candidate the 1 ms internal steps represent poorly (a fast sine moves the masses by
  several standard errors, docs/identification.md) buys a statistical width its shift then undoes: ranked
  on the statistical covariance alone it would win on a promise the refit does not keep. Candidates are
  ranked by the score; each also states the largest-eigen-direction gain (the worst-determined combination
  of targets: the largest eigenvalue of C_T over that of C'_T).

The prediction is linear (at the fit, with the fit's residual level): a parameter the new test pins down
moves the fit, and with it the Jacobian. Units: SI inside; parameters in their units of
``damper_fmu.parameters``; strokes in m, velocities in m/s, forces in N.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import pandas as pd

from damper_dataset.writer import write_dataset
from damper_fmu.fmu import ensure_fmu
from damper_fmu.parameters import MODEL_PARAMETERS
from tuner import strict_json
from tuner.data.reading import RigTest
from tuner.identification.engine import IDENTIFICATION_STEP, IDENTIFICATION_TOLERANCE, Engine, fastest_engine
from tuner.identification.intervals import (DETERMINED_WIDTH, ModelIntervals, classify, free_coordinates,
                                             representation_difference, residual_jacobian)
from tuner.identification.problem import DataSettings, prepared_signals
from tuner.identification.runner import FmuRunner
from tuner.metrics import Z95
from tuner.progress import advance, stage

__all__ = ["RigLimits", "Candidate", "CandidateGain", "ModelDesign", "RankingOptions", "candidate_tests",
           "rank_candidates",
           "combined_shift", "held_coordinates",
           "design_from_folder", "limits_from_tests", "EASE_IN_S", "PRIOR_UNSEEN", "DESIGN_FOLDER", "NO_FIT_SHIFT",
           "NO_CANDIDATE_SHIFT"]

#: sub-folder of a fit output folder for the designed tests (``design_from_folder``)
DESIGN_FOLDER = "design"

#: candidates are eased in (raised cosine) over this time [s]
EASE_IN_S = 1.0
#: information [1/u^2] of a coordinate the fit does not see at all: a uniform distribution over its bounds
PRIOR_UNSEEN = 12.0
#: the candidates' notes when the promise cannot hold the representation shift in full
NO_FIT_SHIFT = ("parameters.json holds no representation shift in the identification's coordinates (written by an "
                "earlier version): the promised widths leave the fit's own shift out; refit to include it")
NO_CANDIDATE_SHIFT = ("the model's reference run (finer internal steps) failed on the candidates: their "
                      "representation shift is left out of the promise")


@dataclass(frozen=True)
class RigLimits:
    """What the rig can do: stroke_m: largest |stroke| [m]; velocity_m_s: largest |stroke velocity| [m/s];
    force_n: largest |force| [N] (checked on the fitted model's prediction)."""

    stroke_m: float
    velocity_m_s: float
    force_n: float

    def check(self) -> None:
        for name, v in (("stroke", self.stroke_m), ("velocity", self.velocity_m_s), ("force", self.force_n)):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"the rig's {name} limit must be a positive number, got {v} (--{name}-limit)")


@dataclass
class Candidate:
    """One candidate rig test: name (file-safe), kind ('sine', 'small-amplitude sine', 'sweep', 'step',
    'manoeuvre'), description, time [s], stroke [m] at the rig's rate."""

    name: str
    kind: str
    description: str
    time: np.ndarray
    stroke: np.ndarray

    @property
    def peak_velocity(self) -> float:
        """Largest |stroke velocity| [m/s] (central differences)."""
        return float(np.max(np.abs(np.gradient(self.stroke, self.time))))

    def rig_test(self) -> RigTest:
        """The candidate as a rig test without a measured force (zeros): what the fit's preparation takes."""
        rate = (self.time.size - 1) / (self.time[-1] - self.time[0])
        return RigTest(name=self.name, role="identification", scenario=self.description, time=self.time,
                       stroke=self.stroke, force=np.zeros_like(self.stroke), sample_rate=rate)


@dataclass
class CandidateGain:
    """A candidate's expected effect on a fitted model's intervals (module docstring): score [nats] (D-optimal
    on the targets), eigen_gain (the worst-determined target combination's variance before over after),
    widths_before/after: expected 95 % interval width per target [its unit] (before: the fit's; the bound
    range when it has no finite interval; both with the representation shift), peak_force_n: the fitted
    model's peak |force| on it [N]; note: what the promise leaves out, if anything ('' when nothing)."""

    candidate: Candidate
    score: float
    eigen_gain: float
    widths_before: dict = field(default_factory=dict)
    widths_after: dict = field(default_factory=dict)
    peak_force_n: float = 0.0
    note: str = ""

    def shrink(self, name: str) -> float:
        """Expected width after over before, for the target ``name``."""
        return self.widths_after[name] / self.widths_before[name]

    def to_dict(self) -> dict:
        return {"name": self.candidate.name, "kind": self.candidate.kind, "description": self.candidate.description,
                "score_nats": self.score, "volume_shrink_factor": math.exp(-self.score), "eigen_gain": self.eigen_gain,
                "peak_force_n": self.peak_force_n, "note": self.note,
                "peak_stroke_m": float(np.max(np.abs(self.candidate.stroke))),
                "peak_velocity_m_s": self.candidate.peak_velocity,
                "targets": {n: {"width_before": self.widths_before[n], "width_after": self.widths_after[n],
                                "shrink": self.shrink(n)} for n in self.widths_before}}


# -- the candidates -----------------------------------------------------------------------------------

def _eased(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``x`` eased in over EASE_IN_S by a raised cosine."""
    w = np.where(t < EASE_IN_S, 0.5 - 0.5 * np.cos(np.pi * np.clip(t / EASE_IN_S, 0.0, 1.0)), 1.0)
    return x * w


def candidate_tests(limits: RigLimits, *, duration: float = 10.0, rate: float = 1000.0,
                    manoeuvres: list | None = None) -> list[Candidate]:
    """The parametric candidates within ``limits`` and the ``manoeuvres`` ([(name, time [s], stroke [m])],
    those within the stroke limit) (module docstring)."""
    limits.check()
    t = np.arange(int(round(duration * rate)) + 1) / rate
    A, V = limits.stroke_m, limits.velocity_m_s
    out = []
    for f in (0.5, 1.0, 2.0, 4.0, 8.0, 12.0, 16.0, 20.0):
        a = min(A, 0.95 * V / (2 * np.pi * f))
        out.append(Candidate(f"sine_{f:g}Hz", "sine", f"sine {f:g} Hz, amplitude {1e3 * a:.3g} mm", t,
                             _eased(t, a * np.sin(2 * np.pi * f * t))))
    for f in (10.0, 20.0, 30.0, 40.0):
        a = min(5e-4, A, 0.95 * V / (2 * np.pi * f))
        out.append(Candidate(f"small_sine_{f:g}Hz", "small-amplitude sine",
                             f"small-amplitude sine {f:g} Hz, amplitude {1e3 * a:.3g} mm", t,
                             _eased(t, a * np.sin(2 * np.pi * f * t))))
    f0, f1 = 0.5, 20.0
    k = math.log(f1 / f0) / duration
    phase = 2 * np.pi * f0 * (np.exp(k * t) - 1.0) / k
    freq = f0 * np.exp(k * t)
    a = np.minimum(A, 0.95 * V / (2 * np.pi * freq))
    out.append(Candidate("sweep_0.5-20Hz", "sweep", f"logarithmic sweep {f0:g}-{f1:g} Hz at the velocity limit", t,
                         _eased(t, a * np.sin(phase))))
    for hold in (0.5, 1.0):
        out.append(_steps(t, A, V, hold))
    for name, tm, x in manoeuvres or []:
        if np.max(np.abs(x)) <= A * (1 + 1e-9):
            out.append(Candidate(f"repeat_{name}", "manoeuvre", f"the identification test {name} run again",
                                 np.asarray(tm, dtype=float) - tm[0], np.asarray(x, dtype=float)))
    return out


def _steps(t: np.ndarray, A: float, V: float, hold: float) -> Candidate:
    """Raised-cosine ramps between -0.8 A and +0.8 A at 0.9 of the velocity limit, ``hold`` [s] between."""
    a = 0.8 * A
    ramp = math.pi * a / (0.9 * V)  # the raised cosine's peak velocity is pi a / T
    period = 2 * (ramp + hold)
    ph = np.mod(t, period)
    up = np.clip(ph / ramp, 0, 1)
    down = np.clip((ph - ramp - hold) / ramp, 0, 1)
    x = np.where(ph < ramp + hold, a * -np.cos(np.pi * up), a * np.cos(np.pi * down))
    return Candidate(f"steps_hold{hold:g}s", "step", f"steps +-{1e3 * a:.3g} mm, ramps of {1e3 * ramp:.0f} ms, "
                     f"held {hold:g} s", t, _eased(t, x))


# -- the expected gain ----------------------------------------------------------------------------------

def _inverse(a: np.ndarray) -> np.ndarray:
    """The (pseudo-)inverse of the symmetric positive semi-definite ``a``, scaled to unit diagonal first:
    the coordinates' variances span twenty decades (a mass the tests do not see, a table point they do)."""
    d = np.sqrt(np.maximum(np.diag(a), 1e-300))
    return np.linalg.pinv(a / np.outer(d, d), rcond=1e-12, hermitian=True) / np.outer(d, d)


def _prior_information(iv: ModelIntervals) -> np.ndarray:
    """The fit's information [1/u^2] on every coordinate: its covariance inverted on the resolved ones,
    PRIOR_UNSEEN on the others."""
    local = iv.local
    d = len(local.coordinates)
    info = np.diag(np.full(d, PRIOR_UNSEEN))
    keep = [local.coordinates.index(c) for c in local.resolved]
    if keep:
        info[np.ix_(keep, keep)] = _inverse(local.matrix)
    return info


def _widths(cov_u: np.ndarray, shift_u: np.ndarray, G: np.ndarray, names: list, targets: list,
            iv: ModelIntervals) -> dict:
    """Expected 95 % widths [unit] of the targets from a covariance [u^2] and a representation shift [u] in u:
    the interval ``classify`` makes of the standard error and shift the delta method gives (G = d theta / d u;
    half-width Z95 sqrt(std^2 + s^2), log-scaled in the logarithm), clipped to the bounds."""
    cov, shift = G @ cov_u @ G.T, G @ shift_u
    out = {}
    for n in targets:
        i = names.index(n)
        p = iv.get(n)
        w = classify(n, p.unit, p.value, math.sqrt(max(cov[i, i], 0.0)), p.bounds, p.log_scale,
                     systematic=float(shift[i]))
        out[n] = w.high - w.low
    return out


def _fit_shift(iv: ModelIntervals) -> np.ndarray:
    """The fit's representation shift in u [u]: ``LocalCovariance.shift``, or zeros when parameters.json
    predates it (the promise then leaves the fit's own shift out, ``NO_FIT_SHIFT`` says so)."""
    local = iv.local
    return np.zeros(len(local.coordinates)) if local.shift is None else np.asarray(local.shift, dtype=float)


def held_coordinates(u: np.ndarray, cov_before: np.ndarray, cov_after: np.ndarray) -> list[int]:
    """The coordinates the combined shift holds (``combined_shift``), from the covariance on every coordinate
    without and with the candidate (``cov_before``/``cov_after`` [u^2]; 'determined': Z95 std_u at most
    ``DETERMINED_WIDTH`` of the range, the intervals' rule in u):

    * at a bound of [0, 1]: held, as the refinement holds it, except when the fit leaves it undetermined
      there and the candidate determines it: it sits at the bound for want of information, and the candidate
      decides where the refit puts it, usually inside (a mass fitted at 20 kg whose truth is 9 kg);
    * inside: held when its 95 % interval with the candidate is still wider than its bound range (2 Z95
      std_u >= 1): the tests do not place it (the refinement leaves it where it drifts, at a bound in the
      known-truth refits), and its linear shift, many times its range (-540 kg on a 1-20 kg mass), would
      only move the others through their correlation with it."""
    def determined(cov, i):
        return Z95 * math.sqrt(max(cov[i, i], 0.0)) <= DETERMINED_WIDTH

    free = set(free_coordinates(u, range(u.size)))
    return [i for i in range(u.size)
            if (i in free and 2.0 * Z95 * math.sqrt(max(cov_after[i, i], 0.0)) >= 1.0)
            or (i not in free and (determined(cov_before, i) or not determined(cov_after, i)))]


def combined_shift(info0: np.ndarray, shift0: np.ndarray, Jc: np.ndarray, dc: np.ndarray | None, weight: float,
                   held: list) -> np.ndarray:
    """The representation shift [u] of the fit with a candidate added: the Gauss-Newton projection of the
    stacked differences [d_0; d_c] [N] on the stacked Jacobians [J_0; J_c] [N/u], each sample weighted by
    ``weight`` = 1/(s^2 tau) [1/N^2] as the information is. The fit's part enters through its information
    I_0 [1/u^2] and shift s_0 [u] (J_0^T W J_0 = I_0 and J_0^T W d_0 = I_0 s_0 on the coordinates its step
    moved): s' = (I_0 + W J_c^T J_c)^-1 (I_0 s_0 + W J_c^T d_c) on the coordinates not ``held``
    (``held_coordinates``; 0 on those, as ``gauss_newton_step`` holds a coordinate at a bound). dc None: the
    candidate's difference unknown, taken as 0."""
    out = np.zeros(shift0.size)
    free = [i for i in range(shift0.size) if i not in set(held)]
    if not free:
        return out
    info = info0 + weight * Jc.T @ Jc
    rhs = info0 @ shift0 + (0.0 if dc is None else weight * Jc.T @ dc)
    out[free] = _inverse(info[np.ix_(free, free)]) @ rhs[free]
    return out


def _total(cov_u: np.ndarray, shift_u: np.ndarray) -> np.ndarray:
    """The total covariance in u [u^2]: the statistical one plus the shift as a rank-one term s s^T (each
    coordinate's variance std^2 + s^2, the intervals' half-width over Z95; the draws' covariance)."""
    return cov_u + np.outer(shift_u, shift_u)


@dataclass(frozen=True)
class RankingOptions:
    """How ``rank_candidates`` ranks: the candidates prepared at ``fit_rate_hz`` [Hz] with ``warmup_s`` [s] as the
    fit's tests; the ``targets`` (None: the parameters the intervals say are not determined); the rig's ``limits``
    (a candidate whose predicted peak force exceeds ``limits.force_n`` is left out; None: none); the
    identification ``engine`` (None: the fastest here); ``progress``: called with the share done (0-1)."""

    fit_rate_hz: float
    warmup_s: float
    targets: list | None = None
    limits: RigLimits | None = None
    engine: str | None = None
    progress: object = None


def rank_candidates(model: str, values: dict, iv: ModelIntervals, candidates: list[Candidate],
                    options: RankingOptions) -> list[CandidateGain]:
    """The ``candidates`` ranked by their expected gain on the targets of ``options`` (``RankingOptions``) of
    ``model`` fitted at ``values`` (SI) with the intervals ``iv`` (module docstring). ValueError when there is
    nothing to rank."""
    fit_rate_hz, warmup_s, targets = options.fit_rate_hz, options.warmup_s, options.targets
    limits, engine, progress = options.limits, options.engine, options.progress
    if iv.local is None:
        raise ValueError(f"{model}: no covariance in the identification's coordinates in parameters.json; refit "
                         "with this version")
    targets = list(targets) if targets is not None else iv.names_with("not determined")
    if not targets:
        raise ValueError(f"{model}: every parameter is determined by the identification tests: nothing to design for")
    par = iv.local.parametrization(model, values)
    space = par.local_space()
    names = list(par.names)
    u0 = np.asarray(iv.local.u, dtype=float)
    info0 = _prior_information(iv)
    cov0 = _inverse(info0)
    shift0 = _fit_shift(iv)
    # as the fit prepares its tests (the differentiator's band from the data, as by default)
    _, signals = prepared_signals([c.rig_test() for c in candidates],
                                  DataSettings(fit_rate_hz=fit_rate_hz, warmup_s=warmup_s))
    with Engine(model, signals, engine=engine or fastest_engine(), workers=0) as eng:
        r, J, G, failed = residual_jacobian(eng, space, u0, names)
        d = representation_difference(eng, space.to_params(u0))  # the candidates' d_c, the fit's definition
    if failed:
        raise ValueError(f"{model}: the fitted model could not be simulated on the candidates next to the fit")
    note = "; ".join(t for t, missing in ((NO_FIT_SHIFT, iv.local.shift is None), (NO_CANDIDATE_SHIFT, d is None))
                     if missing)
    before = _widths(cov0, shift0, G, names, targets, iv)
    weight = 1.0 / (iv.residual_rms_n ** 2 * max(iv.correlation_time_s * fit_rate_hz, 1.0))
    T = [names.index(n) for n in targets]
    a0 = (G @ _total(cov0, shift0) @ G.T)[np.ix_(T, T)]
    gains, start = [], 0
    for k, (c, sig) in enumerate(zip(candidates, signals)):
        n = int(sig.mask.sum())
        span = slice(start, start + n)
        start += n
        peak = float(np.max(np.abs(r[span])))
        if limits is not None and peak > limits.force_n:
            continue
        cov1 = _inverse(info0 + weight * J[span].T @ J[span])
        shift1 = combined_shift(info0, shift0, J[span], None if d is None else d[span], weight,
                                held_coordinates(u0, cov0, cov1))
        a1 = (G @ _total(cov1, shift1) @ G.T)[np.ix_(T, T)]
        score = 0.5 * (np.linalg.slogdet(a0)[1] - np.linalg.slogdet(a1)[1])
        eigen = float(np.linalg.eigvalsh(a0)[-1] / max(np.linalg.eigvalsh(a1)[-1], 1e-300))
        gains.append(CandidateGain(c, float(score), eigen, before, _widths(cov1, shift1, G, names, targets, iv), peak,
                                   note))
        if progress is not None:
            progress((k + 1) / len(candidates))
    if not gains:
        raise ValueError(f"{model}: every candidate's predicted force exceeds the rig's force limit "
                         f"{limits.force_n:.0f} N (--force-limit)")
    return sorted(gains, key=lambda g: -g.score)


# -- a fit output folder --------------------------------------------------------------------------------

@dataclass
class ModelDesign:
    """The ranked candidates of one fitted model: targets (the parameters not determined), ranked
    (``CandidateGain``, best first), written: the files of the best ones (relative to the design folder)."""

    model: str
    targets: list
    ranked: list
    written: list = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"model": self.model, "targets": list(self.targets), "written": list(self.written),
                "ranked": [g.to_dict() for g in self.ranked]}


def limits_from_tests(arrays, names: list[str]) -> RigLimits:
    """What the rig already did in the identification tests ``names`` of ``simulations.npz`` (``arrays``):
    their largest |stroke| [m], |stroke velocity| [m/s] and |force| [N]."""
    if not names:
        raise ValueError("no identification test in the folder to take the rig's limits from; give them "
                         "(--stroke-limit, --velocity-limit, --force-limit)")
    x = [np.asarray(arrays[f"{n}__stroke"]) for n in names]
    t = [np.asarray(arrays[f"{n}__time"]) for n in names]
    f = [np.asarray(arrays[f"{n}__force"]) for n in names]
    return RigLimits(max(float(np.max(np.abs(a))) for a in x),
                     max(float(np.max(np.abs(np.gradient(a, b)))) for a, b in zip(x, t)),
                     max(float(np.max(np.abs(a))) for a in f))


def design_from_folder(folder, out=None, *, limits: RigLimits | None = None, top: int = 3, duration: float = 10.0,
                       rate: float = 1000.0, models: list | None = None, log=print) -> dict:
    """Rank the candidate tests for every fitted model of the fit output folder ``folder`` with parameters not
    determined (``models``: only these), write the ``top`` best of each as a dataset (``out``, default
    ``folder/design``: one CSV per test in the ``damper-rig-dataset/1`` format whose ``force`` column is the
    fitted model's prediction, for the rig's force limit; the rig records the measured force in its place),
    ``design.json`` there with every candidate's expected gain; return design.json's content. ``limits``:
    the rig's (default: what the identification tests reached, ``limits_from_tests``). ``log``: progress lines
    (a ``tuner.progress.JobProgress`` also gets a stage 'design MODEL' per model)."""
    folder = Path(folder)
    for name in ("parameters.json", "metrics.json", "simulations.npz"):
        if not (folder / name).is_file():
            raise FileNotFoundError(f"--from {folder}: no {name} (not a fit output folder)")
    params = strict_json.loads((folder / "parameters.json").read_text())
    settings = strict_json.loads((folder / "metrics.json").read_text())["settings"]
    with np.load(folder / "simulations.npz") as arrays:
        ident = list(settings.get("identification_tests") or [])
        limits = limits or limits_from_tests(arrays, ident)
        manoeuvres = [(n, arrays[f"{n}__time"], arrays[f"{n}__stroke"]) for n in ident]
    candidates = candidate_tests(limits, duration=duration, rate=rate, manoeuvres=manoeuvres)
    log(f"design: {len(candidates)} candidate tests within the rig's limits (stroke {1e3 * limits.stroke_m:.3g} mm, "
        f"velocity {1e3 * limits.velocity_m_s:.3g} mm/s, force {limits.force_n:.0f} N)")
    designs = []
    for model, entry in params.items():
        if models and model not in models:
            continue
        if not entry.get("intervals"):
            log(f"design: {model}: no intervals ({entry.get('intervals_note', 'not computed')}); skipped")
            continue
        iv = ModelIntervals.from_dict(model, entry["intervals"])
        targets = iv.names_with("not determined")
        if not targets:
            log(f"design: {model}: every parameter determined; nothing to design")
            continue
        stage(log, f"design {model}")
        log(f"design: {model}: {len(targets)} parameters not determined ({', '.join(targets)}); ranking ...")
        ranked = rank_candidates(model, entry["values"], iv, candidates, RankingOptions(
            fit_rate_hz=settings["fit_rate_hz"], warmup_s=settings["warmup_s"], limits=limits, engine=fastest_engine(),
            progress=lambda share: advance(log, share)))
        if ranked[0].note:
            log(f"design: {model}: {ranked[0].note}")
        designs.append(ModelDesign(model, targets, ranked))
    return _write_design(folder, Path(out) if out else folder / DESIGN_FOLDER, designs, limits, top, log)


def _predicted_force(model: str, values: dict, c: Candidate) -> np.ndarray:
    """The fitted model's force [N] on the candidate's stroke at the rig's rate (its FMU, the identification's
    internal step)."""
    names = {p.name for p in MODEL_PARAMETERS[model]}
    runner = FmuRunner(ensure_fmu(model), max_internal_step=IDENTIFICATION_STEP, tolerance=IDENTIFICATION_TOLERANCE)
    try:
        return runner.run(c.time, c.stroke, np.gradient(c.stroke, c.time), {k: v for k, v in values.items() if k in names})
    finally:
        runner.close()


def _write_design(folder: Path, out: Path, designs: list, limits: RigLimits, top: int, log) -> dict:
    """The best ``top`` candidates of each design as a dataset in ``out`` and ``design.json`` (module docstring)."""
    params = strict_json.loads((folder / "parameters.json").read_text())
    tests, seen = [], set()
    for d in designs:
        for g in d.ranked[:top]:
            c = g.candidate
            d.written.append(f"{c.name}.csv")
            if c.name in seen:
                continue
            seen.add(c.name)
            force = _predicted_force(d.model, params[d.model]["values"], c)
            gains = "; ".join(f"{n} x{g.shrink(n):.2g}" for n in d.targets)
            tests.append({"name": c.name, "role": "identification",
                          "scenario": f"designed test: {c.description} (expected 95 % widths, {d.model} model: {gains})",
                          "frame": pd.DataFrame({"time": c.time, "stroke": c.stroke, "force": force}),
                          "expected_score_nats": g.score})
            log(f"design: {d.model}: {c.name}: {c.description}; expected widths after/before: {gains}")
    data = {"from": str(folder), "limits": {"stroke_m": limits.stroke_m, "velocity_m_s": limits.velocity_m_s,
                                            "force_n": limits.force_n},
            "method": __doc__.split("\n\n")[1], "models": {d.model: d.to_dict() for d in designs}}
    if tests:
        write_dataset(out, tests, "Designed rig tests: the candidates that would shrink the intervals of the "
                      "parameters the identification tests do not determine (the force column is the fitted "
                      "model's prediction; the rig records the measured force in its place)",
                      {"command": "python -m tuner design", "from": str(folder)}, overwrite=True)
    out.mkdir(parents=True, exist_ok=True)
    (out / "design.json").write_text(strict_json.dumps(data, indent=1))
    return data
