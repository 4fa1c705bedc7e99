"""The effect catalogue: one ``Effect`` record per effect element of the damper models.

What an effect is, in one place: its element parameters (``Parameter``: unit, default = off, model
bounds), which of them the diagnosis identifies (the first is the magnitude, 0 switches it off), their
typical magnitudes (design notes' catalogue: the virtual rig's draws, the plausibility flags, the
"physically meaningful" floor and the search range), how a typical magnitude scales with the damper
tested, the rule of each identified parameter's search bounds, the residual signature the diagnosis's
evidence regresses on, what the element stands for, how reports name it and the notes a verdict adds.

Seven effects form the catalogue of the design notes (the diagnosis's candidate causes,
``CATALOGUE_EFFECTS``); two *forms* beyond it (``FORM_EFFECTS``: pre-yield hysteresis and a bypass
groove) are tried when the catalogue leaves a residual above the floor. The physics of every element is
in ``damper_fmu.effects`` (Python) and the C kernel (``damper_fmu/c/damper_kernel.h``); the order of the
parameters here is the kernel's (``damper_fmu.c_header``). Adding an effect: docs/diagnosis.md,
"Adding an effect". SI units; forces tension +, stroke extension +, temperatures in degC.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Mapping

from .parameter_spec import Parameter

__all__ = ["Effect", "DataExtent", "ALL_EFFECTS", "CATALOGUE_EFFECTS", "FORM_EFFECTS", "EFFECT_PARAMETERS",
           "effect_of", "search_bounds", "SCALES_WITH_FORCE", "SCALES_WITH_STROKE"]

#: ``Effect.scaling`` values: the typical magnitude scales with the damper's peak force, or with its stroke
#: range (never above the catalogue's; ``tuner.diagnosis.effect_sizes``); other parameters do not scale
SCALES_WITH_FORCE = "peak force"
SCALES_WITH_STROKE = "stroke range"


@dataclass(frozen=True)
class DataExtent:
    """What the search bounds of an effect parameter depend on: the measured peak |force| [N], the stroke
    range of the data [m] (None: unknown) and the stroke's limits (min, max) [m] (None: unknown)."""

    peak_force_n: float
    stroke_range_m: float | None = None
    stroke_limits_m: tuple[float, float] | None = None

    @property
    def span_m(self) -> float:
        """The stroke range [m], 20 mm when unknown."""
        return self.stroke_range_m if self.stroke_range_m and self.stroke_range_m > 0 else 0.02


#: a search-bounds rule: (parameter, its typical |value| range or None, the data's extent) -> (low, high) [SI]
SearchRule = Callable[[Parameter, "tuple[float, float] | None", DataExtent], "tuple[float, float]"]


def twice_typical(p: Parameter, typical, data: DataExtent) -> tuple[float, float]:
    """(0, twice the top of the typical range), within the model bounds: every documented magnitude is
    reachable."""
    return (0.0, min(2.0 * typical[1], p.high))


def force_magnitude(p: Parameter, typical, data: DataExtent) -> tuple[float, float]:
    """(0, top) with top twice the typical top, raised to 10 % of the measured peak force (a larger damper
    may have more) and at most the peak force itself, within the model bounds."""
    top = min(max(2.0 * typical[1], 0.1 * data.peak_force_n), data.peak_force_n)
    return (0.0, min(top, p.high))


def signed_force(p: Parameter, typical, data: DataExtent) -> tuple[float, float]:
    """(-top, top) with top as ``force_magnitude`` (a force offset of either sign)."""
    top = force_magnitude(p, typical, data)[1]
    return (-top, top)


def gap(p: Parameter, typical, data: DataExtent) -> tuple[float, float]:
    """(0, twice the typical top) and at most the data's stroke range (a wider gap would leave the damper
    unloaded all along), within the model bounds."""
    top = 2.0 * typical[1]
    if data.stroke_range_m is not None and data.stroke_range_m > 0:
        top = min(top, data.stroke_range_m)
    return (0.0, min(top, p.high))


def displacement_scale(p: Parameter, typical, data: DataExtent) -> tuple[float, float]:
    """10 um up to half the stroke range, between 0.1 and 4 mm."""
    return (1e-5, max(1e-4, min(4e-3, 0.5 * data.span_m)))


def groove_centre(p: Parameter, typical, data: DataExtent) -> tuple[float, float]:
    """Within the stroke's limits (centred on zero, the stroke range wide, when unknown)."""
    if data.stroke_limits_m is not None:
        return tuple(data.stroke_limits_m)
    return (-0.5 * data.span_m, 0.5 * data.span_m)


