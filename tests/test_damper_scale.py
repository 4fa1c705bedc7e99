"""Every bound and fixed constant of the identification follows the damper's scale (issue 74, item 5).

The bundled damper scaled consistently by s (its force times s, ``force_scale_cases.scaled_tests``) is the same
identification problem up to the unit of force: each bound and fixed constant of a force-carrying unit (N, kg,
N/m, N s/m) is s times the full-scale one, the others equal, and the design space maps any point to s times the
full-scale parameters (an identity of consistent scaling, independent of the values the bounds have). At full
scale the bounds still hold the preset (the paper's and the twin-tube fit's values, set on this damper's size)."""
import numpy as np
import pytest

from damper_fmu import defaults, make_model
from damper_fmu.parameters import MODEL_PARAMETERS, UNIT_DEFINITIONS
from tuner.data.reading import load_dataset
from tuner.identification.damper_scale import REFERENCE_SCALE, DamperScale, scaled_preset
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


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("s", FACTORS)
def test_the_bounds_and_fixed_constants_of_a_scaled_damper_are_s_times_the_full_scale_ones(problems, model, s):
    full, small = problems[1.0].parametrization(model), problems[s].parametrization(model)
    assert small.names == full.names
    for n in full.names:
        k = s if _carries_force(model, n) else 1.0
        assert small.bounds[n] == pytest.approx(tuple(k * b for b in full.bounds[n]), rel=1e-12, abs=0.0), n
    for n, v in full.fixed.items():  # the fixed constants (check valves' slope), the abscissae, the preset
        k = s if _carries_force(model, n) else 1.0
        assert small.fixed[n] == pytest.approx(k * v, rel=1e-12, abs=0.0), n
    assert small.force_limit == pytest.approx(s * full.force_limit, rel=1e-12)
    assert small.spring_reference == pytest.approx(s * full.spring_reference, rel=1e-12)


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("s", FACTORS)
def test_every_point_of_the_design_space_is_the_scaled_damper(problems, model, s):
    """The same scaled coordinates give s times the full-scale parameters (``scaled``: every parameter whose
    unit carries a kilogram), in the search's space and the local solver's, so a fit of the scaled data walks
    the same path as the full-scale one."""
    rng = np.random.default_rng(7)
    for space in ("search", "local"):
        full, small = problems[1.0].parametrization(model), problems[s].parametrization(model)
        if space == "local":
            full, small = full.local_space(), small.local_space()
        for z in rng.uniform(0.0, 1.0, (5, full.dimension)):
            expected = scaled(model, full.to_params(z), s)
            got = small.to_params(z)
            for n in expected:
                assert got[n] == pytest.approx(expected[n], rel=1e-9, abs=0.0), (space, n)
            assert small.from_params(got) == pytest.approx(full.from_params(full.to_params(z)), abs=1e-9)


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
    reference's rates: forces and masses x2, stiffnesses x4, dampings x1, lengths x1/2, ratios x1; longer strokes
    than the reference's leave lengths as they are."""
    ref = REFERENCE_SCALE
    scale = DamperScale(2 * ref.peak_force_n, 0.5 * ref.stroke_range_m, 2 * ref.rate_span_m_s)
    assert [scale.factor(u) for u in ("N", "kg", "N/m", "N.s/m", "m", "1")] == pytest.approx([2, 2, 4, 1, 0.5, 1])
    long = DamperScale(ref.peak_force_n, 3 * ref.stroke_range_m, ref.rate_span_m_s)
    assert long.factor("m") == 1.0 and long.factor("N/m") == 1.0
    with pytest.raises(ValueError, match="peak_force_n"):
        DamperScale(0.0, 0.04, 0.1)
    assert scaled_preset("twochamber", ref)["check_damping"] == defaults("twochamber")["check_damping"]


def test_a_gas_spring_of_a_strong_damper_is_accepted_and_a_negative_one_refused():
    """The gas spring is any non-negative value (before: 0-2e4 N/m, which refused every consistently scaled
    two-chamber damper above about 290 kN)."""
    strong = scaled("twochamber", defaults("twochamber"), 40.0)  # a 1 MN damper
    assert strong["k_gas"] > 2e4
    assert make_model("twochamber", strong).force_scale() == pytest.approx(40 * make_model("twochamber").force_scale())
    with pytest.raises(ValueError, match="k_gas .* must not be negative"):
        make_model("twochamber", {"k_gas": -1.0})
