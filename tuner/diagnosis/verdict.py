"""The diagnosis's words: the verdict paragraph, why a candidate was not named, the record of what stays
unexplained and the named causes' magnitudes with their ranges (SI units, stated with each number).
"""
from __future__ import annotations

from damper_fmu.effect_catalogue import ALL_EFFECTS, EFFECT_PARAMETERS, effect_of

from tuner.diagnosis.effect_sizes import DamperSize, plausible_range, typical_range
from tuner.diagnosis.forms import settings_text
from tuner.diagnosis.rules import ACCEPT_SCORE, CONFOUNDED_SHARE, FORM_EXCESS_SHARE, earned, untold
from tuner.formatting import fmt_quantity

__all__ = ["UNITS", "NOTES", "ACQUISITION_CAUSES", "unexplained_record", "effect_parameters", "interval_text",
           "limit_text", "verdict_text", "why_not", "map_text", "told_apart_text",
           "absorbed_phrase", "absorbed_text", "untold_text", "traded_delay_text"]

UNITS = {p.name: p.unit for p in EFFECT_PARAMETERS}


#: what the verdict adds when it names an effect (``Effect.note``)
NOTES = {e.name: e.note for e in ALL_EFFECTS.values() if e.note}


#: named causes that belong to the acquisition (the rig's channels and zero), not to the damper (NOTES): the
#: model to use in a co-simulation is the base without them (``tuner.results.recommendation``; ``Effect.acquisition``)
ACQUISITION_CAUSES = tuple(e.name for e in ALL_EFFECTS.values() if e.acquisition)


#: the regions of ``tuner.diagnosis.residual_map.map_summary`` in the verdict's words
REGION_WORDS = {"near_reversal": "near velocity reversal", "stroke_ends": "at the stroke ends",
                "stroke_band": "at one stroke position", "above_knee": "above the blow-off knee"}


def unexplained_record(final_rmse: float, noise: float, floor: float, stroke_noise_n: float, evidence: dict,
                 fit_converged: bool | None) -> dict:
    """The record of a residual left above the floor [N]: where it lies (band, loop, linear share, the
    restoring-force map's regions: ``residual_map``, the base model's, None without one) and how
    much of it the closest catalogue signature and all of them together explain (``evidence``)."""
    pooled = (evidence.get("general") or {}).get("pooled") or {}
    bands = pooled.get("band_fraction") or {}
    r2 = {e: d.get("r2") or 0.0 for e, d in (evidence.get("effects") or {}).items()}
    return {"identification_rmse_n": final_rmse, "noise_std_n": noise, "floor_n": floor,
            "stroke_noise_force_n": stroke_noise_n, "ratio": final_rmse / floor,
            "dominant_band": max(bands, key=bands.get) if bands else None,
            "band_fraction": bands, "best_signature": max(r2, key=r2.get) if r2 else None,
            "best_signature_r2": max(r2.values()) if r2 else None,
            "linear_share": pooled.get("linear_share"), "band_linear_share": pooled.get("band_linear_share"),
            "loop": pooled.get("loop"), "residual_map": evidence.get("residual_map"),
            "catalogue_r2_all": (evidence.get("joint_screen") or {}).get("r2_all"),
            "fit_converged": fit_converged}


def effect_parameters(best: dict, size: DamperSize) -> dict:
    """The named causes' fitted magnitudes with units, 95 % intervals, their typical and plausible ranges on a
    damper of ``size`` (``tuner.diagnosis.effect_sizes``) and whether the value lies in the plausible one."""
    out = {}
    for n, v in best["parameters"].items():
        out[n] = {"value": v, "unit": UNITS[n], "interval_95": best["interval"][n]}
        if n in effect_of(n).typical:  # a form's shape (a groove's centre and length) has no typical size
            lo, hi = plausible_range(n, size)
            out[n].update({"typical_range": list(typical_range(n, size)), "plausible_range": [lo, hi],
                           "plausible": bool(lo <= abs(v) <= hi)})
    return out


def interval_text(row: dict, names=None) -> str:
    """'name = value (95 % interval low .. high)' of the row's parameters (``names``: only these)."""
    return ", ".join(f"{n} = {fmt_quantity(v, UNITS[n])} (95 % interval {fmt_quantity(row['interval'][n][0], UNITS[n])}"
                     f" .. {fmt_quantity(row['interval'][n][1], UNITS[n])})" for n, v in row["parameters"].items()
                     if names is None or n in names)


