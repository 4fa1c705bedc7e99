"""The diagnosis section of the report (``diagnosis.json``: ranking, selection, intervals, detection limits,
validation before and after, evidence) and the report of a diagnosis on its own."""
from __future__ import annotations

import html
import math
from pathlib import Path

from tuner.formatting import effect_value, fmt_quantity, pct_change
from tuner.diagnosis.residual_map import MIN_BIN_SAMPLES
from tuner.diagnosis.rules import untold
from tuner.results.html import MODEL_LABEL, esc, figure_html, table, write_page
from tuner.results.recommendation import recommend, recommendation_html
from tuner import strict_json


__all__ = ["diagnosis_section_html", "make_diagnosis_report", "detection_html"]

def make_diagnosis_report(out_dir) -> Path:
    """``out_dir/report.html`` for a diagnosis run on its own (no fit in the folder): the recommendation
    (``tuner.results.recommendation``) and the diagnosis section of the full report. Returns its path."""

    out = Path(out_dir)
    title = "Damper diagnosis report"
    return write_page(out, title, [f"<h1>{title}</h1>", recommendation_html(recommend(out)),
                                   diagnosis_section_html(out)])


def detection_html(limits: dict) -> str:
    """The detection limits of a diagnosis (``tuner.diagnosis.detection``) as a table ('' without any)."""
    if not limits:
        return ""
    rows = [[esc(effect), esc(r.get("covers") or "-"), esc(_detectable_from(r)),
             esc(r["best_test"] or "-"),
             {"score": "held-out score", "noise": "force above the noise", "range": "physical range"}[r["limited_by"]]]
            for effect, r in limits.items()]
    return ("<h3>What these tests could have detected</h3><p>The smallest magnitude of each effect that the "
            "diagnosis would have named on these tests (linearised at the base refit: the part of the effect's "
            "force the base refit cannot absorb, against the acceptance score and the noise), and the held-out "
            "test that shows it best. A verdict 'none' means nothing above these sizes.</p>"
            + table(["effect", "the kind it covers", "detectable from", "best test", "limited by"], rows))


def _detectable_from(r: dict) -> str:
    """A detection limit's magnitude for the table: the limit, 'not within its search range', and, when the base
    absorbs the effect (``rules.untold``), that these tests cannot tell it from the base's own elements."""
    text = fmt_quantity(r["limit"], r["unit"]) if r["reachable"] else "not within its search range"
    if not r.get("within_plausible", True) and r["reachable"]:
        text += f" (above the plausible {fmt_quantity(r['plausible_top'], r['unit'])})"
    if untold(r):
        text += f"; {100 * r['absorbed_share']:.0f} % of its force absorbed by the base: not told apart"
    return text


#: the captions of the diagnosis's figures by topic (``tuner.diagnosis.residuals.FIGURE_TOPICS``, the file
#: ``<prefix>_residual_<topic>.png``); a figure without one is shown bare
FIGURE_CAPTIONS = {"map": (
    "Where the base model's error lives: its residual on the identification tests over the restoring-force "
    f"plane. Left, the rms residual in each stroke x velocity bin (blank: fewer than {MIN_BIN_SAMPLES} samples): "
    "a bright column at zero velocity is an error near velocity reversal (friction, a free play, a valve that "
    "cracks open late), bright rows at the top or bottom an error at the stroke ends (an end stop, a top-out "
    "spring), a bright row across every velocity an error at one stroke position (a groove, a scored stretch of "
    "the tube), bright outer columns an error above the blow-off knee (the valves' characteristic). Right, the "
    "mean (solid) and rms (dashed) residual over velocity on the two branches of the loop: where the two means "
    "part at equal velocity, the error depends on whether the damper speeds up or slows down, a hysteresis (a "
    "lag, a missing spring or Maxwell branch); where they coincide away from zero, it is a function of the "
    "velocity alone (the characteristic's shape). The title gives each region's share of the residual power "
    "beside its share of the time (<code>diagnosis.json</code>: <code>evidence.residual_map</code>); a share "
    "well above the time share is where to look. On a single sine the reversals are the stroke ends and each "
    "branch one half of the stroke, so these regions coincide there; a test whose reversals spread over the "
    "stroke tells them apart.")}


def _figures_html(figures: list[str], out: Path) -> str:
    """The diagnosis's figures (``diagnosis.json`` ``figures``, relative to the output folder ``out``): a figure
    with a caption (``FIGURE_CAPTIONS``) as the report's figures are, with a note when its file is missing."""
    parts = []
    for f in figures:
        caption = FIGURE_CAPTIONS.get(Path(f).stem.rsplit("_residual_", 1)[-1])
        if caption is None:
            parts.append(f"<figure><img src='{esc(f)}' alt='{esc(f)}'></figure>")
        else:
            parts.append(figure_html(f if (out / f).is_file() else None, caption,
                                     f"{f} is not in the output folder (the diagnosis draws it with its figures)"))
    return "".join(parts)