def groove_length(p: Parameter, typical, data: DataExtent) -> tuple[float, float]:
    """5-80 % of the stroke range (at least 2 and 4 mm): a longer groove is a change of the whole
    characteristic, which the base absorbs."""
    return (max(2e-3, 0.05 * data.span_m), max(4e-3, 0.8 * data.span_m))


def share(p: Parameter, typical, data: DataExtent) -> tuple[float, float]:
    """A share of the damping force: 0-0.9."""
    return (0.0, 0.9)


@dataclass(frozen=True)
class Effect:
    """One effect element of the damper models (module docstring).

    name: as reports, settings and ``campaign.effects`` name it; label: how the verdict names it;
    form: beyond the design notes' catalogue (tried after its effects); kind: what the element stands for
    (a detection limit holds for that kind of effect only); parameters: every parameter of the element, in
    the C kernel's order (defaults switch it off); identified: those the diagnosis fits, magnitude first;
    typical: typical |value| (SI) of the identified parameters that are sizes; scaling: how those typical
    ranges scale with the damper (``SCALES_WITH_FORCE``, ``SCALES_WITH_STROKE``; absent: unchanged);
    search: the search-bounds rule of every identified parameter; symbol: the magnitude's symbol in the
    residual evidence and the virtual rig ('Ff'); signature: the residual regressor of the diagnosis's
    evidence (``tuner.diagnosis.residuals``; None: none, as for the forms); positive: the noun of the
    effect when its signature's coefficient must be positive to be evidence for it ('a friction'; None:
    either sign); note: what the verdict adds when it names the effect; acquisition: a property of the
    rig's channels or zero, not of the damper (the co-simulation model leaves it out); nonsmooth: its force
    has no gradient with respect to the magnitude at zero and the base absorbs part of it (a free play: a
    soft elastic table stands in for a dead band), so the refit's profile re-fits the model at every grid value
    of the magnitude (``tuner.diagnosis.held_profiles``) instead of re-balancing it on the base's Jacobian.
    """

    name: str
    label: str
    kind: str
    parameters: tuple[Parameter, ...]
    identified: tuple[str, ...]
    typical: Mapping[str, tuple[float, float]]
    search: Mapping[str, SearchRule]
    symbol: str
    form: bool = False
    scaling: Mapping[str, str] = field(default_factory=dict)
    signature: str | None = None
    positive: str | None = None
    note: str | None = None
    acquisition: bool = False
    nonsmooth: bool = False

    def __post_init__(self):
        names = [p.name for p in self.parameters]
        if any(p.effect != self.name for p in self.parameters):
            raise ValueError(f"effect {self.name}: every parameter must name it as its effect")
        for what, keys in (("identified", self.identified), ("typical", self.typical), ("search", self.search),
                           ("scaling", self.scaling)):
            unknown = [k for k in keys if k not in names]
            if unknown:
                raise ValueError(f"effect {self.name}: {what} names no parameter of it: {unknown}")
        if set(self.search) != set(self.identified):
            raise ValueError(f"effect {self.name}: a search rule is needed for each identified parameter")
        if self.identified[0] not in self.typical:
            raise ValueError(f"effect {self.name}: its magnitude {self.identified[0]} needs a typical range")

    @property
    def magnitude(self) -> str:
        """The identified parameter that switches the effect off at 0."""
        return self.identified[0]

    @property
    def unit(self) -> str:
        """The SI unit of the magnitude."""
        return next(p.unit for p in self.parameters if p.name == self.magnitude)


def _p(effect: str, name: str, unit: str, description: str, default: float, low: float, high: float,
       check: str | None = None) -> Parameter:
    """An effect parameter: not identified by the base fit, off (or neutral) at its default; checked within
    [low, high] unless ``check`` says otherwise (``parameter_spec.check_rule``)."""
    return Parameter(name, unit, description, default, low, high, tunable=False, effect=effect, check=check)


