"""Hunting with nonlinear contact per damper FMU: bifurcation diagrams, linear and nonlinear critical speeds
against equivalent conicity, side by side (``python -m tuner vehicle --fmus ... --nonlinear``).

For each FMU (four copies as the car's yaw dampers) and each equivalent conicity [-]:

* the **linear critical speed** [m/s]: the car of :mod:`campaign.vehicle` (linear creep, no flange) with the
  FMUs, small lateral kicks (``linear_kick`` [m], 0.5 mm) and a bisection on speed
  (:func:`tuner.vehicle.hunting.critical_speed_time_domain`); for the linear Maxwell FMU also the
  eigenvalues;
* the **bifurcation diagram**: the nonlinear car (:mod:`campaign.vehicle_nonlinear`, saturating creep,
  flange) with the FMUs (:class:`tuner.vehicle.nonlinear_cosim.NonlinearCosim`), ramped down from a large
  limit cycle above the linear critical speed (:func:`campaign.bifurcation.ramp_down`): the stable
  branch's amplitude of the leading wheelset, its fold, and the **nonlinear critical speed** (the fold,
  or the linear critical speed if that is lower).

Runs for different FMUs and conicities are independent and go to a pool of ``workers`` processes (in
this process for one worker). Writes
``hunting_nonlinear.json``, ``hunting_bifurcation.png`` (one panel per FMU at ``diagram_conicity``) and
``critical_speed_conicity.png`` (linear and nonlinear critical speed against conicity, all FMUs).
"""
from __future__ import annotations

import dataclasses
import math
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from campaign.bifurcation import ConicityPoint, RampSettings, ramp_down, start_speed
from campaign.vehicle import VehicleParams
from campaign.vehicle_nonlinear import ContactSettings, kick_state
from tuner import strict_json
from tuner.vehicle.compare import fmu_labels, maxwell_values
from tuner.vehicle.cosim import VehicleCosim, check_damper_fmu
from tuner.vehicle.hunting import critical_speed_time_domain, eigen_critical_speed
from tuner.vehicle.nonlinear_cosim import NonlinearCosim

__all__ = ["HuntingStudy", "fmu_conicity_point", "hunting_study", "format_study_table", "study_rows", "speeds_cell",
           "DEFAULT_CONICITIES", "LINEAR_KICK", "STUDY_FILE", "DIAGRAM_FIGURE",
           "CONICITY_FIGURE"]

DEFAULT_CONICITIES = (0.05, 0.15, 0.25, 0.35, 0.45)
"""Equivalent conicities [-] of the sweep: new (0.05) to worn (0.45) wheels."""
LINEAR_KICK = 5e-4
"""Lateral kick [m] of the linear critical speed search (small: the dampers' small-amplitude behaviour)."""
STUDY_FILE = "hunting_nonlinear.json"
"""The study's file in its output folder (in a fit output folder: in its ``vehicle/`` sub-folder)."""
DIAGRAM_FIGURE = "hunting_bifurcation.png"
"""The bifurcation diagrams, one panel per FMU at the diagram conicity."""
CONICITY_FIGURE = "critical_speed_conicity.png"
"""Linear and nonlinear critical speed against conicity, all FMUs."""


@dataclasses.dataclass(frozen=True)
class HuntingStudy:
    """Settings of the study (SI units): ``conicities`` [-], ``diagram_conicity`` [-] (the one drawn as a
    bifurcation diagram; added to the sweep), speed range ``v_min``..``v_max`` [m/s], linear search
    tolerance ``tol`` [m/s], the ramp (:class:`campaign.bifurcation.RampSettings`), the contact
    (:class:`campaign.vehicle_nonlinear.ContactSettings`), the car ``params`` (its conicity replaced), the
    communication ``step`` [s] and ``workers`` processes."""

    conicities: tuple = DEFAULT_CONICITIES
    diagram_conicity: float = 0.25
    v_min: float = 100.0 / 3.6
    v_max: float = 1000.0 / 3.6
    tol: float = 2.0 / 3.6
    ramp: RampSettings = RampSettings()
    contact: ContactSettings = ContactSettings()
    params: VehicleParams = VehicleParams()
    step: float = 1e-3
    workers: int = 2

    def __post_init__(self) -> None:
        for lam in (*self.conicities, self.diagram_conicity):
            if not (math.isfinite(lam) and 0.0 < lam < 1.0):
                raise ValueError(f"conicity must be in (0, 1), got {lam}")
        if not (0.0 < self.v_min < self.v_max and math.isfinite(self.v_max)):
            raise ValueError(f"need 0 < v_min < v_max m/s, got {self.v_min}, {self.v_max}")
        if not (self.tol > 0.0 and isinstance(self.workers, int) and self.workers >= 1):
            raise ValueError(f"need tol > 0 and workers >= 1, got {self.tol}, {self.workers}")

    def all_conicities(self) -> list:
        return sorted(set(self.conicities) | {self.diagram_conicity})


