"""The end of a run: ``summary.json`` and the summary printed once everything is written; Table 3."""
from __future__ import annotations

from pathlib import Path

from tuner.cli.log import log
from tuner.datasheet.sheet import DATASHEET_FILE, DATASHEET_FOLDER
from tuner.identification.intervals import ModelIntervals
from tuner.results.recommendation import MODEL_NAME, recommend
from tuner.vehicle.compare import VEHICLE_FOLDER
from tuner.vehicle.cooperrider_hunting import COOPERRIDER_FILE
from tuner.vehicle.propagation import INTERVALS_FILE
from tuner import strict_json

__all__ = ["end_summary", "print_table3", "interval_summary", "vehicle_interval_summary", "cooperrider_summary",
           "update_cooperrider_summary"]


def interval_summary(parameters: dict) -> dict:
    """summary.json's ``parameter_intervals`` from parameters.json: per model the one-line summary, the
    names per flag ('determined', 'at_bound', 'not_determined', 'extrapolated'), the ties {name: [names]}
    and each parameter's 95 % range {name: {"low", "high", "status", "unit"}} (SI; low and high null with
    the status 'not determined' when the tests do not move the force along it); {"note": why} for a model
    without intervals."""
    out = {}
    for model, entry in parameters.items():
        if not isinstance(entry, dict) or not entry.get("intervals"):
            out[model] = {"note": (entry or {}).get("intervals_note", "no intervals in parameters.json")}
            continue
        iv = ModelIntervals.from_dict(model, entry["intervals"])
        flags = (("determined", "determined"), ("at_bound", "at a bound"), ("not_determined", "not determined"),
                 ("extrapolated", "extrapolated"))
        out[model] = {"summary": iv.summary_text(), **{key: iv.names_with(flag) for key, flag in flags},
                      "tied": {p.name: [n for n, _ in p.tied_to] for p in iv.parameters if p.tied_to},
                      "ranges": {p.name: {"low": p.low, "high": p.high, "status": p.status, "unit": p.unit}
                                 for p in iv.parameters}}
    return out


def vehicle_interval_summary(out: Path) -> dict:
    """summary.json's ``vehicle_intervals`` from ``vehicle/intervals.json`` (``tuner.vehicle.propagation``):
    per tuned FMU its model, the critical speed [km/h] and the curve entry's peak damper force [N], each
    {"nominal", "low", "high", "mc_error", "draws", "method"}, the search's own scatter [km/h] and the
    sentence ("critical speed 804 km/h (95 %: 790-815), ... with the lumped FMU"); {} without the file."""
    path = out / VEHICLE_FOLDER / INTERVALS_FILE
    if not path.exists():
        return {}
    out_ = {}
    for label, r in strict_json.loads(path.read_text())["results"].items():
        def pick(f, scale):
            return {**{k: None if f[k] is None else f[k] * scale for k in ("nominal", "low", "high", "mc_error")},
                    "draws": f["draws"], "method": f["method"]}
        scatter = r.get("search_scatter_ms")
        name = MODEL_NAME.get(r["model"], r["model"]).removesuffix(" model")
        out_[label] = {"model": r["model"], "critical_speed_kmh": pick(r["critical_speed"], 3.6),
                       "peak_curve_force_n": pick(r["peak_curve_force"], 1.0),
                       "search_scatter_kmh": None if scatter is None else scatter * 3.6,
                       "text": f"critical speed {r['critical_speed_text']}, curve entry peak damper force "
                               f"{r['peak_curve_force_text']} with the {name} FMU"}
    return out_


def cooperrider_summary(out: Path) -> dict:
    """summary.json's ``cooperrider``, from ``vehicle/cooperrider.json`` (``tuner.vehicle.cooperrider_hunting``): per
    yaw damper (the Cooperrider car's own D6 dashpot and each FMU) the linear critical speed on S1002/UIC60 in m/s
    and km/h (null when none was found) and its bracket [m/s]; {} when the study was not run."""
    path = Path(out) / VEHICLE_FOLDER / COOPERRIDER_FILE
    if not path.exists():
        return {}
    data = strict_json.loads(path.read_text())
    return {label: {k: r[k] for k in ("critical_speed_ms", "critical_speed_kmh", "bracket_ms")}
            for label, r in data["results"].items()}


def update_cooperrider_summary(out: Path) -> bool:
    """Put :func:`cooperrider_summary` into an existing ``out/summary.json`` (after ``python -m tuner vehicle
    --cooperrider --out RUN``); False when there is no summary.json."""
    path = Path(out) / "summary.json"
    if not path.exists():
        return False
    summary = strict_json.loads(path.read_text())
    summary["cooperrider"] = cooperrider_summary(out)
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(strict_json.dumps(summary, indent=1))
    tmp.replace(path)
    return True


