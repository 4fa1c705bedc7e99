"""Form candidates beyond the effect catalogue: elements real dampers show and the base forms lack.

When the catalogue leaves a residual above the floor on a converged fit, the diagnosis
(``tuner.diagnosis.diagnose``) tries each form of ``damper_fmu.effect_catalogue.FORM_EFFECTS`` on top of
the model it has (the base, or the base with the causes named): pre-yield hysteresis (a Dahl
element: MR fluid below yield, seals that stick before they slide) and position-dependent damping
(a bypass groove). A form has a magnitude (its first identified parameter, off at 0) and shape
parameters (a displacement scale; a groove's centre and length) on which the fit depends
nonlinearly and which a local solver cannot find from "off" (the residual does not depend on them
there). ``screen`` finds the shapes: for each shape of a grid (``shape_grid``) the force the form
adds at a probe magnitude is regressed on the residual after projecting out what the base can
absorb (the span of its Jacobian); the shapes whose projection explains most are then refitted
like every effect (``tuner.diagnosis.refit.refit``: a profile of the magnitude with the base
re-balanced, and a joint polish). The same rules then apply as for a catalogue cause: held-out
gain, force above the noise, a physical magnitude and an interval that excludes zero.
Units SI; forces in N, strokes in m.
"""
from __future__ import annotations

import numpy as np

from damper_fmu.effect_catalogue import ALL_EFFECTS, FORM_EFFECTS

from tuner.diagnosis.extended_parametrization import ExtendedParametrization
from tuner.diagnosis.screen import off_span
from tuner.identification.engine import Engine

__all__ = ["FORM_LABELS", "shape_grid", "screen", "settings_text", "PROBE_FRACTION"]

#: how the verdict names each form (``Effect.label``)
FORM_LABELS = {f: ALL_EFFECTS[f].label for f in FORM_EFFECTS}
#: the probe magnitude of the screen, as a fraction of the magnitude's search range (the form's force
#: is close to linear in its magnitude there: exactly for the hysteresis, to first order for the bypass)
PROBE_FRACTION = 0.25


def shape_grid(form: str, bounds: dict[str, tuple[float, float]], knee_m_s: float | None = None) -> list[dict]:
    """Shapes the screen tries for ``form``, within its search ``bounds`` {name: (low, high)} [SI]:
    eight hysteresis displacements spaced geometrically; bypass grooves centred at nine points
    across the inner 80 % of the stroke limits, each of three lengths spaced geometrically, acting in
    both directions, in extension only and in compression only, without a fade and fading past the
    blow-off knee ``knee_m_s`` [m/s] of the data (``tuner.diagnosis.residual_signatures.knee_velocity``). The
    direction and the fade speed are settings of the model the refit keeps, not identified."""
    if form == "hysteresis":
        lo, hi = bounds["hysteresis_displacement"]
        return [{"hysteresis_displacement": float(x)} for x in np.geomspace(lo, hi, 8)]
    if form == "bypass":
        c_lo, c_hi = bounds["bypass_center"]
        w_lo, w_hi = bounds["bypass_width"]
        margin = 0.1 * (c_hi - c_lo)
        fades = (0.0, float(knee_m_s)) if knee_m_s else (0.0,)
        return [{"bypass_center": float(c), "bypass_width": float(w), "bypass_direction": d, "bypass_velocity": f}
                for f in fades for d in (0.0, 1.0, -1.0) for c in np.linspace(c_lo + margin, c_hi - margin, 9)
                for w in np.geomspace(w_lo, w_hi, 3)]
    raise ValueError(f"unknown form {form!r}: expected one of {', '.join(FORM_LABELS)}")


def settings_text(settings: dict) -> str:
    """A form's fixed settings for people ('' when none): 'in extension only, fading above 12 mm/s'."""
    parts = []
    d = settings.get("bypass_direction")
    if d is not None:
        parts.append({1.0: "in extension only", -1.0: "in compression only"}.get(float(d), "in both directions"))
    if settings.get("bypass_velocity"):
        parts.append(f"fading above {1e3 * settings['bypass_velocity']:.3g} mm/s")
    return ", ".join(parts)


def screen(eid: Engine, ext: ExtendedParametrization, form: str, current: dict, jac_svd,
           keep: int = 2, knee_m_s: float | None = None) -> list[dict]:
    """The ``keep`` most promising shapes of ``form`` on top of the model ``current`` (its parameter
    values, the form off) of the identification engine ``eid``.

    ext: the current model extended by the form (its bounds); jac_svd: (U, s, Vt) of the current
    model's residual Jacobian (``tuner.diagnosis.extended_parametrization.base_jacobian``) or None; knee_m_s: as
    ``shape_grid``. For every shape the
    form's force at the probe magnitude is regressed on the residual, both projected off the
    Jacobian's span (what a re-balanced base absorbs); returns [{"shape": {...}, "magnitude": the
    regression's estimate (SI, within the search range), "gain_n2": the SSE it removes there [N^2],
    "held_magnitude": the same regression with the current model held as it is (no re-balance: where a
    shape that is not refitted is ranked, since its "magnitude" wins only with the model re-balanced)}],
    best first (shapes whose force cannot be simulated are skipped)."""
    magnitude = ALL_EFFECTS[form].magnitude
    bounds = dict(zip(ext.extra, ext.extra_bounds))
    lo, hi = bounds[magnitude]
    probe = lo + PROBE_FRACTION * (hi - lo)
    shapes = shape_grid(form, bounds, knee_m_s)
    runs = eid.residuals_batch([current] + [{**current, **s, magnitude: probe} for s in shapes])
    r0 = runs[0]
    if r0 is None:
        return []
    off_basis = off_span(jac_svd)
    r_p = off_basis(r0)
    rows = []
    for s, r in zip(shapes, runs[1:]):
        if r is None:
            continue
        d_p = off_basis(r0 - r)  # the simulated force the form adds at the probe magnitude
        dd = float(d_p @ d_p)
        if dd <= 0.0:
            continue
        # the regression's scale, held within the search range: the gain a magnitude outside the range would
        # bring is not on offer (unclipped, a groove on a real damper was predicted 57 % of the SSE, and won 0)
        a = min(max(float(d_p @ r_p) / dd, lo / probe), hi / probe)
        d = r0 - r
        a_held = min(max(float(d @ r0) / float(d @ d), lo / probe), hi / probe)
        rows.append({"shape": s, "magnitude": float(a * probe), "held_magnitude": float(a_held * probe),
                     "gain_n2": max(a * (2.0 * float(d_p @ r_p) - a * dd), 0.0)})
    rows.sort(key=lambda r: -r["gain_n2"])
    return rows[:keep]