def limit_text(row: dict) -> str:
    """'above 400 N (val2_curve)' of a detection limit, or 'not detectable within the search range', with, when the
    base absorbs its force (``rules.CONFOUNDED_SHARE``), what absorbs it and, for a limit above the physical
    range, that range's top."""
    if not row["reachable"]:
        return "not detectable within its search range" + absorbed_text(row)
    unit = UNITS[row["parameter"]]
    notes = [str(row["best_test"])]
    if not row.get("within_plausible", True):
        notes.append(f"beyond the {fmt_quantity(row['plausible_top'], unit)} a damper this size plausibly has")
    notes += [absorbed_phrase(row)] if absorbed_phrase(row) else []
    return f"above {fmt_quantity(row['limit'], unit)} ({'; '.join(notes)})"


def absorbed_phrase(row: dict) -> str:
    """'99 % of its force absorbed by the elastic table' of a detection limit whose effect the base absorbs to at
    least CONFOUNDED_SHARE, else ''."""
    share = row.get("absorbed_share", 0.0)
    if share < CONFOUNDED_SHARE:
        return ""
    by = " and ".join(row.get("absorbed_by") or {}) or "the base parameters"
    return f"{100 * share:.0f} % of its force absorbed by {by}"


def absorbed_text(row: dict) -> str:
    """' (99 % of its force absorbed by the elastic table)' (``absorbed_phrase`` in brackets), else ''."""
    return f" ({absorbed_phrase(row)})" if absorbed_phrase(row) else ""


def untold_text(limits: dict | None) -> str:
    """For a verdict with causes: the other candidates these tests cannot tell from the base model's own elements
    (``rules.untold``: their force absorbed, ``absorbed_text``, and no plausible magnitude detectable); '' when
    none."""
    told = [f"{e}{absorbed_text(r)}" for e, r in (limits or {}).items() if untold(r)]
    return "; these tests cannot tell from the base model's own elements: " + ", ".join(told) if told else ""


def traded_delay_text(best: dict) -> str:
    """For a named delay whose signature the base absorbs (``best['delay_absorbed_share']`` at least
    ``CONFOUNDED_SHARE``): that its size trades with the base's own elements beyond its interval; '' otherwise."""
    share = best.get("delay_absorbed_share", 0.0)
    if share < CONFOUNDED_SHARE:
        return ""
    return (f"; {100 * share:.0f} % of the delay's signature is what the base model's own elements make (its series "
            "compliance is a lag too): its size trades with theirs, and the interval does not hold that trade")


def coulomb_text(form_step: dict | None) -> str:
    """'; the friction found as a pre-yield hysteresis at its smallest displacement scale ...' when the forms'
    step named a friction in a hysteresis's place (``search.form_steps.as_friction``), else ''."""
    hyst = (form_step or {}).get("coulomb")
    if not hyst:
        return ""
    return (f"; the friction was found as a pre-yield hysteresis of {fmt_quantity(hyst['hysteresis_force'], 'N')} at "
            f"its smallest displacement scale (x_h = {fmt_quantity(hyst['hysteresis_displacement'], 'm')}), "
            "which is a Coulomb friction")