def end_summary(out: Path, seconds: float, quiet: bool = False) -> dict:
    """Write ``summary.json`` and print the end-of-run summary once, after everything is written: the
    recommendation (``tuner.results.recommendation``: the model and FMU to use and why, the same as the
    report's box), the warnings of reading the data (metrics.json's ``warnings``: each once, naming its
    file), verdict, causes, validation AME per test and model, quality gate, how well the tests determine
    each model's parameters (``interval_summary``), where the report, the datasheet and FMUs are. ``seconds``: the run's
    time [s]."""
    metrics = strict_json.loads((out / "metrics.json").read_text()) if (out / "metrics.json").exists() else {}
    diag = strict_json.loads((out / "diagnosis.json").read_text()) if (out / "diagnosis.json").exists() else {}
    vpath = out / VEHICLE_FOLDER / "vehicle.json"
    vehicle = strict_json.loads(vpath.read_text()) if vpath.exists() else {}
    params = strict_json.loads((out / "parameters.json").read_text()) if (out / "parameters.json").exists() else {}
    ame = {}
    for name, t in (metrics.get("tests") or {}).items():
        if t.get("role") == "validation":
            ame[name] = {m: {"ame_n": r["ame"], "ame_pct_of_peak": 100 * r["ame"] / r["peak_measured"]}
                         for m, r in t["models"].items()}
    rec = recommend(out)
    summary = {
        "recommendation": rec.to_dict(out),
        "verdict": diag.get("verdict"), "cause": diag.get("cause"), "causes": diag.get("causes"),
        "form": diag.get("form"),  # a form beyond the catalogue named (also among the causes), or None
        "effect_parameters": diag.get("effect_parameters"),
        "quality": {m: {k: q[k] for k in ("describes_data", "worst_ame_pct_of_peak", "worst_test", "gate_pct")}
                    for m, q in (metrics.get("quality") or {}).items()},
        "validation_ame": ame,
        "parameter_intervals": interval_summary(params),
        "critical_speed_kmh": {k: (r.get("critical_speed") or {}).get("critical_speed_kmh")
                               for k, r in vehicle.get("results", {}).items()},
        "vehicle_intervals": vehicle_interval_summary(out),
        "cooperrider": cooperrider_summary(out),
        "warnings": [str(w) for w in metrics.get("warnings") or []],
        "report": str(out / "report.html") if (out / "report.html").exists() else None,
        "datasheet": str(sheet) if (sheet := out / DATASHEET_FOLDER / DATASHEET_FILE).exists() else None,
        "fmus": sorted(str(f) for f in out.rglob("*.fmu")),
        "total_time_s": seconds, "output_folder": str(out),
    }
    tmp = out / "summary.json.tmp"
    tmp.write_text(strict_json.dumps(summary, indent=1))
    tmp.replace(out / "summary.json")
    lines = ["", "=" * 72, f"done in {seconds / 60:.1f} min: {out}", f"  recommendation: {rec.headline()}",
             *(f"    {text}" for text in (rec.reason, rec.action) if text)]
    if summary["warnings"]:
        lines.append(f"  warnings of reading the data ({len(summary['warnings'])}):")
        lines.extend(f"    {w}" for w in summary["warnings"])
    for m, q in summary["quality"].items():
        lines.append(f"  {m}: {'describes the data' if q['describes_data'] else 'does NOT describe the data'} "
                     f"(worst held-out AME {q['worst_ame_pct_of_peak']:.3g} % of peak, gate {q['gate_pct']:g} %)")
    if ame:
        models = sorted({m for r in ame.values() for m in r})
        lines.append("  validation AME [% of peak]: " + "; ".join(
            f"{n}: " + ", ".join(f"{m} {r[m]['ame_pct_of_peak']:.3g}" for m in models if m in r) for n, r in ame.items()))
    for m, iv in summary["parameter_intervals"].items():
        lines.append(f"  {m} parameters: {iv.get('summary') or iv['note']}")
    if summary["verdict"]:
        lines.append(f"  diagnosis: {summary['verdict']}")
    plain = {k: v for k, v in summary["critical_speed_kmh"].items() if k not in summary["vehicle_intervals"]}
    if plain:  # the FMUs with an interval have their line below
        lines.append("  vehicle, hunting critical speed [km/h]" + (" (no interval drawn)" if summary["vehicle_intervals"]
                                                                  else "") + ": " + ", ".join(
            f"{k} {'-' if v is None else format(v, '.0f')}" for k, v in plain.items()))
    for v in summary["vehicle_intervals"].values():
        lines.append(f"  vehicle: {v['text']}")
    if summary["report"]:
        lines.append(f"  report: {summary['report']}")
    if summary["datasheet"]:
        lines.append(f"  datasheet (force-velocity and Maxwell tables per FMU beside it): {summary['datasheet']}")
    for f in summary["fmus"]:
        lines.append(f"  FMU: {f}")
    lines.append(f"  summary for scripts: {out / 'summary.json'}")
    print("\n".join(lines), flush=True)
    return summary


def print_table3(metrics: dict) -> None:
    t3 = metrics.get("table3") or {}
    if not t3:
        return
    log("\nTable 3 (validation)           MSE Maxwell   MSE lumped    var.    AME Maxwell  AME lumped   var.  AME/peak")
    for name, r in t3.items():
        log(f"  {name:28s} {r['mse_maxwell']:11.3e} {r['mse_lumped']:11.3e} {r['mse_variation_pct']:7.1f}% "
             f"{r['ame_maxwell']:10.0f} N {r['ame_lumped']:9.0f} N {r['ame_variation_pct']:6.1f}% "
             f"{r['ame_lumped_pct_of_peak']:6.2f}%")