# Model bounds: what the tuner may identify (wider than the typical ranges; force effects up to 10 % of
# the 2 MN the data reader accepts, so that the diagnosis can search 10 % of any plausible damper's peak).
_RECORDS = (
    Effect(
        "friction", "Coulomb friction in parallel",
        "in parallel with the damper (rod seal, guides); a friction inside the valve is part of the damping "
        "characteristic",
        (_p("friction", "friction_force", "N", "Coulomb friction in parallel (seals, guides): Ff tanh(v / v_eps)",
            0.0, 0.0, 2e5),
         _p("friction", "friction_velocity", "m/s", "Velocity scale v_eps of the smoothed friction", 5e-4, 1e-5, 1e-2)),
        ("friction_force",), {"friction_force": (50.0, 300.0)}, {"friction_force": force_magnitude}, "Ff",
        scaling={"friction_force": SCALES_WITH_FORCE}, signature="tanh(v / 0.5 mm/s)", positive="a friction"),
    Effect(
        "preload", "preload (constant force offset)",
        "a constant force in parallel (un-tared gas force, load-cell offset)",
        (_p("preload", "preload_force", "N", "Constant force offset (un-tared gas force, load-cell offset); "
            "tension +", 0.0, -2e5, 2e5),),
        ("preload_force",), {"preload_force": (30.0, 400.0)}, {"preload_force": signed_force}, "F0",
        scaling={"preload_force": SCALES_WITH_FORCE}, signature="1",
        note="an un-tared gas force or load-cell offset: check the rig's zero before the test", acquisition=True),
    Effect(
        "free_play", "free play (dead band in series)",
        "a dead band in series at the actuator end (mounts, joints)",
        (_p("free_play", "free_play", "m", "Total clearance (dead band) in series at the actuator end",
            0.0, 0.0, 3e-3),),
        ("free_play",), {"free_play": (1e-4, 1e-3)}, {"free_play": gap}, "gap",
        scaling={"free_play": SCALES_WITH_STROKE}, signature="-F_sim in the apparent gap after velocity reversals",
        positive="a free play", nonsmooth=True),
    Effect(
        "thermal_drift", "thermal drift of the damping",
        "damping that changes with the oil temperature between tests",
        (_p("thermal_drift", "thermal_beta", "1/K", "Damping scaled by exp(-beta (T - T_ref)) with the oil "
            "temperature T", 0.0, 0.0, 0.05),
         # C and G scale with the damper (a consistently scaled damper heats alike): any positive value, the
         # balance being solved exactly over each step (effects.py); the bounds are the typical range
         _p("thermal_drift", "thermal_capacity", "J/K", "Heat capacity of the damper (internal thermal balance)",
            4000.0, 100.0, 1e5, check="positive"),
         _p("thermal_drift", "thermal_conductance", "W/K", "Heat loss to ambient per kelvin (internal thermal "
            "balance)", 5.0, 0.1, 1000.0, check="positive"),
         _p("thermal_drift", "thermal_reference", "degC", "Reference (and ambient) temperature T_ref",
            20.0, -40.0, 150.0)),
        ("thermal_beta",), {"thermal_beta": (2e-3, 2e-2)}, {"thermal_beta": twice_typical}, "beta",
        signature="g exp(-b x) F_sim, x the time since the test start or the temperature"),
    Effect(
        "valve_lag", "valve lag",
        "a first-order lag of the valve opening beyond the blow-off knee",
        (_p("valve_lag", "valve_tau", "s", "Valve opening time constant: force lead beyond the blow-off knee",
            0.0, 0.0, 0.05),),
        ("valve_tau",), {"valve_tau": (1e-3, 1e-2)}, {"valve_tau": twice_typical}, "tau",
        signature="-dF_sim/dt beyond the blow-off knee", positive="a valve lag"),
    Effect(
        "time_delay", "delay of the force channel",
        "a skew between the force and stroke channels (acquisition)",
        (_p("time_delay", "time_delay", "s", "Pure delay of the force channel relative to the stroke channel",
            0.0, 0.0, 0.05),),
        ("time_delay",), {"time_delay": (1e-3, 1e-2)}, {"time_delay": twice_typical}, "delay",
        signature="-dF_sim/dt", positive="a delay",
        note="a skew between the force and stroke channels (DAQ, filters): fix the acquisition; the exported "
             "co-simulation model should not contain it", acquisition=True),
    Effect(
        "inertia", "equivalent inertia",
        "a mass moving with the rod, seen by the load cell",
        (_p("inertia", "inertia_mass", "kg", "Equivalent inertia seen by the load cell: m_eq x1''", 0.0, 0.0, 500.0),),
        ("inertia_mass",), {"inertia_mass": (20.0, 200.0)}, {"inertia_mass": twice_typical}, "m_eq",
        scaling={"inertia_mass": SCALES_WITH_FORCE}, signature="x''", positive="an inertia"),
    Effect(
        "hysteresis", "pre-yield hysteresis",
        "a rate-independent hysteresis loop in parallel (a Dahl element: MR fluid below yield, seals that stick "
        "before they slide)",
        (_p("hysteresis", "hysteresis_force", "N", "Pre-yield hysteresis (Dahl element in parallel): force it "
            "saturates at", 0.0, 0.0, 2e5),
         _p("hysteresis", "hysteresis_displacement", "m", "Pre-yield hysteresis: displacement scale x_h of the "
            "approach to saturation (initial stiffness F_h / x_h)", 5e-4, 1e-6, 0.05)),
        ("hysteresis_force", "hysteresis_displacement"),
        {"hysteresis_force": (50.0, 1000.0), "hysteresis_displacement": (5e-5, 2e-3)},
        {"hysteresis_force": force_magnitude, "hysteresis_displacement": displacement_scale}, "F_h", form=True,
        scaling={"hysteresis_force": SCALES_WITH_FORCE, "hysteresis_displacement": SCALES_WITH_STROKE}),
    Effect(
        "bypass", "position-dependent damping (bypass groove)",
        "damping lower over part of the stroke (a groove past the piston)",
        (_p("bypass", "bypass_ratio", "1", "Position-dependent damping (bypass groove): damping force reduced by "
            "this fraction inside the groove", 0.0, 0.0, 0.95),
         _p("bypass", "bypass_center", "m", "Bypass groove centre (stroke, extension +)", 0.0, -1.0, 1.0),
         _p("bypass", "bypass_width", "m", "Bypass groove length along the stroke", 0.01, 1e-4, 1.0),
         _p("bypass", "bypass_edge", "m", "Bypass groove: length of its tapered ends (tanh edges)", 1e-3, 1e-5, 0.1),
         _p("bypass", "bypass_direction", "1", "Bypass groove acts in: 0 both directions, +1 extension (rebound) "
            "only, -1 compression only (a twin-tube groove in the pressure tube bypasses the piston valve in "
            "rebound)", 0.0, -1.0, 1.0),
         _p("bypass", "bypass_velocity", "m/s", "Bypass groove: speed above which its share fades, "
            "1 / (1 + (v / v_b)^2) (the valve opens past its blow-off knee and the groove's flow becomes a small "
            "part; 0: no fade)", 0.0, 0.0, 10.0)),
        ("bypass_ratio", "bypass_center", "bypass_width"), {"bypass_ratio": (0.1, 0.8)},
        {"bypass_ratio": share, "bypass_center": groove_centre, "bypass_width": groove_length}, "r", form=True),
)

