"""Is it physically a damper on a rig? The plausibility checks of a test read, in both directions, and the
apparent damping's range per damper class (a warning outside it).

Each check names the file, the figure and the unit that would fit (``damper_dataset.format.suggest_unit``
among the units of the system the file was read in, ``tuner.data.units.family``).
"""
from __future__ import annotations

import numpy as np

from damper_dataset.format import DataError, suggest_unit
from tuner.data.differentiator import Differentiator
from tuner.data.read_options import DEFAULT_DAMPER_CLASS
from tuner.data.units import FORCE, STROKE, family

__all__ = ["plausibility", "class_warning", "DAMPER_CLASSES", "RAILWAY_DAMPER_CLASSES"]

MAX_STROKE_RANGE_M = 2.0
MIN_STROKE_RANGE_M = 5e-6
MAX_VELOCITY_M_S = 5.0
MIN_FORCE_PEAK_N = 1.0
MAX_FORCE_PEAK_N = 2e6
MIN_DAMPING_N_S_PER_M = 200.0
MAX_DAMPING_N_S_PER_M = 1e8
#: Apparent damping rms(F) / rms(v) [N s/m] of railway dampers by class: outside its class's range a
#: test is read with a warning (a force in kN read as N gives 1000x too little). Yaw dampers: 1.0e5 to
#: 1.1e6 on the bundled campaign and on the random dampers of ``campaign.damper_class`` (stiff low-speed
#: slopes, blow-off above a few cm/s), widened 3x each way; primary and secondary (vertical and lateral)
#: dampers are an order of magnitude softer. 'any' checks only the hard limits above.
DAMPER_CLASSES = {"yaw": (3e4, 3e6), "primary": (3e3, 3e5), "secondary": (3e3, 3e5),
                  "any": (MIN_DAMPING_N_S_PER_M, MAX_DAMPING_N_S_PER_M)}
#: the railway damper classes: data declared as another class ('any') is not read as a railway damper's
#: (the report then leaves out the railway wording: curving, stability)
RAILWAY_DAMPER_CLASSES = ("yaw", "primary", "secondary")
MIN_FORCE_VELOCITY_CORRELATION = -0.05


def class_warning(source, figures: dict, damper_class: str = DEFAULT_DAMPER_CLASS, units=None) -> str | None:
    """A warning when the apparent damping of :func:`plausibility`'s ``figures`` lies outside the
    range of ``damper_class`` (``DAMPER_CLASSES``), with the force unit that would bring it inside;
    None inside. ValueError for an unknown class."""
    if damper_class not in DAMPER_CLASSES:
        raise ValueError(f"unknown damper class {damper_class!r}; choose from {', '.join(DAMPER_CLASSES)}")
    c_app = figures.get("apparent_damping_n_s_per_m")
    lo, hi = DAMPER_CLASSES[damper_class]
    if c_app is None or lo <= c_app <= hi:
        return None
    fu = (units or {}).get("force", "N")
    return (f"{source}: apparent damping {c_app:.3g} N s/m (rms force / rms stroke velocity) is "
            f"{'below' if c_app < lo else 'above'} the {damper_class} damper range {lo:.0e}-{hi:.0e} N s/m "
            f"(force read in {fu!r})." + suggest_unit(family(FORCE, fu), fu, lambda r: lo <= c_app * r <= hi)
            + " Check --force-unit/--stroke-unit, or name the damper class with --damper-class "
            + "/".join(DAMPER_CLASSES))