#: the head of a ranking table ({ref}: what the validation MSE change is measured against)
RANKING_HEAD = ("<tr><th>candidate</th><th>fitted parameters</th><th>95 % interval</th><th>validation MSE change vs "
                "{ref}</th><th>score</th><th>effect force [N rms]</th></tr>")


def _ranking_rows(ranking: list[dict], winner: str | None) -> str:
    """Table rows of ranking entries (``diagnosis.json``), the named one marked."""
    e, out = html.escape, []
    for r in ranking:
        cls = " class='winner'" if r["effect"] == winner else ""
        fitted = ", ".join(f"{n} = {effect_value(n, v, r['units'][n])}" for n, v in r["parameters"].items())
        why = " (evidence disagrees)" if r.get("evidence_agrees") is False else " (below noise)"
        size = (f"{r['effect_rms_n']:.3g}" + ("" if r.get("resolved", True) else why)
                if r.get("parameters") else "-")
        ci = ", ".join(f"{fmt_quantity(lo, r['units'][n])} .. {fmt_quantity(hi, r['units'][n])}"
                       for n, (lo, hi) in r.get("interval", {}).items())
        ci += "" if "significant" not in r else (" (excludes 0)" if r["significant"] else " (includes 0)")
        ci += "; magnitude below the effect's physical range" if r.get("meaningful") is False else ""
        ci += "; magnitude at its search bound" if r.get("within_bounds") is False else ""
        ci += "; interval above the effect's plausible range" if r.get("plausible") is False else ""
        if r.get("excess_explained") is not None:  # a form: how much of the residual above the floor it removes
            ci += f"; removes {100 * r['excess_explained']:.0f} % of the held-out residual above the floor"
        out.append(f"<tr{cls}><td>{e(r['effect'])}</td><td>{e(fitted)}</td><td>{e(ci or '-')}</td>"
                   + (f"<td colspan='2'>held-out tests not simulable: {e(r['validation_failure'])}</td>"
                      if r.get("validation_failure") else
                      f"<td>{pct_change(r['validation_mse_change_pct'])} %</td><td>{r['score']:+.3f}</td>")
                   + f"<td>{e(size)}</td></tr>")
    return "".join(out)


def _steps_html(d: dict, causes: list[str]) -> str:
    """The forward-selection steps and the forms' tables (weighed with the causes on the base, or on top)."""
    e, steps = html.escape, ""
    for k, st in enumerate(d.get("selection", [])):
        if st.get("tried"):
            added = causes[k + 1] if st["cause"] != "none" else None
            winner = next((r["effect"] for r in st["tried"] if r.get("added") == added), None) if added else None
            steps += (f"<h3>Forward selection, step {k + 2}: on top of {e(' + '.join(causes[:k + 1]))}</h3>"
                      f"<table>{RANKING_HEAD.format(ref='the causes so far')}{_ranking_rows(st['tried'], winner)}"
                      "</table>")
    weighed, tried = d.get("forms_weighed"), d.get("forms_tried")
    if weighed and weighed != tried:  # weighed on the base against a catalogue cause, and not named
        steps += ("<h3>Forms beyond the catalogue, weighed with the causes on the base refitted alike</h3>"
                  "<p>A catalogue cause was named while the base left a residual above the floor; a form that "
                  "scored above it would have been the first cause.</p>"
                  f"<table>{RANKING_HEAD.format(ref='the base refitted alike')}{_ranking_rows(weighed, None)}</table>")
    if tried:  # the catalogue left a residual above the floor, or a form was weighed and came first
        named = next((r["effect"] for r in tried if r["added"] == d.get("form")), None)
        first = bool(weighed) and weighed == tried
        model = "the base refitted alike" if first else (
            " + ".join(c for c in causes if c != d.get("form")) or "the base refitted alike")
        steps += (f"<h3>Forms beyond the catalogue, on top of {e(model)}</h3><p>Tried because the residual stayed "
                  "above the floor. A form is named on the rules of a cause and only when it removes at least half "
                  "of the held-out residual above the floor (one that patches part of another error is not the "
                  f"missing element).</p><table>{RANKING_HEAD.format(ref=e(model))}{_ranking_rows(tried, named)}"
                  "</table>")
    return steps


