"""The report's vehicle section: the tuned FMUs as the vehicle's yaw dampers, side by side (``vehicle/vehicle.json``,
``python -m tuner --vehicle``), hunting with nonlinear wheel-rail contact (``vehicle/hunting_nonlinear.json`` and
its figures, ``python -m tuner vehicle --nonlinear --out RUN``): linear and nonlinear critical speeds per FMU and
conicity, the bifurcation diagrams, what the damper model changes for a worn-wheel bogie; and the tuned FMUs as
the yaw dampers of DTU's Cooperrider car on S1002/UIC60 contact (``vehicle/cooperrider.json``,
``python -m tuner vehicle --cooperrider --out RUN``) beside the cone car's critical speeds."""
from __future__ import annotations

import math
from pathlib import Path

from tuner.results.html import esc, figure_html, table
from tuner.vehicle.compare import VEHICLE_FOLDER, summary_rows
from tuner.vehicle.cooperrider_hunting import BUILT_IN, COOPERRIDER_FILE, cycle_text, speed_text
from tuner.vehicle.limit_cycles import CONICITY_FIGURE, DIAGRAM_FIGURE, STUDY_FILE, study_rows
from tuner.vehicle.propagation import INTERVALS_FILE, SKEWED
from tuner import strict_json


__all__ = ["vehicle_section_html", "linear_vehicle_html", "nonlinear_hunting_html", "worn_wheel_sentence",
           "intervals_html", "cooperrider_html", "SUBCRITICAL"]

SUBCRITICAL = 0.005
"""Relative margin [-] by which the nonlinear critical speed must lie below the linear one to be called
subcritical hunting in the report's sentence (the bisections' tolerance is about 2 km/h in 400)."""


def vehicle_section_html(out_dir) -> str:
    """HTML section for ``out_dir/vehicle/`` (``tuner.job.vehicle_consequences``, ``python -m tuner vehicle``):
    the tuned FMUs as the vehicle's yaw dampers side by side and, where it was run, hunting with nonlinear
    contact ('' when there is neither)."""
    folder = Path(out_dir) / VEHICLE_FOLDER
    parts = linear_vehicle_html(folder) + nonlinear_hunting_html(folder) + cooperrider_html(folder)
    if not parts:
        return ""
    return "<section id='vehicle'><h2>In the vehicle: what the damper model changes</h2>" + parts + "</section>"


def linear_vehicle_html(folder: Path) -> str:
    """The scenarios of ``folder/vehicle.json`` side by side, the spread of the critical speed, the 95 %
    intervals and the figures ('' without vehicle.json)."""
    path = Path(folder) / "vehicle.json"
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
                   for name, desc in data["scenarios"].items() if (Path(folder) / f"{name}.png").exists())
    return ("<p>Each tuned FMU as the four yaw dampers of the campaign's 14-degree-of-freedom vehicle (two "
            f"bogies, four wheelsets, linear creep), stepped at {1e3 * data['step_s']:g} ms by the vehicle as "
            "master (<code>python -m tuner vehicle</code>). Critical speed: kick runs and bisection on the growth "
            "rate of the least damped mode; for the linear Maxwell FMU also the eigenvalues of the linear vehicle "
            "(eig). Damper force: the largest of the four dampers; bogie yaw relative to the track.</p>"
            + spread + table(["quantity", *labels], [[esc(q), *(esc(c) for c in cells)] for q, cells in rows])
            + intervals_html(folder) + figs)