#: every effect by name: the catalogue's first, then the forms (the order of the kernel's parameters)
ALL_EFFECTS: dict[str, Effect] = {e.name: e for e in _RECORDS}
#: the effect catalogue of the design notes (the diagnosis's candidate causes)
CATALOGUE_EFFECTS = tuple(e.name for e in _RECORDS if not e.form)
#: forms beyond the catalogue, tried when it leaves a residual above the floor
FORM_EFFECTS = tuple(e.name for e in _RECORDS if e.form)
#: the parameters of every effect element, in the C kernel's order (every model that carries effects
#: carries this block, ``damper_fmu.parameters``)
EFFECT_PARAMETERS: tuple[Parameter, ...] = tuple(p for e in _RECORDS for p in e.parameters)

_OF_PARAMETER = {p.name: e for e in _RECORDS for p in e.parameters}


def effect_of(parameter: str) -> Effect:
    """The effect whose element has the parameter named ``parameter``."""
    try:
        return _OF_PARAMETER[parameter]
    except KeyError:
        raise ValueError(f"{parameter!r} is no effect parameter; known: {', '.join(_OF_PARAMETER)}") from None


def search_bounds(name: str, peak_force: float, stroke_range_m: float | None = None,
                  stroke_limits: tuple[float, float] | None = None) -> tuple[float, float]:
    """Search bounds (SI) of the identified effect parameter ``name`` on data of peak |force| ``peak_force``
    [N], stroke range ``stroke_range_m`` [m] and stroke limits (min, max) [m], by its effect's rule
    (``Effect.search``; the rules' docstrings say what each allows)."""
    effect = effect_of(name)
    if name not in effect.search:
        raise ValueError(f"{name} is not identified by the diagnosis (effect {effect.name} identifies "
                         f"{', '.join(effect.identified)})")
    p = next(q for q in effect.parameters if q.name == name)
    return effect.search[name](p, effect.typical.get(name), DataExtent(peak_force, stroke_range_m, stroke_limits))