def _tables_html(d: dict) -> tuple[str, str]:
    """(validation before/after rows, effect parameters vs plausible ranges rows)."""
    e = html.escape
    val = "".join(f"<tr><td>{e(n)}</td><td>{v['mse_before']:.3e}</td><td>{v['mse_after']:.3e}</td>"
                  f"<td>{pct_change(v['mse_change_pct'])} %</td><td>{v['ame_before']:.0f}</td><td>{v['ame_after']:.0f}</td></tr>"
                  for n, v in d["validation"].items())
    eff = "".join(f"<tr><td>{e(n)}</td><td>{e(fmt_quantity(p['value'], p['unit']))}</td><td>"
                  + (f"{e(fmt_quantity(p['plausible_range'][0], p['unit']))} - "
                     f"{e(fmt_quantity(p['plausible_range'][1], p['unit']))}</td>"
                     f"<td>{'yes' if p['plausible'] else 'NO'}</td></tr>" if "plausible_range" in p else
                     "- (a shape: no typical size)</td><td>-</td></tr>") for n, p in d["effect_parameters"].items())
    return val, eff


def _evidence_html(d: dict) -> str:
    """List items of the residual evidence: each signature's sentence, and the joint screen."""
    e = html.escape
    ev = (d.get("evidence") or {}).get("effects", {})
    ev_rows = "".join(f"<li><b>{e(k)}</b>: {e(str(v.get('sentence', '')))}</li>" for k, v in ev.items()
                      if isinstance(v, dict) and v.get("sentence"))
    scr = (d.get("evidence") or {}).get("joint_screen")
    if scr:
        kept = " + ".join(f"{k} ({scr['terms'][k]['contribution_n']:.3g} N)" for k in scr["kept"]) or "nothing"
        ev_rows += (f"<li><b>joint screen</b> (the residual on all seven signatures at once, terms below "
                    f"{scr['threshold_n']:.3g} N or of unphysical sign dropped): keeps {e(kept)}, explaining "
                    f"{100 * scr['r2_kept']:.0f} % of the residual power; all seven together "
                    f"{100 * scr['r2_all']:.0f} %: the most any linear mix of catalogue effects could remove</li>")
    return ev_rows


def _base_html(d: dict) -> str:
    """The base model and how it was chosen (again after the diagnosis when the first choice left a residual), and
    the grid the diagnosis ended on (``tuner.diagnosis.grid_check``)."""
    e = html.escape
    base_kind = d.get("base_model", "lumped")
    choice = d.get("base_choice") or {}
    text = (f"<p>Base model: <b>{e(MODEL_LABEL.get(base_kind, base_kind))}</b>"
            + (", chosen by " + e(choice.get("by", "")) + ": " + ", ".join(
                f"{e(MODEL_LABEL.get(k, k))} {math.sqrt(v):.3g} N rms" for k, v in choice["validation_mse"].items())
               if choice.get("validation_mse") else "") + ".</p>")
    if choice.get("after_diagnosis"):  # the first choice left a residual above the floor: both diagnosed
        text += ("<p>The first choice, " + e(MODEL_LABEL.get(choice["first_choice"], choice["first_choice"]))
                 + ", left a residual above the floor, so the diagnosis was repeated on every base form and "
                 "the final model with the lowest held-out MSE kept: " + ", ".join(
                     f"{e(MODEL_LABEL.get(k, k))} with {e(' + '.join(v['causes']) or 'no cause')} "
                     f"{math.sqrt(v['validation_mse']):.3g} N rms" for k, v in choice["after_diagnosis"].items())
                 + ".</p>")
    grid = d.get("grid") or {}
    if grid.get("refined"):
        text += f"<p>{e(grid['text'])}.</p>"
    elif grid.get("check"):
        c = grid["check"]
        text += (f"<p>Grid: the final model's force moves by {c['change_n']:.3g} N rms between the "
                 f"{1e3 * c['step_s']:g} ms grid it was fitted on and a {1e3 * c['finer_step_s']:g} ms one, within "
                 f"{c['share_allowed']:g} x the {c['noise_n']:.3g} N force noise.</p>")
    return text


def _floor_text(d: dict) -> str:
    """The residual floor, and why the residual was not compared with it when the noise is not credible."""
    text = (f" The residual floor is {d['residual_floor_n']:.3g} N: the force noise and the "
            f"{d['stroke_noise_force_n']:.3g} N the stroke channel's noise makes through the model."
            if d.get("residual_floor_n") else "")
    final = d.get("final_residual_floor_n")
    if final and d.get("residual_floor_n") and abs(final - d["residual_floor_n"]) > 0.1 * d["residual_floor_n"]:
        text += (f" Through the final model the stroke noise makes {d['final_stroke_noise_force_n']:.3g} N, and its "
                 f"residual is judged against a floor of {final:.3g} N.")
    noise = d.get("noise") or {}
    if noise and not noise.get("credible", True):
        text += " The residual was not compared with it: " + html.escape(noise.get("text", "noise estimate not credible")) + "."
    return text


