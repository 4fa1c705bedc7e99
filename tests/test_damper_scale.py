"""Every bound and fixed constant of the identification follows the damper's scale (issue 74, item 5).

The bundled damper scaled consistently by s (its force times s, ``force_scale_cases.scaled_tests``) is the same
identification problem up to the unit of force: each fixed constant and start value of a force-carrying unit
(N, kg, N/m, N s/m, J/K, W/K) is s times the full-scale one, the others equal (an identity of consistent
scaling, independent of the values the constants have). Its bounds hold s times the full-scale damper's own
range (the reference yaw damper's mapped to it), so that every full-scale point within it, scaled, is a point of
its design space, and the reference's bounds (never narrower: ``damper_scale``). At full scale the bounds still
hold the preset (the paper's and the twin-tube fit's values, set on this damper's size)."""
import numpy as np
import pytest

from damper_fmu import defaults, make_model
from damper_fmu.parameters import MODEL_PARAMETERS, UNIT_DEFINITIONS
from tuner.data.reading import load_dataset
from tuner.identification.damper_scale import REFERENCE_SCALE, DamperScale, scaled_preset
from tuner.identification.parametrization import Parametrization
from tuner.identification.problem import Problem

from force_scale_cases import scaled, scaled_tests

MODELS = ("lumped", "maxwell", "maxwell_table", "twochamber")
FACTORS = (1e-3, 10.0)


@pytest.fixture(scope="module")
def problems():
    """{factor: the Problem of the bundled identification tests with the force times factor} (1: as bundled)."""
    ident = [t for t in load_dataset("data/default") if t.role == "identification"]
    return {s: Problem.build(scaled_tests(ident, s), []) for s in (1.0, *FACTORS)}


def _carries_force(model: str, name: str) -> bool:
    unit = next(p.unit for p in MODEL_PARAMETERS[model] if p.name == name)
    return UNIT_DEFINITIONS[unit].get("kg") == 1


def _holds(outer: tuple, inner: tuple) -> bool:
    """[outer] holds [inner], to rounding."""
    return outer[0] <= inner[0] + 1e-12 * abs(inner[0]) and inner[1] <= outer[1] + 1e-12 * abs(outer[1])


def _own_range(model: str, problem: Problem) -> dict[str, tuple[float, float]]:
    """The reference's bounds of the scalar parameters of ``model`` mapped to the damper of ``problem`` by the factor
    of their unit, not widened."""
    return {p.name: (p.low * problem.scale.factor(p.unit), p.high * problem.scale.factor(p.unit))
            for p in MODEL_PARAMETERS[model] if p.tunable and not p.name.startswith(("Fc_", "Fk_"))}


@pytest.mark.parametrize("model", MODELS)
def test_the_fixed_constants_follow_a_damper_beyond_the_class_span_and_stay_within_it(problems, model):
    """Between the bundled damper scaled by 1e-3 and by 10 (both beyond ``CLASS_SPAN`` of the reference) every fixed
    constant and start carrying force is 1e4 times as large, the others equal (consistent scaling: an identity);
    the bundled damper itself (1.34 x the reference, within the span) keeps the reference's own preset."""
    weak, strong = problems[1e-3].parametrization(model), problems[10.0].parametrization(model)
    assert weak.names == strong.names
    for n, v in weak.fixed.items():  # the fixed constants (check valves' slope), the abscissae, the start (preset)
        k = 1e4 if _carries_force(model, n) else 1.0
        assert strong.fixed[n] == pytest.approx(k * v, rel=1e-9, abs=0.0), n
    assert strong.force_limit == pytest.approx(1e4 * weak.force_limit, rel=1e-12)
    assert strong.spring_reference == pytest.approx(1e4 * weak.spring_reference, rel=1e-12)
    full = problems[1.0].parametrization(model)
    preset = defaults(model)
    for n in full.names:
        if not n.startswith(("Fc_", "Fk_")):
            assert full.fixed[n] == pytest.approx(preset[n], rel=1e-12), n
    assert full.spring_reference == 1.5e7


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("s", FACTORS)
def test_the_bounds_of_a_scaled_damper_hold_s_times_the_full_scale_ones_and_the_reference_s(problems, model, s):
    """The bounds at scale s hold s times the full-scale damper's own range, and the reference yaw damper's
    bounds (``Parametrization`` at the reference scale on the same abscissae), a range from zero is s times the
    full-scale one; the damping table's limits are s times the full-scale ones (the force limit)."""
    full, small = problems[1.0].parametrization(model), problems[s].parametrization(model)
    reference = Parametrization(model, force_limit=full.force_limit, spring_reference=1.5e7,
                                fixed={k: v for k, v in full.fixed.items() if k.startswith(("Fc_v", "Fk_x"))})
    own = _own_range(model, problems[1.0])
    for n in full.names:
        if n.startswith("Fc_"):
            assert small.bounds[n] == pytest.approx(tuple(s * b for b in full.bounds[n]), rel=1e-12), n
            continue
        if n.startswith("Fk_"):
            x = full.fixed[n.replace("Fk_", "Fk_x")]
            own_spring = 1.5e7 * problems[1.0].scale.factor("N/m")  # the full-scale damper's own, mapped whole
            inner = tuple(sorted((0.2 * s * own_spring * x, 3.0 * s * own_spring * x)))
        else:
            inner = tuple(s * b for b in own[n]) if _carries_force(model, n) else own[n]
        if reference.bounds[n][0] == 0.0:  # a range from zero (the gas spring) is mapped alone: it holds s times
            assert _holds(small.bounds[n], inner), (n, small.bounds[n], inner)
            continue
        assert _holds(small.bounds[n], inner), (n, small.bounds[n], inner)
        assert _holds(small.bounds[n], reference.bounds[n]), (n, small.bounds[n], reference.bounds[n])


