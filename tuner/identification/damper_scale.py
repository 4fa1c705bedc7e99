"""The damper's force, stroke and velocity scale, and every bound and fixed constant of the base forms mapped to it.

The bounds and fixed constants of ``damper_fmu.parameters`` (masses 1-20 kg, k_B 1e2-1e9 N/m, the gas spring
0-2e4 N/m, the thermal balance's 4000 J/K, ...) are those of the paper's railway yaw damper,
``REFERENCE_SCALE``: about 20 kN peak force (the paper's 3e4 N force limit is 1.5 x that), strokes of tens of
millimetres, Table 2's damping table up to 100 mm/s. On a damper 1000 times weaker the same numbers hold its
mounts, reservoir force and masses far above what it has (the bundled damper scaled by 1e-3 fitted the two-chamber
form to 14.5 % of peak against 0.132 %, k_M, c_M and f_res on their lower bounds, the check valves' fixed 1e3
N s/m 50 N at 0.05 m/s on a 25 N damper); 10 times stronger, its silent blocks and gas spring lie above them. So the
identification maps them to the damper its data show (``DamperScale.of``, one place), by the unit of each:

* the force factor ``force`` = peak force / the reference's: forces [N] and masses [kg] (a mass's force
  m x'' is a share of the damper's force at the rig's accelerations, as the diagnosis's plausible inertia);
* the length factor ``length`` = min(1, stroke range / the reference's): lengths [m] (the chambers' lengths;
  never above the reference's: a longer test stroke is no larger damper, as the diagnosis's plausible gaps);
* the velocity factor ``velocity`` = the damping table's last rate abscissa / Table 2's (100 mm/s; the
  abscissae follow the data's peak velocity beyond 1.5 x it, ``tuner.identification.problem.table_abscissae``):
* stiffnesses [N/m] by force / length, dampings and slopes [N s/m] by force / velocity; ratios [1] unchanged;
  the thermal balance's heat capacity [J/K] and loss [W/K] by force, as masses (the damper's body and oil).

A fixed constant is the reference's times that factor (``scaled_preset``: the thermal balance's capacity and loss,
a check valves' slope given, and the preset the search starts from; by default the check valves' slope follows the
model's own damping table, ``damper_fmu.models.CHECK_SHARE``, the same rule inside the model). A bound is the
reference's range mapped to the damper and widened to hold the reference's own (``scaled_bounds``: low x min(1,
factor), high x max(1, factor); a range from zero is mapped alone): bounds follow a damper beyond the reference
yaw damper, never narrower than its. The peak force of a test program is no exact measure of a damper's parts: yaw
dampers whose tests peak at 8 to 38 kN have masses of 3-20 kg and blocks up to 1e9 N/m alike (the random dampers
of the class, ``campaign.damper_class``), and bounds narrowed to 0.6 x the reference's (masses up to 12 kg, blocks
up to 6e8 N/m, a 12.1 kN class damper) left one of them at 6.8 x its truth's RMSE. A damper scaled consistently
(every parameter whose unit carries a kilogram times s, the data's force times s, strokes and times unchanged)
then has every fixed constant and start s times its own, and bounds that hold s times the full-scale damper's
own range. The FMU's own defaults do not change (but the check valves', 0: derived); the fixed constants the fit
uses go into the tuned FMU as its parameter values. The table ordinates' bounds follow the force limit
(``default_force_limit``) and the elastic table's spring reference (``spring_reference``), the effect elements'
search bounds their own rules (``damper_fmu.effect_catalogue.search_bounds``).
"""
from __future__ import annotations

from dataclasses import dataclass

from damper_fmu.parameters import FC_ABSCISSAE, FK_REFERENCE_STIFFNESS, MODEL_PARAMETERS

__all__ = ["DamperScale", "REFERENCE_SCALE", "UNIT_FACTORS", "widened", "scaled_bounds", "scaled_preset",
           "spring_reference", "class_factor", "CLASS_SPAN"]

