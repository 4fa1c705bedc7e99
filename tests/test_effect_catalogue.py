"""The effect catalogue (``damper_fmu.effect_catalogue``): one record per effect, and every other place reads
what an effect means from it."""
import pytest

from damper_fmu.effect_catalogue import (ALL_EFFECTS, CATALOGUE_EFFECTS, EFFECT_PARAMETERS, FORM_EFFECTS, Effect,
                                         effect_of, search_bounds)
from damper_fmu.parameters import MODEL_PARAMETERS
from damper_fmu.parameter_spec import Parameter


def test_every_effect_parameter_belongs_to_one_record_and_both_effect_models_carry_them():
    owners = [e.name for p in EFFECT_PARAMETERS for e in ALL_EFFECTS.values() if p in e.parameters]
    assert owners == [p.effect for p in EFFECT_PARAMETERS]
    for model in ("lumped", "twochamber"):
        names = [p.name for p in MODEL_PARAMETERS[model]]
        assert names[-len(EFFECT_PARAMETERS):] == [p.name for p in EFFECT_PARAMETERS]  # the kernel's block
    assert set(CATALOGUE_EFFECTS) | set(FORM_EFFECTS) == set(ALL_EFFECTS)
    assert all(p.default == 0.0 for e in ALL_EFFECTS.values() for p in e.parameters if p.name == e.magnitude)


def test_the_search_reaches_every_documented_magnitude_on_the_reference_damper():
    """Each identified parameter's typical range lies within its search bounds (20 kN peak, 40 mm stroke),
    a preload's of either sign; only the preload and the channel delay belong to the acquisition."""
    for e in ALL_EFFECTS.values():
        for name, (lo, hi) in e.typical.items():
            if name not in e.identified:
                continue
            b_lo, b_hi = search_bounds(name, 2e4, 0.04, (-0.02, 0.02))
            assert b_lo <= lo and hi <= b_hi, (name, (b_lo, b_hi), (lo, hi))
            if name == "preload_force":
                assert b_lo <= -hi
    assert effect_of("preload_force").acquisition and effect_of("time_delay").acquisition
    assert not any(e.acquisition for e in ALL_EFFECTS.values() if e.name not in ("preload", "time_delay"))


def test_an_inconsistent_record_is_refused_by_name():
    p = Parameter("squeak_force", "N", "a squeak", 0.0, 0.0, 1e3, tunable=False, effect="squeak")
    with pytest.raises(ValueError, match="squeak.*typical names no parameter"):
        Effect("squeak", "squeak", "a squeak", (p,), ("squeak_force",), {"squeak_n": (1.0, 2.0)},
               {"squeak_force": lambda *a: (0.0, 1.0)}, "S")
    with pytest.raises(ValueError, match="search rule"):
        Effect("squeak", "squeak", "a squeak", (p,), ("squeak_force",), {"squeak_force": (1.0, 2.0)}, {}, "S")
    with pytest.raises(ValueError, match="no effect parameter"):
        effect_of("k_B")
