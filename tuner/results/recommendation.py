"""The one recommendation of a run: which model and which FMU to use, and why (issue 38).

``recommend(out_dir)`` reads the output folder -- ``metrics.json`` (per-model validation metrics and the
quality gate, ``tuner.identification.fit``) and ``diagnosis.json`` when a diagnosis ran
(``tuner.diagnosis.diagnose``) -- and returns a :class:`Recommendation`. The report's summary box
(``tuner.results.report``), the printed end summary and ``summary.json`` (``tuner.cli.summary``) all show
this one object, so they cannot disagree. Errors are in N (rms: the square root of the MSE pooled over
the tests' samples), AME in % of the test's peak measured force.

Rules, in order:

1. A diagnosis that failed (``diagnosis.json`` with ``failed_stage``): no recommendation and no verdict;
   the stage, the error, and ``--resume`` to continue.
2. Candidates: every fitted model with its tuned FMU ``fmu/<Model>_tuned.fmu``, its held-out error (the
   MSE pooled over the validation tests, the Table 3 definition the diagnosis chooses its base by; the
   identification tests when there is no validation test) and the quality gate (``metrics.json``
   ``quality``: worst held-out AME at most ``gate_pct`` % of that test's peak force). A finished
   diagnosis puts its final model in place of its base's: the base form it kept (``base_model``) with
   its named causes, exported as ``fmu/<Model>_<causes>_tuned.fmu``, scored by the diagnosis's 'after'
   figures and gated on the same peaks. Causes that belong to the acquisition, not the damper
   (``ACQUISITION_CAUSES``: time_delay, preload; the diagnosis's notes) are not for a co-simulation model:
   with one of them named, the candidate is the base's plain tuned FMU and the user is told to fix the
   acquisition.
3. Recommended: the candidate with the lowest held-out error among those that pass the gate. The
   diagnosis's model comes first on a tie; the linear Maxwell model is recommended only when it validates
   better than every nonlinear model that passes. When the linear Maxwell model passes and is as good
   as the recommended nonlinear one (its held-out MSE within a factor exp(ACCEPT_SCORE) of it: less than
   the gain the diagnosis asks of an added effect), it is said plainly, and so is a nonlinear model that
   passes without validating better than a recommended Maxwell model.
4. Nothing passes: no model describes the data; the closest (the lowest worst held-out AME) is named,
   not recommended. Without metrics.json (a diagnosis on its own) the gate is not evaluated: the
   diagnosis's model is recommended and the text says the gate was not checked.
5. A residual the diagnosis leaves above its floor (``unexplained``) qualifies the recommendation. On a
   settled refit (``fit_converged`` not false: the diagnosis's own reading) it is a model-form error: the
   model serves comparative studies, not absolute figures (for a railway damper: stability margins);
   look at the residual figures, consider another form. On a refit that did not converge it may be an
   unfinished fit: fit again with a larger budget.

The railway wording (stability margins) is used unless the data was read as another damper class
(``--damper-class any``, recorded per test in ``metrics.json``; see :func:`railway_damper`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

from damper_fmu.fmu import SLAVES
from damper_fmu.parameters import MODEL_KINDS
from tuner.data.reading import RAILWAY_DAMPER_CLASSES
from tuner.diagnosis.diagnose import ACCEPT_SCORE, ACQUISITION_CAUSES, NOTES
from tuner.formatting import eng
from tuner.identification.fit import QUALITY_AME_PCT, quality_gate
from tuner.metrics import pooled_mse
from tuner.results.html import esc
from tuner import strict_json

__all__ = ["Candidate", "Recommendation", "recommend", "railway_damper", "recommendation_html", "LINEAR_MODEL"]

#: the linear Maxwell element of today's multibody codes
LINEAR_MODEL = "maxwell"
#: how the recommendation names a model in a sentence
MODEL_NAME = {"lumped": "lumped model", "maxwell": "linear Maxwell model",
              "maxwell_table": "Maxwell model with a table dashpot", "twochamber": "two-chamber model"}
#: recommended: a model passes the gate; nothing_passes: none does (the closest named); diagnosis_failed: no
#: verdict (--resume); no_results: neither metrics.json nor diagnosis.json
STATUSES = ("recommended", "nothing_passes", "diagnosis_failed", "no_results")


@dataclass(frozen=True)
class Candidate:
    """A model the user could take: ``model`` with the named ``causes`` (effect names), its FMU in the output
    folder, its error (``mse_n2`` [N^2], pooled over the held-out tests, or the identification tests when
    ``held_out`` is false) and the quality gate (``worst_ame_pct`` [% of the test's peak force] on
    ``worst_test`` against ``gate_pct`` [%]; None: not evaluated). ``from_diagnosis``: the diagnosis's model."""

    model: str
    causes: tuple
    fmu: str
    mse_n2: float
    held_out: bool
    worst_ame_pct: float | None
    worst_test: str | None
    gate_pct: float
    from_diagnosis: bool = False

    @property
    def passes(self) -> bool | None:
        """Whether it passes the quality gate (None: not evaluated)."""
        return None if self.worst_ame_pct is None else bool(self.worst_ame_pct <= self.gate_pct)

    @property
    def rmse_n(self) -> float:
        """Its error as an rms [N]."""
        return math.sqrt(self.mse_n2) if self.mse_n2 >= 0 else math.nan

    @property
    def label(self) -> str:
        """'two-chamber model with friction + inertia'."""
        name = MODEL_NAME.get(self.model, f"{self.model} model")
        return name + (f" with {' + '.join(self.causes)}" if self.causes else "")

    def gate_text(self) -> str:
        """'worst held-out AME 3.1 % of peak force on val2 (gate 10 %)', or that it was not evaluated."""
        if self.worst_ame_pct is None:
            return "quality gate not evaluated"
        kind = "held-out" if self.held_out else "identification"
        return f"worst {kind} AME {self.worst_ame_pct:.3g} % of peak force on {self.worst_test} (gate {self.gate_pct:g} %)"

    def error_text(self) -> str:
        """'14.4 N rms', '1.04 kN rms'."""
        return f"{eng(self.rmse_n, 'N')} rms"

    def to_dict(self) -> dict:
        """The candidate in ``summary.json``'s ``recommendation.facts.candidates`` (error in N rms, AME in %)."""
        return {"model": self.model, "causes": list(self.causes), "label": self.label, "fmu": self.fmu,
                "error_rms_n": self.rmse_n, "held_out": self.held_out, "worst_ame_pct_of_peak": self.worst_ame_pct,
                "worst_test": self.worst_test, "gate_pct": self.gate_pct, "passes_gate": self.passes,
                "from_diagnosis": self.from_diagnosis}


@dataclass(frozen=True)
class Recommendation:
    """What to use and why. ``status``: one of STATUSES; ``model``/``causes``/``fmu`` (a path in the output
    folder): the recommended model, None when there is none; ``reason``: why, in one or two sentences;
    ``action``: what the user should do beside it ('' when nothing); ``closest``: the model nearest the
    gate when nothing passes; ``facts``: what it rests on (``to_dict``)."""

    status: str
    model: str | None
    causes: tuple
    fmu: str | None
    reason: str
    action: str
    facts: dict
    closest: Candidate | None = None

    def __post_init__(self):
        if self.status not in STATUSES:
            raise ValueError(f"recommendation status {self.status!r}: choose from {', '.join(STATUSES)}")

    def headline(self) -> str:
        """One line: 'use the two-chamber model with friction: fmu/DamperTwoChamber_friction_tuned.fmu'."""
        if self.status == "recommended":
            return f"use the {_label(self.model, self.causes)}: {self.fmu}"
        if self.status == "nothing_passes":
            return (f"none: no model describes this data (the closest is the {self.closest.label}, "
                    f"{self.closest.fmu})")
        if self.status == "diagnosis_failed":
            return "none: the diagnosis failed, no verdict (run the same command with --resume)"
        return "none: no fitted model and no diagnosis in this folder"

    def to_dict(self, out=None) -> dict:
        """The ``recommendation`` object of summary.json; ``out``: the output folder, for the FMU's full path."""
        full = str(Path(out) / self.fmu) if out is not None and self.fmu else self.fmu
        return {"status": self.status, "model": self.model, "causes": list(self.causes), "fmu": full,
                "fmu_in_folder": self.fmu,
                "fmu_exists": bool(out is not None and self.fmu and (Path(out) / self.fmu).is_file()),
                "headline": self.headline(), "reason": self.reason, "action": self.action,
                "closest": self.closest.to_dict() if self.closest else None, "facts": self.facts}


def _label(model: str, causes) -> str:
    """'two-chamber model with friction' (as ``Candidate.label``)."""
    return MODEL_NAME.get(model, f"{model} model") + (f" with {' + '.join(causes)}" if causes else "")


def _read(path: Path) -> dict | None:
    """A JSON file of the output folder (strict JSON), None when absent; ValueError naming it when unreadable."""
    if not path.exists():
        return None
    try:
        return strict_json.loads(path.read_text())
    except ValueError as exc:
        raise ValueError(f"{path} is not valid JSON: {exc}") from exc


def railway_damper(metrics: dict | None) -> bool:
    """Whether the data is a railway damper's: no test was read as a class other than yaw, primary or
    secondary (``metrics.json`` ``tests[*].damper_class``; a test without it, from a folder written before
    the class was recorded or not read from a file, counts as the default yaw damper)."""
    classes = {t.get("damper_class") for t in ((metrics or {}).get("tests") or {}).values()} - {None}
    return classes <= set(RAILWAY_DAMPER_CLASSES)


def _tuned_fmu(model: str, causes=()) -> str:
    """The FMU the job writes for ``model`` (extended by ``causes``), as a path in the output folder."""
    return f"fmu/{SLAVES.get(model, model)}_{''.join(c + '_' for c in causes)}tuned.fmu"


def _scored_tests(metrics: dict) -> tuple[list[str], bool]:
    """(the tests a model's error is pooled over, whether they are held out): the validation tests, else all."""
    tests = metrics.get("tests") or {}
    val = [n for n, t in tests.items() if t.get("role") == "validation"]
    return (val, True) if val else (list(tests), False)


def _fit_candidates(metrics: dict | None) -> list[Candidate]:
    """Every fitted model of ``metrics.json`` with its plain tuned FMU, error and quality gate."""
    if not metrics:
        return []
    tests = metrics.get("tests") or {}
    names, held_out = _scored_tests(metrics)
    fitted = {m for t in tests.values() for m in (t.get("models") or {})}
    models = [m for m in MODEL_KINDS if m in fitted] + sorted(fitted - set(MODEL_KINDS))
    quality = metrics.get("quality") or {}
    out = []
    for m in models:
        if not all(m in (tests[n].get("models") or {}) for n in names):
            continue  # not validated on every test: no comparable error
        q = quality.get(m) or quality_gate(tests, [m])[m]
        out.append(Candidate(m, (), _tuned_fmu(m), pooled_mse([tests[n]["models"][m] for n in names]), held_out,
                             q["worst_ame_pct_of_peak"], q["worst_test"], q["gate_pct"]))
    return out


def _diagnosed(diag: dict, metrics: dict | None, model: str, causes: tuple, which: str) -> Candidate:
    """The diagnosis's model from its validation figures (``which``: 'before' for the base, 'after' for
    the final model), pooled with the samples and gated on the peaks of ``metrics.json``'s same tests."""
    tests = (metrics or {}).get("tests") or {}
    rows, gate_tests = [], {}
    for name, v in (diag.get("validation") or {}).items():
        measured = next(iter(((tests.get(name) or {}).get("models") or {}).values()), None)
        rows.append({"mse": v[f"mse_{which}"], "n": measured["n"] if measured else 1})
        if measured:
            gate_tests[name] = {"role": "validation",
                                "models": {model: {"ame": v[f"ame_{which}"], "peak_measured": measured["peak_measured"]}}}
    gate = quality_gate(gate_tests, [model])[model] if rows and len(gate_tests) == len(rows) else None
    return Candidate(model, causes, _tuned_fmu(model, causes), pooled_mse(rows), True,
                     gate["worst_ame_pct_of_peak"] if gate else None, gate["worst_test"] if gate else None,
                     gate["gate_pct"] if gate else QUALITY_AME_PCT, from_diagnosis=True)


def _diagnosis_candidate(diag: dict, metrics: dict | None, fits: list[Candidate]) -> Candidate:
    """The diagnosis's final model: its base with the named causes, or the base's plain tuned FMU when a
    named cause belongs to the acquisition (or none was named)."""
    base = diag.get("base_model") or "lumped"
    causes = tuple(diag.get("causes") or ())
    plain = next((c for c in fits if c.model == base), None)
    if causes and not any(c in ACQUISITION_CAUSES for c in causes):
        return _diagnosed(diag, metrics, base, causes, "after")
    if plain is not None:
        return replace(plain, from_diagnosis=True)
    return _diagnosed(diag, metrics, base, (), "before")


def _source_text(best: Candidate, dc: Candidate | None, acquisition: tuple) -> str:
    """Where the recommended model comes from, for the reason's first sentence."""
    if best.from_diagnosis and best.causes:
        return f"the diagnosis's final model: the base form it kept on held-out data, with {' + '.join(best.causes)} named"
    if best.from_diagnosis and acquisition:
        return (f"the diagnosis's base form, without the {' + '.join(acquisition)} it named, which belongs to the "
                "acquisition, not the damper")
    if best.from_diagnosis:
        return "the diagnosis's base form, no cause named"
    if dc is None:
        return "the fitted model with the lowest held-out error among those that pass the quality gate; no diagnosis ran"
    if dc.passes is False:
        return (f"the diagnosis's {dc.label} does NOT pass the quality gate (worst held-out AME "
                f"{dc.worst_ame_pct:.3g} % of peak force on {dc.worst_test})")
    return f"it validates better than the diagnosis's {dc.label} ({dc.error_text()})"


def _maxwell_text(best: Candidate, candidates: list[Candidate]) -> tuple[str, bool | None]:
    """(a sentence comparing the recommended model with the linear Maxwell one, or with the best nonlinear
    one when Maxwell is recommended; whether Maxwell is as good: None when no such comparison)."""
    if best.model == LINEAR_MODEL:
        others = [c for c in candidates if c.model != LINEAR_MODEL and c.passes]
        if not others:
            return ("No nonlinear model passes the gate.", True) if len(candidates) > 1 else ("", None)
        nl = min(others, key=lambda c: c.mse_n2)
        return (f"The {nl.label} passes the gate too but does not validate better ({nl.error_text()} against "
                f"{best.error_text()}): the linear Maxwell element is as good for this damper."), True
    mx = next((c for c in candidates if c.model == LINEAR_MODEL), None)
    if mx is None or not mx.passes:
        return "", (None if mx is None else False)
    if math.log(mx.mse_n2 / best.mse_n2) <= ACCEPT_SCORE:
        return (f"The linear Maxwell model passes the gate too and validates as well ({mx.error_text()} against "
                f"{best.error_text()}): where a simulation takes only a linear element, {mx.fmu} is as good."), True
    return (f"The linear Maxwell model passes the gate too but validates worse ({mx.error_text()} against "
            f"{best.error_text()})."), False


def _acquisition_text(diag: dict, acquisition: tuple) -> str:
    """What to do when the diagnosis named a cause of the acquisition (its notes), and where the damper's own
    named causes are."""
    text = " ".join(f"The diagnosis names {c}, {NOTES.get(c, 'which belongs to the acquisition')}."
                    for c in acquisition) + " Then fit again."
    damper = [c for c in diag.get("causes") or () if c not in ACQUISITION_CAUSES]
    if damper:
        full = _tuned_fmu(diag.get("base_model") or "lumped", tuple(diag["causes"]))
        text += (f" The diagnosis's extended FMU ({full}) holds {' + '.join(damper)} too, but with the "
                 f"{' + '.join(acquisition)} in it.")
    return text


def _residual_text(diag: dict, railway: bool, usable: bool) -> tuple[str, bool | None]:
    """(what the diagnosis's residual above the floor means for the use of the model -- ``usable``: a model is
    recommended --, whether it is a model-form error: None when the diagnosis left no such residual)."""
    left = diag.get("unexplained")
    if not left:
        return "", None
    size = (f"the remaining residual, {eng(left['identification_rmse_n'], 'N')} rms, is {left['ratio']:.1f} x the "
            f"residual floor")
    base = MODEL_NAME.get(diag.get("base_model"), "base model")
    if left.get("fit_converged") is False:
        return (f"The diagnosis on the {base} leaves a residual above its floor ({size}) on a refit that did not "
                "converge: this may be an unfinished fit, NOT shown to be a model-form error; fit again with a "
                "larger budget (--iterations, --polish) before relying on absolute figures."), False
    use = "stability margins (the hunting critical speed)" if railway else "absolute force predictions"
    return ((f"But the diagnosis finds a model-form error on the {base} that no catalogue effect explains ({size}): "
             f"use the model for comparative studies, not for {use}; " if usable else
             f"The diagnosis finds a model-form error on the {base} that no catalogue effect explains ({size}): ")
            + "look at the residual figures (figures/diag_residual_*.png) and consider another base form or a "
              "form the catalogue lacks."), True


def _diagnosis_facts(diag: dict | None) -> dict | None:
    """The diagnosis's fields the recommendation rests on."""
    if diag is None:
        return None
    left = diag.get("unexplained") or {}
    return {"cause": diag.get("cause"), "causes": list(diag.get("causes") or []), "base_model": diag.get("base_model"),
            "acquisition_causes": [c for c in diag.get("causes") or () if c in ACQUISITION_CAUSES],
            "unexplained_ratio": left.get("ratio"), "fit_converged": left.get("fit_converged") if left else None,
            "failed_stage": diag.get("failed_stage")}


def _failed(diag: dict, facts: dict) -> Recommendation:
    """No recommendation: the diagnosis failed in a stage (no verdict until it finishes)."""
    return Recommendation(
        "diagnosis_failed", None, (), None,
        f"No recommendation: the diagnosis failed in its stage '{diag['failed_stage']}' ({diag.get('error', '')}), "
        "so there is no verdict on which model represents the damper.",
        "Run the same command with --resume to continue from its last finished stage; the fit's tuned FMUs are "
        "in fmu/ meanwhile, unjudged.", facts)


def _nothing_passes(candidates: list[Candidate], gate: float, action: str, facts: dict) -> Recommendation:
    """No model passes the quality gate: say so and name the closest (lowest worst AME), not recommended."""
    closest = min(candidates, key=lambda c: c.worst_ame_pct)
    reason = (f"No model describes this data: none passes the quality gate (worst held-out AME at most {gate:g} % "
              f"of peak force). The closest is the {closest.label} ({closest.fmu}), {closest.gate_text()}: its "
              "parameters are not a characterisation of this damper.")
    action = (action + " " if action else "") + ("Check the data (units, signs, the force channel) and the fit "
                                                 "(the report's force and residual figures) before using any model.")
    return Recommendation("nothing_passes", None, (), None, reason, action, facts, closest)


def recommend(out_dir) -> Recommendation:
    """The recommendation for the output folder ``out_dir`` (rules in the module docstring). Reads
    metrics.json and diagnosis.json (either may be absent); ValueError when one is not valid JSON."""
    out = Path(out_dir)
    metrics, diag = _read(out / "metrics.json"), _read(out / "diagnosis.json")
    railway = railway_damper(metrics)
    facts = {"gate_pct": QUALITY_AME_PCT, "railway_damper": railway,
             "damper_classes": sorted({t.get("damper_class") for t in ((metrics or {}).get("tests") or {}).values()}
                                      - {None}),
             "diagnosis": _diagnosis_facts(diag), "candidates": [], "maxwell_as_good": None, "form_error": None}
    if diag is not None and diag.get("failed_stage"):
        return _failed(diag, facts)
    fits = _fit_candidates(metrics)
    dc = _diagnosis_candidate(diag, metrics, fits) if diag is not None else None
    candidates = ([dc] if dc else []) + [c for c in fits if dc is None or c.model != dc.model]
    facts["candidates"] = [c.to_dict() for c in candidates]
    if not candidates:
        return Recommendation("no_results", None, (), None, "No recommendation: this folder holds neither fitted "
                              "models (metrics.json) nor a diagnosis (diagnosis.json).", "", facts)
    passing = [c for c in candidates if c.passes]
    unchecked = not passing and dc is not None and dc.passes is None
    acquisition = tuple(facts["diagnosis"]["acquisition_causes"]) if diag else ()
    residual, facts["form_error"] = _residual_text(diag, railway, bool(passing) or unchecked) if diag else ("", None)
    action = " ".join(t for t in (_acquisition_text(diag, acquisition) if acquisition else "", residual) if t)
    if passing:
        best = min(passing, key=lambda c: c.mse_n2)  # min keeps the first on a tie: the diagnosis's model
    elif unchecked:
        best = dc
        action = (action + " " if action else "") + ("The quality gate was not checked: this folder has no "
                                                     "metrics.json (diagnose --from a fit's folder to have it).")
    else:
        return _nothing_passes([c for c in candidates if c.passes is not None], candidates[0].gate_pct, action,
                               facts)
    maxwell, facts["maxwell_as_good"] = _maxwell_text(best, candidates)
    kind = "held-out" if best.held_out else "identification (no held-out test)"
    reason = (f"The {best.label} is the model to use: {_source_text(best, dc, acquisition)}; {kind} error "
              f"{best.error_text()}, {best.gate_text()}." + (f" {maxwell}" if maxwell else ""))
    return Recommendation("recommended", best.model, best.causes, best.fmu, reason, action, facts)


def recommendation_html(rec: Recommendation) -> str:
    """The recommendation box of the reports (``id='recommendation'``; the model and FMU as data attributes)."""
    head = rec.headline()
    if rec.fmu:
        head = head.replace(rec.fmu, "")
    return (f"<div class='verdict' id='recommendation' data-status='{esc(rec.status)}' data-model='{esc(rec.model or '')}' "
            f"data-fmu='{esc(rec.fmu or '')}'><p><b>Recommendation:</b> {esc(head[:1].upper() + head[1:])}"
            + (f"<code>{esc(rec.fmu)}</code>" if rec.fmu else "") + f"</p><p>{esc(rec.reason)}</p>"
            + (f"<p>{esc(rec.action)}</p>" if rec.action else "") + "</div>")