def _linear_speed(fmu: Path, params: VehicleParams, study: HuntingStudy) -> float:
    """Linear critical speed [m/s] of the linear-contact car with the FMU (small kicks); ``inf`` above v_max."""
    with VehicleCosim(fmu, params=params, step=study.step) as co:
        res = critical_speed_time_domain(co, study.v_min, study.v_max, tol=study.tol, kick=LINEAR_KICK)
    return res.speed


def fmu_conicity_point(fmu, conicity: float, study: HuntingStudy) -> ConicityPoint:
    """Linear critical speed, bifurcation diagram and nonlinear critical speed [m/s] of the car with four
    copies of ``fmu`` at equivalent ``conicity`` [-] (module docstring)."""
    params = dataclasses.replace(study.params, conicity=float(conicity))
    v_lin = _linear_speed(Path(fmu), params, study)
    with NonlinearCosim(fmu, params=params, settings=study.contact, step=study.step) as co:
        d = ramp_down(co.runner(), start_speed(v_lin, study.v_max), study.v_min, kick_state(study.ramp.kick),
                      study.ramp, linear_critical_speed=v_lin, v_max=study.v_max)
    return ConicityPoint(float(conicity), d)


def _job(args):
    i, fmu, lam, study = args
    t0 = time.perf_counter()
    return i, lam, fmu_conicity_point(fmu, lam, study), time.perf_counter() - t0


def hunting_study(fmus, out: Path, study: HuntingStudy | None = None, *, log=print) -> dict:
    """Run the study (module docstring) for each damper FMU of ``fmus`` (paths), write the JSON and the two
    figures into ``out`` and return the JSON content (speeds in km/h, amplitudes in mm)."""
    study = study if study is not None else HuntingStudy()
    paths = [Path(f) for f in fmus]
    if not paths:
        raise ValueError("give at least one damper FMU")
    for p in paths:
        check_damper_fmu(p)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    labels = fmu_labels(paths)
    jobs = [(i, p, lam, study) for i, p in enumerate(paths) for lam in study.all_conicities()]
    points: dict = {lab: {} for lab in labels}
    t0 = time.perf_counter()
    workers = min(study.workers, len(jobs))
    pool = ProcessPoolExecutor(max_workers=workers) if workers > 1 else None
    try:
        for i, lam, pt, wall in (pool.map(_job, jobs) if pool is not None else map(_job, jobs)):
            points[labels[i]][lam] = pt
            log(f"{labels[i]}: conicity {lam:.3f}: linear {_kmh(pt.linear_critical_speed)}, nonlinear "
                f"{_kmh(pt.nonlinear_critical_speed)} km/h ({len(pt.diagram.cycles)} plateaus, {wall:.0f} s)")
    finally:
        if pool is not None:
            pool.shutdown(cancel_futures=True)
    data = _json(points, paths, labels, study, time.perf_counter() - t0)
    (out / STUDY_FILE).write_text(strict_json.dumps(data, indent=1))
    _figures(points, study, out)
    return data


def _kmh(v: float):
    return "> v_max" if math.isinf(v) else "no cycle reached" if math.isnan(v) else f"{v * 3.6:.1f}"


def _json(points: dict, paths, labels, study: HuntingStudy, wall: float) -> dict:
    res = {}
    for p, lab in zip(paths, labels):
        mx = maxwell_values(p)
        rows = []
        for lam, pt in sorted(points[lab].items()):
            d = pt.diagram
            v, a = d.branch()
            row = {"conicity": lam, "linear_critical_speed_kmh": _num(d.linear_critical_speed * 3.6),
                   "fold_speed_kmh": _num(d.fold_speed * 3.6),
                   "fold_bracket_kmh": [_num(b * 3.6) for b in d.bracket],
                   "nonlinear_critical_speed_kmh": _num(d.nonlinear_critical_speed * 3.6),
                   "cycle_reached": d.cycle_reached,
                   "fold_below_v_min": d.fold_below_stop,
                   "branch": {"speed_kmh": list(v * 3.6), "amplitude_mm": list(a * 1e3)},
                   "plateaus": [{k: getattr(c, k) for k in ("speed", "amplitude", "exists", "converged", "duration")}
                                for c in d.cycles]}
            if mx is not None:
                ve = eigen_critical_speed(mx["k_s"], mx["c"], dataclasses.replace(study.params, conicity=lam),
                                          v_max=study.v_max)
                row["eigenvalue_critical_speed_kmh"] = _num(ve * 3.6)
            rows.append(row)
        res[lab] = {"fmu": str(p), "conicities": rows}
    return {"diagram_conicity": study.diagram_conicity, "contact": dataclasses.asdict(study.contact),
            "ramp": dataclasses.asdict(study.ramp), "linear_kick_m": LINEAR_KICK, "step_s": study.step,
            "wall_time_s": wall, "results": res}


def _num(v: float):
    return None if not math.isfinite(v) else float(v)


