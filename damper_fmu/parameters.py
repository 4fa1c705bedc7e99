"""Parameter definitions, reference presets and bounds of the damper models.

Every parameter (``damper_fmu.parameter_spec.Parameter``) carries its SI unit, a description, the
reference (default) value and the identification bounds; the effect elements' parameters
(``EFFECT_PARAMETERS``, the last block of the lumped and two-chamber models) come from the effect
catalogue (``damper_fmu.effect_catalogue``). Sign convention (whole package): elongation and elongation rate
positive in extension, element forces positive in tension.

Lumped model (Isacchi, Ripamonti, Corsi 2023, section 2.1): 29 tunable parameters
    M_C, M_O, M_P [kg], k_B [N/m], c_B [N s/m],
    Fk_01..Fk_10 [N]  ordinates of the elastic table Fk,O at the fixed elongations Fk_x01..Fk_x10 [m],
    Fc_01..Fc_14 [N]  ordinates of the damping table Fc,O at the fixed rates Fc_v01..Fc_v14 [m/s];
both tables pass through F(0) = 0, so the zero abscissa carries no parameter. The abscissae are
``fixed`` parameters (set before a run, not identified): the paper chooses them per damper.
The reference preset is the paper's Table 2; the bounds are the paper's section 2.3 values, those of its
20 kN yaw damper: the tuner maps every bound and fixed constant to the damper tested
(``tuner.identification.damper_scale``).

Two-chamber model (``models.TwoChamberModel``, a twin-tube form): 38 tunable parameters
    k_M [N/m], c_M [N s/m] mounts, k_R, k_C [N/m] chamber stiffnesses, area_ratio [1],
    L_R, L_C [m] chamber lengths, air [1], f_res [N], k_gas [N/m],
    Fc_01..Fc_28 [N]  ordinates of the damping table at Fc_v01..Fc_v28 [m/s] (Table 2's abscissae
    with the midpoints added: the valves' knees need the finer layout),
the fixed check-valve slope check_damping [N s/m] (0, the default: 0.4 % of the damping table's mean slope to its
last rate, 1.01e3 N s/m on the preset, so that it follows the damper's table) and the effect elements (seal friction inside the
mounts, at the piston velocity). Its preset is a fit to the virtual rig's
twin-tube damper (docs/twin-tube-form-study.md), a plausible railway yaw damper, not a paper value.
"""
from __future__ import annotations

from .effect_catalogue import EFFECT_PARAMETERS
from .parameter_spec import Parameter, check_rule

__all__ = [
    "EFFECT_PARAMETERS",
    "FK_ABSCISSAE",
    "FC_ABSCISSAE",
    "LUMPED_PARAMETERS",
    "MAXWELL_PARAMETERS",
    "MAXWELL_TABLE_PARAMETERS",
    "TWOCHAMBER_PARAMETERS",
    "TWOCHAMBER_FC_ABSCISSAE",
    "densify_abscissae",
    "MODEL_PARAMETERS",
    "MODEL_KINDS",
    "EFFECT_MODELS",
    "parameter_group",
    "EFFECTS_INSIDE",
    "defaults",
    "tunable_names",
    "check_values",
    "UNIT_DEFINITIONS",
]

#: SI base-unit exponents of every unit used (FMU UnitDefinitions).
UNIT_DEFINITIONS: dict[str, dict[str, float]] = {
    "m": {"m": 1}, "m/s": {"m": 1, "s": -1}, "s": {"s": 1}, "kg": {"kg": 1},
    "N": {"kg": 1, "m": 1, "s": -2}, "N/m": {"kg": 1, "s": -2}, "N.s/m": {"kg": 1, "s": -1},
    "1": {}, "K": {"K": 1}, "1/K": {"K": -1}, "J/K": {"kg": 1, "m": 2, "s": -2, "K": -1},
    "W/K": {"kg": 1, "m": 2, "s": -3, "K": -1}, "degC": {"K": 1, "offset": 273.15},
}


# Table 2 of the paper: elongation abscissae [mm] and ordinates [kN] of Fk,O (zero point omitted).
_FK_X_MM = (-2.0, -1.0, -0.75, -0.5, -0.25, 0.25, 0.5, 0.75, 1.0, 2.0)
_FK_KN = (-34.0, -17.0, -11.0, -7.7, -3.4, 3.6, 7.5, 11.0, 17.0, 36.0)
# Rate abscissae [mm/s] and ordinates [kN] of Fc,O (zero point omitted).
_FC_V_MMS = (-100.0, -30.0, -15.0, -10.0, -7.5, -5.0, -2.5, 2.5, 5.0, 7.5, 10.0, 15.0, 30.0, 100.0)
_FC_KN = (-26.0, -20.0, -16.0, -12.0, -9.2, -6.1, -2.2, 2.3, 6.6, 9.1, 12.0, 16.0, 20.0, 25.0)