def diagnosis_section_html(out_dir) -> str:
    """HTML section of the report for ``out_dir/diagnosis.json`` ('' when there is none)."""
    path = Path(out_dir) / "diagnosis.json"
    if not path.exists():
        return ""
    d = strict_json.loads(path.read_text())
    if d.get("failed_stage"):
        return _failure_html(d)
    e = html.escape
    causes = d.get("causes") or ([d["cause"]] if d["cause"] not in ("none", "unexplained") else [])
    rows = _ranking_rows(d["ranking"], causes[0] if causes else None)
    val, eff = _tables_html(d)
    ev_rows, s, noise = _evidence_html(d), d["settings"], d.get("noise") or {}
    figs = _figures_html(d.get("figures", []), path.parent)
    return (
        "<section id='diagnosis'><h2>Diagnosis: what the model gets wrong, and why</h2>"
        f"<p class='verdict'>{e(d['verdict'])}{'. ' + e(d['note']) if d.get('note') else ''}</p>"
        + _base_html(d) +
        "<p>Each candidate effect was added to the base model and the extended model refitted on the "
        "identification tests; the decision rests on the validation (held-out) MSE: score = -ln(MSE_ext / "
        f"MSE_base) - {s['penalty_per_parameter']} per extra parameter, a cause is named when its score exceeds "
        f"{s['accept_score']}.</p>"
        "<p>'none' is the base model refitted from the same starts with the same effort; every score is "
        "measured against it, so a refit's own progress is not credited to an effect. An effect whose force "
        f"contribution (fitted model minus the same with the effect off) is below the measurement noise "
        f"({e(noise.get('text') or format(d.get('noise_std_n', float('nan')), '.3g') + ' N')}) is not named.</p>"
        "<p>A cause is also significant: the 95 % confidence interval of its magnitude excludes zero. The "
        "interval comes from the identification residual's Jacobian by a block sandwich estimate (blocks of "
        "three residual correlation times), because the residuals are correlated and the textbook interval "
        "would be far too narrow. Causes are added one at a time (forward selection) while the next one "
        "earns its score against the model of the causes found so far. When the final model's residual stays "
        f"above {s.get('unexplained_ratio', 2)} x the residual floor, the report says so: a model-form error the "
        f"catalogue does not explain.{_floor_text(d)}</p>"
        f"<table>{RANKING_HEAD.format(ref=chr(39) + 'none' + chr(39))}{rows}</table>{_steps_html(d, causes)}"
        + (f"<h3>Effect parameters vs plausible ranges</h3><table><tr><th>parameter</th><th>fitted</th>"
           f"<th>typical range</th><th>plausible</th></tr>{eff}</table>" if eff else "")
        + "<h3>Validation before and after</h3><table><tr><th>test</th><th>MSE before [N&sup2;]</th>"
          f"<th>MSE after [N&sup2;]</th><th>change</th><th>AME before [N]</th><th>AME after [N]</th></tr>{val}</table>"
        + (f"<h3>Residual evidence (base model)</h3><ul>{ev_rows}</ul>" if ev_rows else "")
        + detection_html(d.get("detection_limits") or {})
        + figs + "</section>")


def _failure_html(d: dict) -> str:
    """The diagnosis section of a diagnosis that failed in a stage (``diagnosis.json`` with ``failed_stage``):
    no verdict, the stage, the error, the stages finished and the candidates refitted so far."""
    rows = [[esc(r["effect"]), esc(", ".join(f"{n} = {effect_value(n, v, r['units'][n])}"
                                             for n, v in r["parameters"].items()) or "-"),
             f"{pct_change(r['validation_mse_change_pct'])} %", f"{r['score']:+.3f}"] for r in d.get("ranking") or []]
    return ("<section id='diagnosis'><h2>Diagnosis: FAILED, no verdict</h2>"
            f"<p class='verdict'>The diagnosis failed in its stage <b>{esc(d['failed_stage'])}</b>: "
            f"{esc(d['error'])}.</p>"
            f"<p>Stages finished: {esc(', '.join(d.get('finished_stages') or []) or 'none')}. The same command "
            "with <code>--resume</code> continues from the last finished stage; the error's traceback is in "
            "<code>diagnosis.json</code>.</p>"
            + (f"<p>Causes named before the failure (not a verdict): {esc(' + '.join(d['causes']))}.</p>"
               if d.get("causes") else "")
            + ("<h3>Candidates refitted before the failure (not a verdict)</h3>"
               + table(["candidate", "fitted parameters", "validation MSE change", "score"], rows) if rows else "")
            + "</section>")
