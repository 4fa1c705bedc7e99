"""The end of a run: ``summary.json`` and the summary printed once everything is written; Table 3."""
from __future__ import annotations

import json
from pathlib import Path

from tuner.cli.log import log
from tuner.results.recommendation import recommend
from tuner.vehicle.compare import VEHICLE_FOLDER
from tuner import strict_json

__all__ = ["end_summary", "print_table3"]


def end_summary(out: Path, seconds: float, quiet: bool = False) -> dict:
    """Write ``summary.json`` and print the end-of-run summary once, after everything is written: the
    recommendation (``tuner.results.recommendation``: the model and FMU to use and why, the same as the
    report's box), verdict, causes, validation AME per test and model, quality gate, where the report and
    FMUs are. ``seconds``: the run's time [s]."""
    metrics = strict_json.loads((out / "metrics.json").read_text()) if (out / "metrics.json").exists() else {}
    diag = strict_json.loads((out / "diagnosis.json").read_text()) if (out / "diagnosis.json").exists() else {}
    vpath = out / VEHICLE_FOLDER / "vehicle.json"
    vehicle = strict_json.loads(vpath.read_text()) if vpath.exists() else {}
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
        "critical_speed_kmh": {k: (r.get("critical_speed") or {}).get("critical_speed_kmh")
                               for k, r in vehicle.get("results", {}).items()},
        "report": str(out / "report.html") if (out / "report.html").exists() else None,
        "fmus": sorted(str(f) for f in out.rglob("*.fmu")),
        "total_time_s": seconds, "output_folder": str(out),
    }
    tmp = out / "summary.json.tmp"
    tmp.write_text(strict_json.dumps(summary, indent=1))
    tmp.replace(out / "summary.json")
    lines = ["", "=" * 72, f"done in {seconds / 60:.1f} min: {out}", f"  recommendation: {rec.headline()}",
             *(f"    {text}" for text in (rec.reason, rec.action) if text)]
    for m, q in summary["quality"].items():
        lines.append(f"  {m}: {'describes the data' if q['describes_data'] else 'does NOT describe the data'} "
                     f"(worst held-out AME {q['worst_ame_pct_of_peak']:.3g} % of peak, gate {q['gate_pct']:g} %)")
    if ame:
        models = sorted({m for r in ame.values() for m in r})
        lines.append("  validation AME [% of peak]: " + "; ".join(
            f"{n}: " + ", ".join(f"{m} {r[m]['ame_pct_of_peak']:.3g}" for m in models if m in r) for n, r in ame.items()))
    if summary["verdict"]:
        lines.append(f"  diagnosis: {summary['verdict']}")
    if summary["critical_speed_kmh"]:
        lines.append("  vehicle, hunting critical speed [km/h]: " + ", ".join(
            f"{k} {'-' if v is None else format(v, '.0f')}" for k, v in summary["critical_speed_kmh"].items()))
    if summary["report"]:
        lines.append(f"  report: {summary['report']}")
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