def plausibility(source, time, stroke, force, velocity=None, rate=None, units=None) -> dict:
    """Refuse a test that is not physically a damper on a rig, in either direction.

    SI inputs: time [s], stroke [m], force [N], velocity [m/s] (None: the stroke differentiated
    over 20 Hz). Limits: stroke range 5 um .. 2 m; peak stroke velocity <= 5 m/s (a rig
    actuator's limit; a stroke in mm read as m gives tens of m/s); peak force 1 N .. 2 MN;
    apparent damping rms(F)/rms(v) from 200 N s/m (lighter than any vehicle damper: a force in kN
    read as N) to 1e8 N s/m (100 x a yaw damper's low-speed 1e6: a stroke in m read as mm); a
    passive damper absorbs power, so force and velocity must not be anti-correlated (correlation
    below -0.05: one of the two signs is flipped).
    ``units``: the units the file was read in, for the suggested fix. Returns the
    figures checked (SI); raises DataError naming the file, the figure and the likely fix.
    """
    units = units or {}
    su, fu = units.get("stroke", "m"), units.get("force", "N")
    rate = rate or (len(time) - 1) / (time[-1] - time[0])
    v = velocity if velocity is not None else Differentiator.design(rate, 20.0, max_window=len(stroke)).apply(stroke)
    srange = float(np.ptp(stroke))
    vpeak = float(np.max(np.abs(v)))
    fpeak = float(np.max(np.abs(force)))
    vrms = float(np.std(v))
    c_app = float(np.std(force) / vrms) if vrms > 1e-6 else None
    fv = np.asarray(force, dtype=float) - np.mean(force)
    power = float(np.mean(fv * v) / (np.std(fv) * vrms)) if vrms > 1e-6 and np.std(fv) > 0 else None
    fig = {"stroke_range_m": srange, "velocity_peak_m_s": vpeak, "force_peak_n": fpeak,
           "apparent_damping_n_s_per_m": c_app, "force_velocity_correlation": power}
    tail = " If the values are right, run with --accept-implausible."
    scaled = " A transducer's raw output (volts) needs its calibration: --stroke-scale, --force-scale."
    if srange > MAX_STROKE_RANGE_M or vpeak > MAX_VELOCITY_M_S:
        raise DataError(
            f"{source}: implausible stroke: range {srange:.4g} m, peak velocity {vpeak:.4g} m/s (a damper rig "
            f"moves <= {MAX_STROKE_RANGE_M:g} m at <= {MAX_VELOCITY_M_S:g} m/s) with stroke in {su!r}."
            + suggest_unit(family(STROKE, su), su, lambda r: srange * r <= MAX_STROKE_RANGE_M
                           and vpeak * r <= MAX_VELOCITY_M_S and srange * r >= MIN_STROKE_RANGE_M)
            + " Use --stroke-unit." + scaled + tail)
    if srange < MIN_STROKE_RANGE_M:
        raise DataError(
            f"{source}: implausible stroke: range {srange * 1e6:.3g} um (< {MIN_STROKE_RANGE_M * 1e6:g} um, under a "
            f"rig's displacement resolution) with stroke in {su!r}."
            + suggest_unit(family(STROKE, su), su, lambda r: MIN_STROKE_RANGE_M <= srange * r <= MAX_STROKE_RANGE_M)
            + " Use --stroke-unit, or the stroke signal is missing." + scaled + tail)
    if fpeak < MIN_FORCE_PEAK_N or fpeak > MAX_FORCE_PEAK_N:
        raise DataError(
            f"{source}: implausible force: peak |force| {fpeak:.4g} N (a damper on a rig: {MIN_FORCE_PEAK_N:g} N "
            f"to {MAX_FORCE_PEAK_N:.0e} N) with force in {fu!r}."
            + suggest_unit(family(FORCE, fu), fu, lambda r: MIN_FORCE_PEAK_N <= fpeak * r <= MAX_FORCE_PEAK_N)
            + " Use --force-unit, or the load signal is missing." + scaled + tail)
    if c_app is not None and c_app < MIN_DAMPING_N_S_PER_M:
        raise DataError(
            f"{source}: implausible force for its stroke: rms force {np.std(force):.4g} N at rms velocity "
            f"{vrms:.4g} m/s is an apparent damping of {c_app:.3g} N s/m, under the {MIN_DAMPING_N_S_PER_M:g} N s/m "
            f"of the lightest vehicle damper, with force in {fu!r} and stroke in {su!r}."
            + suggest_unit(family(FORCE, fu), fu,
                           lambda r: c_app * r >= MIN_DAMPING_N_S_PER_M and fpeak * r <= MAX_FORCE_PEAK_N)
            + " Use --force-unit/--stroke-unit." + scaled + tail)
    if power is not None and power < MIN_FORCE_VELOCITY_CORRELATION:
        raise DataError(
            f"{source}: force and stroke velocity are anti-correlated (correlation {power:+.2f}): the damper would "
            f"deliver power instead of absorbing it, so one sign convention differs from ours (stroke positive in "
            f"extension, force positive in tension). Use --force-sign -1 (or --stroke-sign -1)." + tail)
    if c_app is not None and c_app > MAX_DAMPING_N_S_PER_M:
        raise DataError(
            f"{source}: implausible stroke for its force: rms force {np.std(force):.4g} N at rms velocity "
            f"{vrms:.4g} m/s is an apparent damping of {c_app:.3g} N s/m, over {MAX_DAMPING_N_S_PER_M:.0e} N s/m "
            f"(100 x a yaw damper's), with stroke in {su!r} and force in {fu!r}."
            + suggest_unit(family(STROKE, su), su,
                           lambda r: c_app / r <= MAX_DAMPING_N_S_PER_M and srange * r <= MAX_STROKE_RANGE_M)
            + " Use --stroke-unit/--force-unit." + scaled + tail)
    return fig
