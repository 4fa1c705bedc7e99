"""The report's vehicle section: the tuned FMUs as the vehicle's yaw dampers, side by side (``vehicle/vehicle.json``)."""
from __future__ import annotations

from pathlib import Path

from tuner.results.html import esc, figure_html, table
from tuner.vehicle.compare import VEHICLE_FOLDER, summary_rows
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
            + figs + "</section>")