FK_ABSCISSAE = tuple(x * 1e-3 for x in _FK_X_MM)  # [m]
FC_ABSCISSAE = tuple(v * 1e-3 for v in _FC_V_MMS)  # [m/s]

#: Linear spring the paper's Fk,O bounds are built around [N/m].
FK_REFERENCE_STIFFNESS = 1.5e7
#: Paper's force limit of the Fc,O ordinates [N].
FC_FORCE_LIMIT = 3.0e4


def _fk_bounds(x: float) -> tuple[float, float]:
    """Bounds of an Fk,O ordinate at elongation x [m]: 0.2..3 times the 1.5e7 N/m spring force."""
    a, b = 0.2 * FK_REFERENCE_STIFFNESS * x, 3.0 * FK_REFERENCE_STIFFNESS * x
    return (min(a, b), max(a, b))


def _fc_bounds(v: float) -> tuple[float, float]:
    """Bounds of an Fc,O ordinate at rate v [m/s]: same sign as v, |F| <= 3e4 N (dissipative)."""
    return (0.0, FC_FORCE_LIMIT) if v > 0 else (-FC_FORCE_LIMIT, 0.0)


def _table_parameters(prefix: str, abscissae, ordinates_kn, xunit: str, what: str, bounds):
    params = []
    for i, (x, f) in enumerate(zip(abscissae, ordinates_kn), start=1):
        lo, hi = bounds(x)
        params.append(Parameter(
            f"{prefix}_{i:02d}", "N",
            f"{what} ordinate at {'elongation' if xunit == 'm' else 'elongation rate'} "
            f"{prefix}_{'x' if xunit == 'm' else 'v'}{i:02d}", f * 1e3, lo, hi))
    for i, x in enumerate(abscissae, start=1):
        axis = "x" if xunit == "m" else "v"
        params.append(Parameter(
            f"{prefix}_{axis}{i:02d}", xunit,
            f"{what} abscissa {i} ({'elongation' if xunit == 'm' else 'elongation rate'}, fixed)",
            x, -10.0 if xunit == "m" else -100.0, 10.0 if xunit == "m" else 100.0, tunable=False))
    return params


_FK = _table_parameters("Fk", FK_ABSCISSAE, _FK_KN, "m", "Elastic force Fk,O", _fk_bounds)
_FC = _table_parameters("Fc", FC_ABSCISSAE, _FC_KN, "m/s", "Damping force Fc,O", _fc_bounds)

LUMPED_PARAMETERS: tuple[Parameter, ...] = (
    Parameter("M_C", "kg", "Lumped mass C (cylinder side, next to silent block B)", 15.8, 1.0, 20.0),
    Parameter("M_O", "kg", "Lumped mass O (oil, between Fc,O and Fk,O)", 16.5, 1.0, 20.0),
    Parameter("M_P", "kg", "Lumped mass P (piston side, next to silent block A)", 17.3, 1.0, 20.0),
    Parameter("k_B", "N/m", "Silent block stiffness (each end)", 4.08e8, 1e2, 1e9, log_scale=True),
    Parameter("c_B", "N.s/m", "Silent block damping (each end)", 4.17e6, 1e2, 1e7, log_scale=True),
    *[p for p in _FK if p.tunable],
    *[p for p in _FC if p.tunable],
    *[p for p in _FK if not p.tunable],
    *[p for p in _FC if not p.tunable],
    *EFFECT_PARAMETERS,
)

MAXWELL_PARAMETERS: tuple[Parameter, ...] = (
    Parameter("k_s", "N/m", "Series stiffness of the Maxwell element", 1.4e7, 1e5, 1e9, log_scale=True),
    Parameter("c", "N.s/m", "Linear damping of the Maxwell dashpot", 5.0e5, 1e3, 1e7, log_scale=True),
)

MAXWELL_TABLE_PARAMETERS: tuple[Parameter, ...] = (
    Parameter("k_s", "N/m", "Series stiffness of the Maxwell element", 1.4e7, 1e5, 1e9, log_scale=True),
    *_FC,
)


def densify_abscissae(abscissae) -> tuple[float, ...]:
    """The abscissae with the midpoint of every piece from zero outwards added (twice as many)."""
    out = []
    for side in ([x for x in abscissae if x < 0][::-1], [x for x in abscissae if x > 0]):
        prev, pts = 0.0, []
        for x in side:
            pts += [0.5 * (prev + x), x]
            prev = x
        out += pts
    return tuple(sorted(out))