def verdict_text(causes: list[str], best: dict, none_row: dict, rejected: list[dict], unexplained: dict | None,
             noise: float, limits: dict | None = None, form_step: dict | None = None) -> str:
    """One-paragraph verdict: the causes with magnitudes and intervals and their held-out gain, or
    none with what these tests could have detected (``limits``), a form beyond the catalogue named
    with its gain (``form_step``: what ``try_forms`` tried), and what stays unexplained."""
    form = form_step["form"] if form_step else None
    found = [c for c in causes if c != form]
    if form:
        change = 100 * (best["validation_mse"] / none_row["validation_mse"] - 1)
        # against the model it was added to: the causes found before it, or the base when it came first
        first = bool(form_step.get("first"))
        step = (form_step["row"] if first else best)["validation_mse_change_pct"]
        how = settings_text(form_step["row"].get("settings") or {})
        text = (f"form beyond the catalogue: {ALL_EFFECTS[form].label} ({interval_text(best, ALL_EFFECTS[form].identified)}"
                + (f"; {how}" if how else "") + "): "
                f"held-out MSE {step:+.0f} %" + (f" on top of {' + '.join(found)}" if found and not first else "")
                + (" on the base, weighed against the catalogue's causes and scoring above them" if first else "")
                + f"; {change:+.0f} % against the base refitted alike")
        if found:
            text = (f"cause{'s' if len(found) > 1 else ''}: {' + '.join(found)} ("
                    + interval_text(best, [n for c in found for n in ALL_EFFECTS[c].identified]) + "); " + text)
    elif causes:
        change = 100 * (best["validation_mse"] / none_row["validation_mse"] - 1)
        text = (f"cause{'s' if len(causes) > 1 else ''}: {' + '.join(causes)} ({interval_text(best)}); "
                f"validation MSE {change:+.0f} % against the base refitted alike" + coulomb_text(form_step)
                + traded_delay_text(best) + untold_text(limits))
    else:
        none_inner = ("no extension earns its parameters on held-out data"
                      + ("; " + ", ".join(f"{r['effect']} scored {r['score']:+.3f} but " + why_not(r, noise)
                                          for r in rejected) if rejected else ""))
        limits_text = ("; these tests would have named: "
                       + ", ".join(f"{e} {limit_text(r)}" for e, r in limits.items())
                       + (f" (friction: {limits['friction']['covers']})" if "friction" in limits else "")
                       if limits else "")
        text = f"cause: none ({none_inner}){limits_text}"
    if unexplained:
        where = (f"; most of it in the {unexplained['dominant_band']} band" if unexplained["dominant_band"] else "")
        where += map_text(unexplained.get("residual_map"))
        sig = (f"; the closest catalogue signature ({unexplained['best_signature']}) explains "
               f"{100 * unexplained['best_signature_r2']:.0f} % of the base model's residual"
               if unexplained["best_signature"] else "")
        if unexplained.get("catalogue_r2_all") is not None:
            sig += (f", all seven signatures together {100 * unexplained['catalogue_r2_all']:.0f} % "
                    "(joint least squares)")
        lin = unexplained.get("linear_share")
        if lin is not None:
            sig += (f"; {100 * lin:.0f} % of its power is linear in the stroke (coherence) "
                    + ("- a missing linear element (spring, Maxwell branch, delay) fits that" if lin >= 0.7 else
                       "- so no added linear element (spring, Maxwell branch, delay) can remove most of it: "
                       "the error is nonlinear or time-varying"))
        if form_step and not form:
            sig += "; forms beyond the catalogue tried, none earns its parameters: " + ", ".join(
                _form_tried_text(r, noise) for r in form_step["tried"])
        loop = unexplained.get("loop") or {}
        if loop:
            low = sum(v["power_share"] for k, v in loop.items() if k.startswith("below"))
            low_t = sum(v["time_share"] for k, v in loop.items() if k.startswith("below"))
            sig += (f"; {100 * low:.0f} % of it at speeds below the blow-off knee ({100 * low_t:.0f} % of the time), "
                    f"{100 * (1 - low):.0f} % beyond")
        apart = told_apart_text(unexplained.get("indistinguishable"))
        what = ("a model-form error that no catalogue effect explains" + apart
                if unexplained.get("fit_converged") is not False
                else "but the refit did not converge within its Jacobian cap, so this may be an unfinished fit: "
                     "it is NOT shown to be a model-form error")
        text = ("unexplained: " if not causes else text + ". Not explained: ") + (
            f"the remaining residual, {unexplained['identification_rmse_n']:.3g} N rms, is "
            f"{unexplained['ratio']:.1f} x the residual floor ({unexplained['floor_n']:.2g} N: force noise "
            f"{noise:.2g} N, stroke noise through the model {unexplained['stroke_noise_force_n']:.2g} N): "
            f"{what}{where}{sig}") + ("" if causes else f"; no named cause: {none_inner}{limits_text}")
    return text


