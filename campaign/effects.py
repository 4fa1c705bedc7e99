"""Switchable hidden effects of the virtual rig (the diagnosis catalogue of design.md).

Each effect has one physical parameter with a documented realistic range and default:

============== ========= ====== ============ ======== ==============================================
name           parameter unit   range        default  where it acts
============== ========= ====== ============ ======== ==============================================
friction       Ff        N      50 - 300     150      seal/guide Coulomb friction ``Ff tanh(v/v_eps)``
                                                      between rod and cylinder (v_eps = 0.5 mm/s)
preload        F0        N      30 - 400     300      un-tared reservoir gas force / load-cell offset:
                                                      the force channel reads ``-F0`` more (the gas
                                                      pushes the rod out: compression); this damper's
                                                      own gas force is (p_g0 - p_atm) A_r = 291 N
free_play      gap       m      1e-4 - 1e-3  3e-4     total clearance (dead band) in the actuator-side
                                                      end mount, in series
thermal_drift  beta      1/K    2e-3 - 2e-2  1e-2     bleed and blow-off pressure drops scaled by
                                                      ``exp(-beta (T - T_ref))``, T_ref = 20 degC; oil
                                                      temperature from
                                                      ``C dT/dt = P_diss - hA (T - T_amb)``
                                                      (C = 4000 J/K, hA = 5 W/K)
valve_lag      tau       s      1e-3 - 1e-2  3e-3     first-order lag of the blow-off valve openings;
                                                      the valve opens late, so the force overshoots
                                                      while it opens and sags while it closes: near
                                                      the blow-off knee the residual LEADS (~ +dF/dt),
                                                      opposite to a first-order lag on the force
time_delay     delay     s      1e-3 - 1e-2  3e-3     force channel lags the stroke channel
                                                      (DAQ/filter skew): F_meas(t) = F(t - delay)
inertia        m_eq      kg     20 - 200     60       equivalent fluid/rod inertia added to the rod,
                                                      seen by the load cell as ~ m_eq x''
============== ========= ====== ============ ======== ==============================================

Default state: every effect is OFF. The rig damper itself always has what a real
twin-tube yaw damper has (oil compressibility with entrained air, bleed + blow-off +
check valves, reservoir gas stiffness, rubber mounts with damping, rod and body mass);
the static reservoir gas force is tared away as on a real rig, so ``preload`` is off
unless asked for; seal friction, play, heating, valve dynamics, channel skew and extra
fluid inertia are what the catalogue asks the tuner to find, so they are off too.

Two model *forms* beyond the catalogue (``FORMS``), for testing the diagnosis's form
candidates blind: the rig makes them with physics of its own, not with the tuner's equations.

============== ========= ====== ============ ======== ==============================================
name           parameter unit   range        default  where it acts
============== ========= ====== ============ ======== ==============================================
hysteresis     F_y       N      100 - 800    400      MR / seal pre-yield hysteresis: a Bouc-Wen
                                                      element ``F_y zeta`` between rod and cylinder,
                                                      ``zeta' = (v / x_y)(1 - zeta^2 (0.5 sign(v zeta)
                                                      + 0.5))``, x_y = 0.5 mm (v: piston velocity)
bypass         A_g       m^2    2e-8 - 15e-8 6e-8     bypass groove R <-> C in the pressure tube, 10 mm
                                                      long at mid-stroke (1 mm edges): a turbulent
                                                      orifice ``Cd A_g g(x) sqrt(2 |dp| / rho)`` in
                                                      parallel with the piston valve; rebound force
                                                      inside the groove -43 % at 5 mm/s, -38 % at
                                                      10 mm/s, -2.6 % at 30 mm/s (blow-off open);
                                                      compression unchanged (the foot valve sets it)
============== ========= ====== ============ ======== ==============================================

The forms' ``model_parameter`` names the tuner model's form parameter (``hysteresis_force``,
``bypass_ratio``), which this branch's ``damper_fmu`` need not have, so ``FORMS`` is not checked
against it (the catalogue is, in the tests). ``hysteresis``: the fitted ``hysteresis_force`` ~
``model_sign`` x F_y. ``bypass``: the model's ``bypass_ratio`` r (force x (1 - r) in the groove)
is not a multiple of the groove area; the rig's drop (above, ``quasi_static_force``) is what it
should find, and it depends on speed. The forms are twin-tube physics only: the lumped damper
refuses them (its hydraulics are the tuner's model).

The catalogue effects' symbols, units and realistic ranges are those of their records in
``damper_fmu.effect_catalogue`` (the one source); the defaults and where each acts are the rig's own.

Effect specifications: ``friction``, ``friction=150``, ``free_play=0.4e-3``, ``hysteresis=300``
(a bare name means the default value); several may be joined by commas.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Mapping

import numpy as np

from campaign.rig_damper import DamperConfig
from damper_fmu.effect_catalogue import ALL_EFFECTS, CATALOGUE_EFFECTS


@dataclass(frozen=True)
class EffectSpec:
    """One hidden effect: name, parameter name, unit, realistic range [low, high],
    default value, a one-line description, and the lumped-model effect parameter that
    measures it (``model_parameter`` = ``model_sign`` x the rig value, same unit)."""

    name: str
    parameter: str
    unit: str
    low: float
    high: float
    default: float
    description: str
    model_parameter: str
    model_sign: float = 1.0


#: the rig's own side of each catalogue effect: (default value, where it acts, sign of the model's magnitude
#: against the rig value); symbol, unit and realistic range are the catalogue's (``damper_fmu.effect_catalogue``)
_RIG_SIDE = {
    "friction": (150.0, "seal/guide Coulomb friction Ff tanh(v / 0.5 mm/s) in parallel", 1.0),
    "preload": (300.0, "un-tared reservoir gas force / load-cell offset: force reads -F0 more", -1.0),
    "free_play": (3e-4, "clearance (total dead band) in the actuator-side end mount", 1.0),
    "thermal_drift": (1e-2, "damping x exp(-beta (T - 20 degC)); the oil heats with dissipated power", 1.0),
    "valve_lag": (3e-3, "first-order lag of the blow-off valve openings", 1.0),
    "time_delay": (3e-3, "force channel lags the stroke channel by a pure delay", 1.0),
    "inertia": (60.0, "equivalent fluid/rod inertia seen by the load cell", 1.0),
}


def _catalogue_spec(name: str) -> EffectSpec:
    """The rig's effect ``name`` with its catalogue record's symbol, unit and typical range."""
    e = ALL_EFFECTS[name]
    default, where, sign = _RIG_SIDE[name]
    return EffectSpec(name, e.symbol, e.unit, *e.typical[e.magnitude], default, where, e.magnitude, sign)


#: the effect catalogue, as the rig makes it (module docstring)
EFFECTS: dict[str, EffectSpec] = {name: _catalogue_spec(name) for name in CATALOGUE_EFFECTS}

#: model forms beyond the catalogue (module docstring); selectable like the effects
FORMS: dict[str, EffectSpec] = {
    s.name: s for s in (
        EffectSpec("hysteresis", "F_y", "N", 100.0, 800.0, 400.0,
                   "pre-yield hysteresis: Bouc-Wen element F_y zeta between rod and cylinder, x_y = 0.5 mm",
                   "hysteresis_force"),
        EffectSpec("bypass", "A_g", "m^2", 2e-8, 1.5e-7, 6e-8,
                   "bypass groove R <-> C, 10 mm at mid-stroke: damping lower inside it", "bypass_ratio"),
    )
}
#: every selectable name: the catalogue and the forms
SPECS: dict[str, EffectSpec] = {**EFFECTS, **FORMS}

DEFAULT_EFFECTS: dict[str, float] = {}  # nothing on by default (see module docstring)
#: effects on the force channel after the damper (``apply_channel_effects``), not damper physics: those of the
#: acquisition (``Effect.acquisition``)
CHANNEL_EFFECTS = tuple(name for name in CATALOGUE_EFFECTS if ALL_EFFECTS[name].acquisition)


def parse_effect(text: str) -> tuple[str, float]:
    """Parse ``name`` or ``name=value`` into (name, value) with range checks."""
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"empty effect specification: {text!r}")
    name, sep, value = text.strip().partition("=")
    name = name.strip()
    if name not in SPECS:
        raise ValueError(f"unknown effect {name!r}; known: {', '.join(SPECS)}")
    if not sep:
        return name, SPECS[name].default
    try:
        v = float(value)
    except ValueError:
        raise ValueError(f"effect {name!r}: value {value.strip()!r} is not a number") from None
    return name, _check(name, v)


def parse_effects(specs: str | Iterable[str] | None) -> dict[str, float]:
    """Parse a comma-separated string or a list of specifications into a dict."""
    if specs is None:
        return {}
    items = specs.split(",") if isinstance(specs, str) else list(specs)
    out: dict[str, float] = {}
    for item in items:
        if isinstance(item, str) and not item.strip() and isinstance(specs, str):
            continue
        name, v = parse_effect(item)
        if name in out:
            raise ValueError(f"effect {name!r} given twice")
        out[name] = v
    return out


def _check(name: str, v: float) -> float:
    spec = SPECS[name]
    if not math.isfinite(v) or not (spec.low <= v <= spec.high):
        raise ValueError(f"effect {name!r}: {spec.parameter} = {v!r} {spec.unit} outside the "
                         f"realistic range [{spec.low:g}, {spec.high:g}] {spec.unit}")
    return float(v)


def validate_effects(effects: Mapping[str, float | None] | None) -> dict[str, float]:
    """Check names and ranges; a value None means the default. Returns a new dict."""
    if effects is None:
        return dict(DEFAULT_EFFECTS)
    if not isinstance(effects, Mapping):
        raise ValueError(f"effects must be a dict name -> value, got {type(effects).__name__}")
    out = {}
    for name, v in effects.items():
        if name not in SPECS:
            raise ValueError(f"unknown effect {name!r}; known: {', '.join(SPECS)}")
        if v is None:
            out[name] = SPECS[name].default
            continue
        try:
            fv = float(v)
        except (TypeError, ValueError):
            raise ValueError(f"effect {name!r}: value {v!r} is not a number") from None
        out[name] = _check(name, fv)
    return out


def physics_config(effects: Mapping[str, float]) -> DamperConfig:
    """The effects that act inside the damper physics, as a ``DamperConfig``."""
    e = validate_effects(effects)
    return DamperConfig(
        friction_force=e.get("friction", 0.0), free_play=e.get("free_play", 0.0),
        thermal_beta=e.get("thermal_drift", 0.0), valve_tau=e.get("valve_lag", 0.0),
        extra_mass=e.get("inertia", 0.0), preyield_force=e.get("hysteresis", 0.0),
        bypass_area=e.get("bypass", 0.0))


def apply_channel_effects(t: np.ndarray, force: np.ndarray,
                          effects: Mapping[str, float]) -> np.ndarray:
    """Effects on the force channel after the damper: ``preload`` (offset -F0 [N]) and
    ``time_delay`` (F(t - delay), held at F(t[0]) before the start). t [s], force [N]."""
    e = validate_effects(effects)
    out = np.asarray(force, dtype=float).copy()
    if "time_delay" in e:
        out = np.interp(np.asarray(t) - e["time_delay"], t, out, left=out[0])
    if "preload" in e:
        out = out - e["preload"]
    return out