#: Damping-table abscissae of the two-chamber model [m/s]: Table 2's with the midpoints added.
TWOCHAMBER_FC_ABSCISSAE = densify_abscissae(FC_ABSCISSAE)
# Preset ordinates [kN]: the fit tc_pos_air_gas_x2 of seed 1 (docs/twin-tube-form-study-results.txt), rounded.
_FC_TC_KN = (-25.19, -22.37, -19.08, -18.29, -17.33, -16.46, -12.44, -10.45, -8.54, -6.81, -5.22, -3.72, -2.39,
             -1.12, 1.12, 2.37, 3.72, 5.22, 6.82, 8.55, 10.39, 12.38, 16.44, 17.31, 18.27, 19.08, 22.37, 25.29)
_FC_TC = _table_parameters("Fc", TWOCHAMBER_FC_ABSCISSAE, _FC_TC_KN,
                           "m/s", "Damping force Fc,O (piston valve in rebound, foot valve in compression)",
                           _fc_bounds)

#: Two-chamber (twin-tube) model; preset: a fit to the virtual rig's twin-tube damper.
TWOCHAMBER_PARAMETERS: tuple[Parameter, ...] = (
    Parameter("k_M", "N/m", "Mount stiffness (both silent blocks in series)", 2.99e7, 1e5, 1e11, log_scale=True),
    Parameter("c_M", "N.s/m", "Mount damping (both silent blocks in series)", 5.1e4, 1e1, 1e8, log_scale=True),
    Parameter("k_R", "N/m", "Rebound-chamber hydraulic stiffness at mid-stroke, bubble-free oil (beta Aa^2 / V_R)",
              2.38e7, 1e5, 1e10, log_scale=True),
    Parameter("k_C", "N/m", "Compression-chamber hydraulic stiffness at mid-stroke, bubble-free oil "
              "(beta Ap^2 / V_C)", 7.59e7, 1e5, 1e10, log_scale=True),
    Parameter("area_ratio", "1", "Annulus area / piston area Aa / Ap", 0.336, 0.02, 0.98, check="range"),
    Parameter("L_R", "m", "Rebound-chamber length at mid-stroke V_R0 / Aa (stiffness grows as the chamber "
              "shortens)", 0.096, 0.05, 100.0, log_scale=True),
    Parameter("L_C", "m", "Compression-chamber length at mid-stroke V_C0 / Ap", 0.089, 0.05, 100.0, log_scale=True),
    Parameter("air", "1", "Entrained-air softening of the oil at reservoir pressure (0: none)", 3.45, 0.0, 50.0,
              check="range"),
    Parameter("f_res", "N", "Reservoir pressure times piston area Ap p_res (scale of the air's stiffening)",
              878.0, 10.0, 1e5, log_scale=True),
    # any non-negative value: the bounds are the reference damper's, a consistently scaled damper 20 times
    # stronger has 20 times its gas spring (tuner.identification.damper_scale)
    Parameter("k_gas", "N/m", "Reservoir gas spring on the rod, zero at the start stroke", 1727.0, 0.0, 2e4,
              check="nonnegative"),
    *[p for p in _FC_TC if p.tunable],
    Parameter("check_damping", "N.s/m", "Slope of the piston and intake check valves (fixed); 0: 0.4 % of the damping "
              "table's mean slope to its last rate (models.CHECK_SHARE)", 0.0, 0.0, 1e6, tunable=False,
              check="nonnegative"),
    *[p for p in _FC_TC if not p.tunable],
    *EFFECT_PARAMETERS,
)

#: Models that carry the effect elements (damper_fmu.effects), and where friction and free play act:
#: the lumped model adds them at the actuator; the two-chamber model has a piston and a mount, and
#: seal friction acts between rod and cylinder, inside the mounts (docs/twin-tube-form-study.md:
#: outside, a 150 N friction was fitted as 26 N), the free play in the mount (outside, the chambers stayed loaded across the gap:
#: a twin-tube damper's 0.3 mm play fitted as 0).
EFFECT_MODELS = ("lumped", "twochamber")
EFFECTS_INSIDE = ("twochamber",)
#: The elastic element in series with the free play in each effect model, (stiffness [N/m], damping [N s/m]):
#: the lumped model's silent blocks, the two-chamber model's mount. A free play and a soft or dashpot-like
#: series element trade for each other in a fit (``tuner.diagnosis.held_profiles.series_profiles``).
SERIES_ELEMENT = {"lumped": ("k_B", "c_B"), "twochamber": ("k_M", "c_M")}
#: The two-chamber model's chamber parameters (the oil's compliance and what stiffens it)
CHAMBER_PARAMETERS = ("k_R", "k_C", "area_ratio", "L_R", "L_C", "air", "f_res")