def nonlinear_hunting_html(folder: Path) -> str:
    """Hunting with nonlinear contact from ``folder/hunting_nonlinear.json`` (``tuner.vehicle.limit_cycles``):
    the method in a paragraph, the linear and nonlinear critical speeds per FMU and conicity, the sentence on
    the worn-wheel bogie, the eigenvalue check of a Maxwell FMU and the two figures ('' without the file)."""
    path = Path(folder) / STUDY_FILE
    if not path.exists():
        return ""
    data = strict_json.loads(path.read_text())
    contact, ramp = data["contact"], data["ramp"]
    labels, rows = study_rows(data)
    eig = [f"{esc(lab)} at {r['conicity']:g}: {r['eigenvalue_critical_speed_kmh']:.0f} km/h"
           for lab, res in data["results"].items() for r in res["conicities"]
           if r.get("eigenvalue_critical_speed_kmh") is not None]
    captions = {DIAGRAM_FIGURE: f"Hunting bifurcation diagrams at equivalent conicity {data['diagram_conicity']:g}: the "
                                "amplitude of the leading wheelset on the large hunting's branch against speed (ramp-"
                                "down), one panel per FMU; straight running stable below the linear critical speed "
                                "(dashed), hunting possible from the nonlinear one (red).",
                CONICITY_FIGURE: "Linear and nonlinear critical speed and the fold of large hunting against "
                                 "equivalent conicity (new wheels low, worn wheels high), every FMU."}
    figs = "".join(figure_html(f"{VEHICLE_FOLDER}/{name}", esc(cap), "")
                   for name, cap in captions.items() if (Path(folder) / name).exists())
    return ("<h3>Hunting with nonlinear wheel-rail contact</h3>"
            "<p>Each FMU as the four yaw dampers of the car with nonlinear wheel-rail contact (conical wheels, "
            f"creep saturating at mu N with mu = {contact['friction_coefficient']:g}, flange beyond "
            f"{1e3 * contact['flange_clearance']:g} mm; <code>python -m tuner vehicle --nonlinear</code>), per "
            "equivalent conicity. <b>Linear</b> critical speed: the linear car, "
            f"{1e3 * data['linear_kick_m']:g} mm kicks, bisection. <b>Nonlinear</b> critical speed: the lowest speed "
            f"at which hunting, once started, persists: a {1e3 * ramp['kick']:g} mm kick above the linear critical "
            f"speed, then the speed lowered in {3.6 * ramp['dv']:g} km/h steps along the large limit cycle to the "
            "fold of its branch (in brackets), or the linear critical speed where that is lower. '&gt; v_max': "
            "none found below the top speed.</p>"
            + table(["equivalent conicity", *(f"{lab}: linear / nonlinear (fold) [km/h]" for lab in labels)],
                    [[esc(c) for c in r] for r in rows])
            + f"<p>{worn_wheel_sentence(data)}</p>"
            + (f"<p>Eigenvalues of the linear car with the linear Maxwell FMU's stiffness and damping: "
               f"{'; '.join(eig)}.</p>" if eig else "")
            + figs)


def worn_wheel_sentence(data: dict) -> str:
    """What the damper model changes for a worn-wheel bogie, from ``hunting_nonlinear.json`` content: at the
    study's largest equivalent conicity, the nonlinear critical speeds [km/h] of the FMUs (their range when
    there are several) and the FMUs with which hunting is subcritical (the nonlinear critical speed more than
    :data:`SUBCRITICAL` below the linear one). Escaped HTML text."""
    lam = max(r["conicity"] for res in data["results"].values() for r in res["conicities"])
    at = {lab: next(r for r in res["conicities"] if r["conicity"] == lam)
          for lab, res in data["results"].items() if any(r["conicity"] == lam for r in res["conicities"])}
    nl = {lab: r["nonlinear_critical_speed_kmh"] for lab, r in at.items()
          if r["cycle_reached"] and r["nonlinear_critical_speed_kmh"] is not None}
    head = f"For a worn-wheel bogie (equivalent conicity {lam:g}, the largest of the study)"
    if not nl:
        return esc(f"{head} no FMU's nonlinear critical speed was found below the top speed of the study.")
    if len(nl) > 1:
        lo, hi = min(nl, key=nl.get), max(nl, key=nl.get)
        text = (f"{head} the nonlinear critical speed ranges from {nl[lo]:.0f} km/h ({lo}) to {nl[hi]:.0f} km/h "
                f"({hi}): {nl[hi] - nl[lo]:.0f} km/h decided by the damper model alone.")
    else:
        (lab, v), = nl.items()
        text = f"{head} the nonlinear critical speed with {lab} is {v:.0f} km/h."
    sub = []
    for lab, v in nl.items():
        lin = at[lab]["linear_critical_speed_kmh"]
        if lin is not None and math.isfinite(lin) and v < (1.0 - SUBCRITICAL) * lin:
            sub.append(f"{lab} ({100.0 * (1.0 - v / lin):.0f} % below its linear {lin:.0f} km/h)")
    if sub:
        text += (" Hunting is subcritical there with " + ", ".join(sub) + ": once a disturbance has started it, "
                 "it persists below the speed a linear analysis calls critical.")
    else:
        text += (" With no FMU does large hunting persist clearly below the linear critical speed there: the "
                 "linear critical speed is the limit.")
    return esc(text)


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
            "where the estimate is Gaussian, with the representation shift as a rank-one term so that each "
            "parameter spreads as its interval says; reflected at the bounds; parameters the rig tests do not see "
            "drawn "
            "uniformly within their bounds), each run as the four yaw dampers: the critical speed by the robust "
            "search from the fitted FMU's (its zero extrapolated from the decaying side), the curve entry's peak "
            "damper force on the same track. The nominal value is the fitted set's by the same search; 95 %: the "
            "interval over the draws (normal theory below 200 draws, empirical quantiles above); Monte-Carlo: "
            "the standard error of the interval's ends; search scatter: the fitted set's critical speed searched "
            "from three brackets.</p>"
            + table(["FMU", "critical speed", "Monte-Carlo", "search scatter [km/h]", "curve peak damper force",
                     "Monte-Carlo", "draws", "interval"], rows)
            + f"<ul>{''.join(notes)}{errors}</ul>")


