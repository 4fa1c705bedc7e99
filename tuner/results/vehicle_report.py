"""The report's vehicle section: the tuned FMUs as the vehicle's yaw dampers, side by side (``vehicle/vehicle.json``)."""
from __future__ import annotations

from pathlib import Path

from tuner.results.html import esc, figure_html, table
from tuner.vehicle.compare import VEHICLE_FOLDER, summary_rows
from tuner.vehicle.propagation import INTERVALS_FILE, SKEWED
from tuner import strict_json


__all__ = ["vehicle_section_html"]

def vehicle_section_html(out_dir) -> str:
    """HTML section for ``out_dir/vehicle/vehicle.json`` (``tuner.job.vehicle_consequences``): the tuned
    FMUs as the vehicle's yaw dampers, side by side ('' when there is none)."""
    folder = Path(out_dir) / VEHICLE_FOLDER
    path = folder / "vehicle.json"
    if not path.exists():
        return ""
    data = strict_json.loads(path.read_text())
    labels, rows = summary_rows(data)
    speeds = {lab: (r.get("critical_speed") or {}).get("critical_speed_kmh") for lab, r in data["results"].items()}
    speeds = {lab: v for lab, v in speeds.items() if v is not None}
    spread = ""
    if len(speeds) > 1:
        lo, hi = min(speeds, key=speeds.get), max(speeds, key=speeds.get)
        spread = (f"<p>The hunting critical speed ranges from {speeds[lo]:.0f} km/h ({esc(lo)}) to {speeds[hi]:.0f} "
                  f"km/h ({esc(hi)}): {speeds[hi] - speeds[lo]:.0f} km/h decided by the damper model alone, "
                  "each fitted to the same rig data.</p>")
    figs = "".join(figure_html(f"{VEHICLE_FOLDER}/{name}.png", esc(desc), "")
                   for name, desc in data["scenarios"].items() if (folder / f"{name}.png").exists())
    return ("<section id='vehicle'><h2>In the vehicle: what the damper model changes</h2>"
            "<p>Each tuned FMU as the four yaw dampers of the campaign's 14-degree-of-freedom vehicle (two "
            f"bogies, four wheelsets, linear creep), stepped at {1e3 * data['step_s']:g} ms by the vehicle as "
            "master (<code>python -m tuner vehicle</code>). Critical speed: kick runs and bisection on the growth "
            "rate of the least damped mode; for the linear Maxwell FMU also the eigenvalues of the linear vehicle "
            "(eig). Damper force: the largest of the four dampers; bogie yaw relative to the track.</p>"
            + spread + table(["quantity", *labels], [[esc(q), *(esc(c) for c in cells)] for q, cells in rows])
            + intervals_html(folder) + figs + "</section>")


def intervals_html(folder: Path) -> str:
    """The vehicle figures' 95 % intervals from ``folder/intervals.json`` (``tuner.vehicle.propagation``): a
    sentence per tuned FMU, a table with the Monte-Carlo errors and how the draws were made ('' without it)."""
    path = Path(folder) / INTERVALS_FILE
    if not path.exists():
        return ""
    data = strict_json.loads(path.read_text())
    rows, notes = [], []
    for label, r in data["results"].items():
        cs, pf = r["critical_speed"], r["peak_curve_force"]
        scatter = r.get("search_scatter_ms")

        def err(f, scale, unit):
            return "not estimable" if f["mc_error"] is None else f"+-{f['mc_error'] * scale:.2g} {unit}"

        rows.append([esc(label), esc(r["critical_speed_text"]), esc(err(cs, 3.6, "km/h")),
                     "-" if scatter is None else f"+-{scatter * 3.6:.2g}", esc(r["peak_curve_force_text"]),
                     esc(err(pf, 1e-3, "kN")), str(cs["draws"]) + (f" ({cs['failed']} failed)" if cs["failed"] else ""),
                     esc(cs["method"])])
        skew = [f"{f['quantity']}: skewed draws (skewness {f['skewness']:+.1f}), the normal-theory ends are rough"
                for f in (cs, pf) if f["method"] == "normal" and abs(f.get("skewness", 0.0)) > SKEWED]
        notes.append(f"<li>{esc(label)}: {esc(r['draws']['text'])}; {esc(r['stop'])}"
                     f"{''.join('; ' + esc(t) for t in skew)}</li>")
    errors = "".join(f"<li>{esc(k)}: no interval ({esc(v)})</li>" for k, v in data.get("errors", {}).items())
    return ("<h3>What the identification's uncertainty means in the vehicle</h3>"
            "<p>Parameter sets drawn from each fitted model's covariance (in the identification's coordinates, "
            "where the estimate is Gaussian; reflected at the bounds; parameters the rig tests do not see drawn "
            "uniformly within their bounds), each run as the four yaw dampers: the critical speed by the robust "
            "search from the fitted FMU's (its zero extrapolated from the decaying side), the curve entry's peak "
            "damper force on the same track. The nominal value is the fitted set's by the same search; 95 %: the "
            "interval over the draws (normal theory below 200 draws, empirical quantiles above); Monte-Carlo: "
            "the standard error of the interval's ends; search scatter: the fitted set's critical speed searched "
            "from three brackets.</p>"
            + table(["FMU", "critical speed", "Monte-Carlo", "search scatter [km/h]", "curve peak damper force",
                     "Monte-Carlo", "draws", "interval"], rows)
            + f"<ul>{''.join(notes)}{errors}</ul>")