def parameter_group(model: str, name: str) -> str:
    """The physical element a base parameter of ``model`` belongs to, as reports name it ("the damping table",
    "the series elasticity (k_B, c_B)", ...); a parameter of no group is named by itself."""
    if name.startswith("Fc_"):
        return "the damping table"
    if name.startswith("Fk_"):
        return "the elastic table"
    if name in SERIES_ELEMENT.get(model, ()):
        return f"the series elasticity ({', '.join(SERIES_ELEMENT[model])})"
    if name.startswith("M_"):
        return "the masses"
    if model == "twochamber" and name in CHAMBER_PARAMETERS:
        return "the chambers' oil stiffness"
    return name

MODEL_PARAMETERS: dict[str, tuple[Parameter, ...]] = {
    "lumped": LUMPED_PARAMETERS,
    "maxwell": MAXWELL_PARAMETERS,
    "maxwell_table": MAXWELL_TABLE_PARAMETERS,
    "twochamber": TWOCHAMBER_PARAMETERS,
}

#: Model kinds, in the order reports list them.
MODEL_KINDS = tuple(MODEL_PARAMETERS)


def defaults(model: str) -> dict[str, float]:
    """Reference preset of ``model`` ('lumped', 'maxwell', 'maxwell_table', 'twochamber') as name -> SI value."""
    return {p.name: p.default for p in MODEL_PARAMETERS[model]}


def tunable_names(model: str) -> list[str]:
    """Names of the identified parameters of ``model``, in the canonical order."""
    return [p.name for p in MODEL_PARAMETERS[model] if p.tunable]


def check_values(model: str, values: dict[str, float], *, bounds: bool = False) -> dict[str, float]:
    """Complete ``values`` with the preset and check them.

    Raises ValueError naming the parameter for unknown names, non-finite values, non-positive
    masses/stiffness/damping, a negative gas spring, abscissae that are not strictly increasing or do not straddle zero,
    tables whose force falls anywhere (a passive element is non-decreasing),
    and (with ``bounds=True``) values outside the identification bounds.
    """
    import math

    spec = {p.name: p for p in MODEL_PARAMETERS[model]}
    unknown = sorted(set(values) - set(spec))
    if unknown:
        raise ValueError(f"unknown parameter(s) for model '{model}': {', '.join(unknown)}")
    full = defaults(model)
    full.update({k: float(v) for k, v in values.items()})
    for name, v in full.items():
        if not math.isfinite(v):
            raise ValueError(f"parameter {name} = {v} is not finite")
        p = spec[name]
        rule = check_rule(p)
        if rule == "range" and not (p.low <= v <= p.high):
            what = "effect parameter" if p.effect else "parameter"
            raise ValueError(f"{what} {name} = {v:g} {p.unit} outside [{p.low:g}, {p.high:g}]")
        if rule == "positive" and v <= 0.0:
            raise ValueError(f"parameter {name} = {v} {p.unit} must be positive")
        if rule == "nonnegative" and v < 0.0:
            raise ValueError(f"parameter {name} = {v} {p.unit} must not be negative")
        if bounds and p.tunable and not (p.low <= v <= p.high):
            raise ValueError(f"parameter {name} = {v:g} {p.unit} outside its bounds [{p.low:g}, {p.high:g}]")
    for prefix, axis in (("Fk", "x"), ("Fc", "v")):
        xs = [full[n] for n in sorted(full) if n.startswith(f"{prefix}_{axis}")]
        if not xs:
            continue
        if any(b <= a for a, b in zip(xs, xs[1:])):
            raise ValueError(f"{prefix} abscissae must be strictly increasing, got {xs}")
        if not (xs[0] < 0.0 < xs[-1]):
            raise ValueError(f"{prefix} abscissae must have negative and positive values (F(0) = 0 is implied)")
        fs = [full[n] for n in sorted(full) if n.startswith(f"{prefix}_") and n[len(prefix) + 1:].isdigit()]
        pts = sorted([*zip(xs, fs), (0.0, 0.0)])
        for (xa, fa), (xb, fb) in zip(pts, pts[1:]):
            if fb < fa:
                raise ValueError(f"{prefix} table is not monotone: the force falls between abscissae {xa:g} and "
                                 f"{xb:g} (a passive element needs non-decreasing ordinates)")
    return full