def told_apart_text(records: list[dict] | None) -> str:
    """What cannot be told apart (``rules.indistinguishable``), for the verdict: each effect with its refit's
    magnitude and held-out change and the base elements that absorb it; '' when none."""
    if not records:
        return ""
    parts = []
    for r in records:
        by = " and ".join(f"{g} ({100 * v:.0f} %)" for g, v in r["absorbed_by"].items()) or "the base parameters"
        values = ", ".join(f"{n} = {fmt_quantity(v, UNITS[n])}" for n, v in r["parameters"].items())
        change = r["validation_mse_change_pct"]
        parts.append(f"{ALL_EFFECTS[r['effect']].label} ({values}; held-out MSE {change:+.0f} %) "
                     f"and {by} explain the same residual: the base refit absorbs {100 * r['absorbed_share']:.0f} % of "
                     f"its force")
    return (" apart from what these tests cannot tell from the base model's own elements: " + "; ".join(parts)
            + " (a test that separates them, e.g. other frequencies or amplitudes, would tell which)")


def why_not(row: dict, noise: float) -> str:
    """Why a row that scored enough was not named (for the verdict)."""
    if row.get("evidence_agrees") is False:
        return "its delay disagrees with the residual's"
    if not row["resolved"]:
        return f"its force, {row['effect_rms_n']:.2g} N rms, is below the measurement noise ({noise:.2g} N)"
    if row.get("excess_explained") is not None and row["excess_explained"] < FORM_EXCESS_SHARE and earned(row):
        return (f"it removes only {100 * row['excess_explained']:.0f} % of the held-out residual above the floor "
                f"(a form must remove {100 * FORM_EXCESS_SHARE:.0f} %: one that patches part of another error is not "
                "the missing element)")
    if not row.get("within_bounds", True):
        return ("its magnitude (" + ", ".join(f"{fmt_quantity(v, UNITS[n])}" for n, v in row["parameters"].items())
                + ") is at its search bound: stopped by the bound, not by the data, it patches another error")
    if not row.get("plausible", True):
        return ("its 95 % interval lies above the effect's plausible range on this damper: it patches another "
                "error (a form gap)")
    if not row.get("meaningful", True):
        return ("its magnitude (" + ", ".join(f"{fmt_quantity(v, UNITS[n])}" for n, v in row["parameters"].items())
                + ") is below the physical range of the effect")
    if row.get("interval_not_computed"):
        return f"its 95 % interval could not be computed: {row['interval_not_computed']}"
    ci = "; ".join(f"{n} {fmt_quantity(lo, UNITS[n])} .. {fmt_quantity(hi, UNITS[n])}"
                   for n, (lo, hi) in row.get("interval", {}).items())
    return f"its 95 % interval includes zero ({ci or 'not computed'})"


def _form_tried_text(row: dict, noise: float) -> str:
    """A form tried and not named, for the verdict: its held-out change, or, when no shape was refitted, what
    the screen predicted (a form ranked where it fits best with the model held gains nothing there)."""
    if row.get("refitted") is False and row.get("screen"):
        share = max(c["predicted_share"] for c in row["screen"])
        return (f"{row['form']} screened only (its best shape predicted to win {100 * share:.0f} % of the "
                f"identification residual, too little to be named; not refitted)")
    return (f"{row['form']} {row['validation_mse_change_pct']:+.0f} % held-out MSE (score {row['score']:+.3f}"
            + (", " + why_not(row, noise) if row["score"] > ACCEPT_SCORE and "interval" in row else "") + ")")


def map_text(summary: dict | None) -> str:
    """Where the residual lives on the restoring-force plane (``residual_map.map_summary``), for the verdict: each
    region holding a disproportionate share of its power, with that share and its share of the time, and the
    difference between the loop's branches when it is a hysteresis; '' when neither (or no summary)."""
    if not summary:
        return ""
    parts = []
    for k in summary["concentrated_in"]:
        d = summary["regions"][k]
        at = (f", {1e3 * d['stroke_from_m']:.3g} to {1e3 * d['stroke_to_m']:.3g} mm" if k == "stroke_band" else "")
        parts.append(f"{REGION_WORDS[k]}{at} ({100 * d['power_share']:.0f} % of the power in "
                     f"{100 * d['time_share']:.0f} % of the time)")
    text = "; concentrated " + " and ".join(parts) if parts else ""
    branches = summary["branch_asymmetry"]
    if branches["hysteresis"]:
        text += (f"; {100 * branches['power_share']:.0f} % of its power differs between the accelerating and "
                 "decelerating branches at equal velocity (a hysteresis)")
    return text