def _figures(points: dict, study: HuntingStudy, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = list(points)
    fig, axes = plt.subplots(1, len(labels), figsize=(4.2 * len(labels), 3.8), sharey=True, squeeze=False)
    for ax, lab in zip(axes[0], labels):
        _diagram_panel(ax, lab, points[lab][study.diagram_conicity], study)
    axes[0][0].set_ylabel("limit cycle amplitude, leading wheelset [mm]")
    fig.suptitle(f"Hunting bifurcation diagrams, equivalent conicity {study.diagram_conicity:g}")
    fig.tight_layout()
    fig.savefig(out / DIAGRAM_FIGURE, dpi=110)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for i, lab in enumerate(labels):
        lam = np.array(sorted(points[lab]))
        lin = np.array([points[lab][x].linear_critical_speed for x in lam]) * 3.6
        nl = np.array([points[lab][x].nonlinear_critical_speed for x in lam]) * 3.6
        color = f"C{i}"
        ax.plot(lam, np.where(np.isfinite(lin), lin, np.nan), "--o", color=color, mfc="none", label=f"{lab}: linear")
        fold = np.array([points[lab][x].diagram.fold_speed for x in lam]) * 3.6
        ax.plot(lam, np.where(np.isfinite(nl), nl, np.nan), "-s", color=color, label=f"{lab}: nonlinear")
        ax.plot(lam, np.where(np.isfinite(fold), fold, np.nan), ":^", color=color, ms=4,
                label=f"{lab}: fold of large hunting")
    ax.set_xlabel("equivalent conicity [-]")
    ax.set_ylabel("critical speed [km/h]")
    ax.set_title(f"Critical hunting speed against wheel conicity (drawn up to {study.v_max * 3.6:.0f} km/h)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / CONICITY_FIGURE, dpi=110)
    plt.close(fig)


def _diagram_panel(ax, label: str, pt: ConicityPoint, study: HuntingStudy) -> None:
    d = pt.diagram
    v, a = d.branch()
    ax.plot(v * 3.6, a * 1e3, "-o", ms=3, label="stable limit cycle (ramp-down)")
    lost = [c for c in d.cycles if not c.exists]
    if lost:
        ax.plot([c.speed * 3.6 for c in lost], [0.0] * len(lost), "x", color="C3", label="left the branch")
    vl = d.linear_critical_speed
    top = study.v_max
    if math.isfinite(vl):
        ax.plot([study.v_min * 3.6, vl * 3.6], [0, 0], "k-", lw=2, label="stable straight running")
        ax.plot([vl * 3.6, top * 3.6], [0, 0], "k:", lw=2, label="unstable straight running")
        ax.axvline(vl * 3.6, color="k", ls="--", lw=0.8)
    if math.isfinite(d.nonlinear_critical_speed):
        ax.axvline(d.nonlinear_critical_speed * 3.6, color="C3", lw=0.8)
    ax.axhline(study.contact.flange_clearance * 1e3, color="0.6", lw=0.8, ls="-.", label="flange clearance")
    ax.set_title(f"{label}\nlinear {_kmh(vl)} / nonlinear {_kmh(d.nonlinear_critical_speed)} km/h", fontsize=9)
    ax.set_xlabel("speed [km/h]")
    speeds = [c.speed for c in d.cycles] + ([vl] if math.isfinite(vl) else [])
    ax.set_xlim(max(study.v_min, 0.85 * min(speeds)) * 3.6, min(top, 1.05 * max(speeds)) * 3.6)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=6, loc="upper left")


def speeds_cell(row: dict) -> str:
    """One conicity's critical speeds of one FMU as text (a ``conicities`` row of ``hunting_nonlinear.json``):
    ``linear / nonlinear (fold)`` [km/h], ``> v_max`` where none was found below the top speed, ``no cycle``
    where the ramp's kick reached no limit cycle although straight running was unstable."""
    f = (lambda v: "> v_max" if v is None else f"{v:.0f}")
    nl = f(row["nonlinear_critical_speed_kmh"]) if row["cycle_reached"] or row["linear_critical_speed_kmh"] is None \
        else "no cycle"
    fold = f" ({f(row['fold_speed_kmh'])})" if row["cycle_reached"] else ""
    return f"{f(row['linear_critical_speed_kmh'])} / {nl}{fold}"


def study_rows(data: dict) -> tuple:
    """The study's critical speeds side by side: (FMU labels, rows), one row per conicity: the conicity [-]
    and per FMU its :func:`speeds_cell` ('-' where that FMU has no run at that conicity)."""
    labels = list(data["results"])
    lams = sorted({row["conicity"] for lab in labels for row in data["results"][lab]["conicities"]})

    def cell(lab, lam):
        row = next((r for r in data["results"][lab]["conicities"] if r["conicity"] == lam), None)
        return "-" if row is None else speeds_cell(row)

    return labels, [[f"{lam:.3f}", *(cell(lab, lam) for lab in labels)] for lam in lams]


def format_study_table(data: dict) -> str:
    """The study's critical speeds as a text table (:func:`study_rows`): one row per conicity, per FMU the
    linear and the nonlinear critical speed [km/h] and the fold of the large cycles' branch in brackets."""
    labels, rows = study_rows(data)
    head = ["conicity", *(f"{lab}: linear / nonlinear (fold) [km/h]" for lab in labels)]
    w = [max(len(head[i]), *(len(r[i]) for r in rows)) for i in range(len(head))]
    return "\n".join("  ".join(c.rjust(wi) for c, wi in zip(r, w)) for r in [head, *rows])