#: how each unit of a base parameter scales: the product of the factors' powers (force, length, velocity)
UNIT_FACTORS: dict[str, tuple[int, int, int]] = {
    "N": (1, 0, 0), "kg": (1, 0, 0), "N/m": (1, -1, 0), "N.s/m": (1, 0, -1), "m": (0, 1, 0), "1": (0, 0, 0),
    "J/K": (1, 0, 0), "W/K": (1, 0, 0)}
#: the effect elements' fixed constants that follow the damper (the others are off at their defaults, or shapes
#: and times the diagnosis sets by its own rules): the internal thermal balance's capacity and loss
SCALED_EFFECT_UNITS = ("J/K", "W/K")


@dataclass(frozen=True)
class DamperScale:
    """A damper's size as its identification tests show it: peak |force| [N], the largest stroke range of a
    test [m] and the damping table's last rate abscissa [m/s] (its velocity span)."""

    peak_force_n: float
    stroke_range_m: float
    rate_span_m_s: float

    def __post_init__(self):
        for name in ("peak_force_n", "stroke_range_m", "rate_span_m_s"):
            value = getattr(self, name)
            if not (value > 0 and value < float("inf")):
                raise ValueError(f"DamperScale.{name} = {value!r}: a positive finite value is needed (the "
                                 "identification tests must move the damper and carry a force)")

    @classmethod
    def of(cls, peak_force_n: float, stroke_range_m: float, axes: dict) -> "DamperScale":
        """The scale of data of peak |force| ``peak_force_n`` [N] and stroke range ``stroke_range_m`` [m], whose
        damping table has the rate abscissae of ``axes`` (``table_abscissae``: ``Fc_v01``... [m/s])."""
        span = max(abs(v) for k, v in axes.items() if k.startswith("Fc_v"))
        return cls(float(peak_force_n), float(stroke_range_m), float(span))

    @property
    def force(self) -> float:
        """Factor on forces and masses [-]: peak force / the reference's."""
        return self.peak_force_n / REFERENCE_SCALE.peak_force_n

    @property
    def length(self) -> float:
        """Factor on lengths [-]: stroke range / the reference's, at most 1."""
        return min(1.0, self.stroke_range_m / REFERENCE_SCALE.stroke_range_m)

    @property
    def velocity(self) -> float:
        """Factor on velocities [-]: the damping table's velocity span / the reference's."""
        return self.rate_span_m_s / REFERENCE_SCALE.rate_span_m_s

    def factor(self, unit: str) -> float:
        """The factor [-] on a bound or constant of SI ``unit`` ('N', 'kg', 'N/m', 'N.s/m', 'm', '1')."""
        try:
            f, x, v = UNIT_FACTORS[unit]
        except KeyError:
            raise ValueError(f"no scaling rule for unit {unit!r}; known: {', '.join(UNIT_FACTORS)}") from None
        return self.force ** f * self.length ** x * self.velocity ** v

    def to_dict(self) -> dict:
        return {"peak_force_n": self.peak_force_n, "stroke_range_m": self.stroke_range_m,
                "rate_span_m_s": self.rate_span_m_s}

    @classmethod
    def from_dict(cls, d: dict | None) -> "DamperScale":
        """From ``to_dict``'s form; None (a file written before the scale was stored): ``REFERENCE_SCALE``."""
        if d is None:
            return REFERENCE_SCALE
        return cls(float(d["peak_force_n"]), float(d["stroke_range_m"]), float(d["rate_span_m_s"]))

    def describe(self) -> str:
        return (f"damper scale: peak force {self.peak_force_n:.4g} N, stroke range {1e3 * self.stroke_range_m:.4g} mm, "
                f"rates up to {1e3 * self.rate_span_m_s:.4g} mm/s: fixed constants and bounds x {self.force:.3g} "
                f"(forces, masses), x {self.factor('N/m'):.3g} (stiffnesses), x {self.factor('N.s/m'):.3g} "
                f"(dampings), x {self.length:.3g} (lengths) of the reference yaw damper's, the bounds widened to "
                "hold its own")