def cooperrider_html(folder: Path) -> str:
    """The Cooperrider car on S1002/UIC60 from ``folder/cooperrider.json`` (``tuner.vehicle.cooperrider_hunting``):
    the method in a paragraph and a table, per yaw damper (the car's own ``D6`` dashpot first, then each FMU), of
    the linear critical speed, its ratio to the ``D6`` row's and the same FMU's critical speed on the cone car
    (``vehicle.json``, where it was run) ('' without the file)."""
    path = Path(folder) / COOPERRIDER_FILE
    if not path.exists():
        return ""
    data = strict_json.loads(path.read_text())
    cone_path = Path(folder) / "vehicle.json"
    cone = strict_json.loads(cone_path.read_text()).get("results", {}) if cone_path.exists() else {}
    ref = data["results"].get(BUILT_IN, {}).get("critical_speed_ms")
    rows = []
    for label, r in data["results"].items():
        v = r["critical_speed_ms"]
        cone_v = (cone.get(label, {}).get("critical_speed") or {}).get("critical_speed_kmh")
        rows.append([esc(label), esc(speed_text(r)), "-" if v is None or ref is None else f"{v / ref:.3f}",
                     "-" if cone_v is None else f"{cone_v:.0f}", esc(cycle_text(r) or "-"),
                     f"{r['wall_time_s'] + r.get('cycle_wall_time_s', 0.0):.0f}"])
    s, m = data["search"], data["model"]
    return ("<h3>Cooperrider car, S1002/UIC60</h3>"
            "<p>Each FMU as the four yaw dampers (the longitudinal secondary dashpots, D6 = "
            f"{m['yaw_damper_D6_ns_per_m'] * 1e-3:.4g} kN s/m, replaced; the parallel spring k6 = "
            f"{m['yaw_spring_k6_n_per_m'] * 1e-3:.4g} kN/m kept) of DTU's Cooperrider car: car body, two bogie frames, "
            "four wheelsets, the tabulated S1002 wheel on UIC60 rail at 1:40, Kalker creep saturating at mu N "
            "(<code>python -m tuner vehicle --cooperrider</code>; the car's parameters and contact table read at run "
            "time from the published input of the DTU simulator DYTSI, whose linear critical speed the car "
            "reproduces). "
            f"Co-simulated at {1e3 * s['step_s']:g} ms, the car by Runge-Kutta. Linear critical speed: the response "
            f"to a {1e3 * s['offset_m']:g} mm offset of the leading wheelset over {s['duration_s']:g} s turns from "
            "decay to growth (growth rate of its largest |y| in the last fifth against 40-60 % of the run), "
            f"interpolated between neighbouring speeds; {s['rounds']} rounds of {s['per_round']} speeds between "
            f"{s['v_min_ms']:g} and {s['v_max_ms']:g} m/s. Cone car: the same FMU's critical speed on the "
            "14-degree-of-freedom car above (constant conicity, linear creep). Limit cycle: at "
            f"{s['cycle_factor']:g} times the critical speed, half the leading wheelset's peak-to-peak motion over "
            f"the last {s['cycle_window_s']:g} s of {s['cycle_time_s']:g} s.</p>"
            + _cooperrider_spread(data["results"], cone)
            + table(["yaw damper", "linear critical speed", "/ D6 dashpot's", "cone car [km/h]",
                     "limit cycle at 1.05 x", "wall time [s]"], rows))


def _cooperrider_spread(results: dict, cone: dict) -> str:
    """A paragraph: the range of the FMUs' critical speeds on the Cooperrider car beside their range on the cone car
    ('' with fewer than two FMU speeds)."""
    v = {lab: r["critical_speed_ms"] for lab, r in results.items() if lab != BUILT_IN and r["critical_speed_ms"]}
    if len(v) < 2:
        return ""
    lo, hi = min(v, key=v.get), max(v, key=v.get)
    text = (f"On the Cooperrider car the tuned FMUs' linear critical speeds range from {v[lo]:.2f} m/s ({lo}) to "
            f"{v[hi]:.2f} m/s ({hi}): {3.6 * (v[hi] - v[lo]):.0f} km/h")
    c = {lab: (cone.get(lab, {}).get("critical_speed") or {}).get("critical_speed_kmh") for lab in v}
    c = {lab: x for lab, x in c.items() if x is not None}
    if len(c) > 1:
        text += f", against {max(c.values()) - min(c.values()):.0f} km/h on the cone car"
    return f"<p>{esc(text)}.</p>"