def _elastic_table(rng, point: dict, spring: float) -> dict:
    """Fk,O ordinates [N] at the abscissae of ``point`` (none when it has no elastic table) whose pieces, outward
    from zero, have stiffnesses drawn in 0.2-3 x ``spring`` [N/m]: the full-scale damper's own range."""
    out = {}
    for sign in (-1.0, 1.0):
        xs = sorted((abs(v), k.replace("Fk_x", "Fk_")) for k, v in point.items()
                    if k.startswith("Fk_x") and v * sign > 0)
        f, x0 = 0.0, 0.0
        for x, name in xs:
            f += rng.uniform(0.2, 3.0) * spring * (x - x0)
            out[name], x0 = sign * f, x
    return out


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("s", FACTORS)
def test_every_full_scale_point_scaled_is_a_point_of_the_scaled_damper_s_space(problems, model, s):
    """A point drawn in the full-scale design space (its scalars within the damper's own range), scaled
    (``scaled``: every parameter whose unit carries a kilogram times s), maps to coordinates of the scaled space and
    back to itself, in the search's space and the local solver's: nothing the full-scale damper has is cut off the
    scaled one (before, masses of 1-20 kg held a 25 N damper's 16 g far above)."""
    rng = np.random.default_rng(7)
    own = _own_range(model, problems[1.0])
    for space in ("search", "local"):
        full, small = problems[1.0].parametrization(model), problems[s].parametrization(model)
        if space == "local":
            full, small = full.local_space(), small.local_space()
        for z in rng.uniform(0.0, 1.0, (5, full.dimension)):
            point = full.to_params(z)
            point.update({n: min(max(point[n], lo), hi) for n, (lo, hi) in own.items()})
            point.update(_elastic_table(rng, point, 1.5e7 * problems[1.0].scale.factor("N/m")))
            point = scaled(model, point, s)
            back = small.to_params(small.from_params(point))
            for n in small.names:  # the identified parameters (the fixed constants: the test above)
                assert back[n] == pytest.approx(point[n], rel=1e-9, abs=1e-12 * s), (space, n)


@pytest.mark.parametrize("model", MODELS)
def test_the_full_scale_bounds_hold_the_preset(problems, model):
    """The bundled damper is of the reference's size (26.8 kN, 1.34 x): the bounds mapped to it still hold the
    preset of every model (the paper's Table 2 and section 2.3 for the lumped model, the fit to this damper for
    the two-chamber one) and the damping table's force limit its ordinates."""
    par = problems[1.0].parametrization(model)
    preset = defaults(model)
    for n in par.names:
        if n.startswith("Fc_"):
            assert abs(preset[n]) <= par.force_limit, n
        elif n.startswith("Fk_"):
            slope = preset[n] / preset[n.replace("Fk_", "Fk_x")]
            assert 0.2 * par.spring_reference <= slope <= 3.0 * par.spring_reference, n
        else:
            lo, hi = par.bounds[n]
            assert lo <= preset[n] <= hi, n
    assert 1.0 < problems[1.0].scale.force < 1.5 and problems[1.0].scale.length == 1.0


def test_the_scale_maps_units_as_force_over_length_and_over_velocity():
    """A damper twice as strong, on half the reference's stroke, with its damping table stretched to twice the
    reference's rates: forces, masses and heat capacities x2, stiffnesses x4, dampings x1, lengths x1/2, ratios
    x1; longer strokes than the reference's leave lengths as they are."""
    ref = REFERENCE_SCALE
    scale = DamperScale(2 * ref.peak_force_n, 0.5 * ref.stroke_range_m, 2 * ref.rate_span_m_s)
    assert [scale.factor(u) for u in ("N", "kg", "N/m", "N.s/m", "m", "1")] == pytest.approx([2, 2, 4, 1, 0.5, 1])
    long = DamperScale(ref.peak_force_n, 3 * ref.stroke_range_m, ref.rate_span_m_s)
    assert long.factor("m") == 1.0 and long.factor("N/m") == 1.0
    with pytest.raises(ValueError, match="peak_force_n"):
        DamperScale(0.0, 0.04, 0.1)
    preset = scaled_preset("twochamber", scale)  # within the class span: the reference's own preset
    assert preset["thermal_capacity"] == defaults("twochamber")["thermal_capacity"]
    far = DamperScale(5 * ref.peak_force_n, 0.2 * ref.stroke_range_m, ref.rate_span_m_s)  # beyond it: mapped whole
    preset = scaled_preset("twochamber", far)  # the thermal balance's capacity as a mass, a length as one
    assert preset["thermal_capacity"] == pytest.approx(5 * defaults("twochamber")["thermal_capacity"])
    assert preset["L_R"] == pytest.approx(0.2 * defaults("twochamber")["L_R"])


def test_a_gas_spring_of_a_strong_damper_is_accepted_and_a_negative_one_refused():
    """The gas spring is any non-negative value (before: 0-2e4 N/m, which refused every consistently scaled
    two-chamber damper above about 290 kN)."""
    strong = scaled("twochamber", defaults("twochamber"), 40.0)  # a 1 MN damper
    assert strong["k_gas"] > 2e4
    assert make_model("twochamber", strong).force_scale() == pytest.approx(40 * make_model("twochamber").force_scale())
    with pytest.raises(ValueError, match="k_gas .* must not be negative"):
        make_model("twochamber", {"k_gas": -1.0})