#: the damper the bounds and fixed constants of ``damper_fmu.parameters`` are set for: the paper's yaw damper
#: (peaks of about 20 kN, quasi-static strokes of tens of mm, Table 2's rates up to 100 mm/s); the diagnosis's
#: typical effect sizes are those of the same damper (``tuner.diagnosis.effect_sizes.REFERENCE``)
REFERENCE_SCALE = DamperScale(peak_force_n=20e3, stroke_range_m=0.04, rate_span_m_s=max(abs(v) for v in FC_ABSCISSAE))


def _is_table(name: str) -> bool:
    return name.startswith(("Fc_", "Fk_"))


def widened(low: float, high: float, factor: float) -> tuple[float, float]:
    """The reference's bounds (``low``, ``high``) mapped by ``factor`` and widened to hold the reference's own:
    (low x min(1, factor), high x max(1, factor)), for bounds of one sign (0 <= low <= high). A range from zero
    (the gas spring's 0-2e4 N/m) is mapped alone, (0, high x factor): it is searched linearly from zero, and
    widened to the reference's top a 25 N damper's gas spring (1.7 N/m) would lie within 0.01 % of it, on its
    bound for the search and the intervals."""
    if low == 0.0:
        return 0.0, high * factor
    return low * min(1.0, factor), high * max(1.0, factor)


def scaled_bounds(model: str, scale: DamperScale) -> dict[str, tuple[float, float]]:
    """Bounds (SI) of the identified parameters of ``model`` that are no table ordinate, for a damper of
    ``scale``: the reference's mapped by the factor of the parameter's unit, never narrower than the reference's
    (``widened``; module docstring)."""
    return {p.name: widened(p.low, p.high, class_factor(scale, p.unit))
            for p in MODEL_PARAMETERS[model] if p.tunable and not _is_table(p.name)}


#: within this factor of the reference (either way) a damper's bounds, start and fixed constants are the reference's
#: own: a test programme's peak force is no exact measure of a damper's parts (the class's yaw dampers peak at 8-38
#: kN with the same masses and blocks, 0.4-1.9 x the reference's); beyond it they follow the damper by the whole
#: factor (``class_factor``). Mapped by the peak force inside the span, the bounds of a 28 kN lumped damper (x 1.42)
#: moved its diagnosis off the path that names its friction, preload and hysteresis (``tests/test_forms.py``: the
#: friction came out as a hysteresis at its Coulomb edge, the hysteresis not named)
CLASS_SPAN = 3.0


def class_factor(scale: DamperScale, unit: str) -> float:
    """The factor [-] on the reference's bound, start or fixed constant of SI ``unit`` for a damper of ``scale``:
    1 while the unit's factor (``DamperScale.factor``) lies within ``CLASS_SPAN`` of the reference's, else that
    factor (a damper 1000 x weaker or 10 x stronger than the reference yaw damper is mapped whole)."""
    f = scale.factor(unit)
    return 1.0 if 1.0 / CLASS_SPAN <= f <= CLASS_SPAN else f


def scaled_preset(model: str, scale: DamperScale) -> dict[str, float]:
    """The preset of ``model`` mapped to a damper of ``scale`` (SI): every base parameter but the tables' abscissae
    times ``class_factor`` of its unit (the damping ordinates as forces, the elastic ones as a spring's forces at their
    elongations: by the stiffness factor), the fixed constants (the thermal balance's capacity and loss, a
    ``check_damping`` given; its default 0 derives it from the table in the model) included; the effect elements
    otherwise at their defaults (off). The start of the fit's search and its fixed constants."""
    out = {}
    for p in MODEL_PARAMETERS[model]:
        if (p.effect is not None and p.unit not in SCALED_EFFECT_UNITS) or (not p.tunable and _is_table(p.name)):
            out[p.name] = p.default
        elif p.name.startswith("Fk_"):
            out[p.name] = p.default * class_factor(scale, "N/m")
        else:
            out[p.name] = p.default * class_factor(scale, p.unit)
    return out


def spring_reference(scale: DamperScale) -> float:
    """The elastic table's reference spring [N/m] for a damper of ``scale``: the paper's 1.5e7 N/m times the
    stiffness factor (the Fk,O pieces' stiffness bounds are 0.2-3 times it, widened to the reference damper's
    as every bound: ``Parametrization``)."""
    return FK_REFERENCE_STIFFNESS * class_factor(scale, "N/m")
