"""'Cannot be told apart' (tuner.diagnosis.rules.indistinguishable, verdict.told_apart_text): pure rules."""
import pytest

from tuner.diagnosis.rules import CONFOUNDED_SHARE, indistinguishable
from tuner.diagnosis.verdict import told_apart_text


def _row(effect, change, **params):
    return {"effect": effect, "validation_mse_change_pct": change, "parameters": params}


def _limit(share, by=None):
    return {"absorbed_share": share, "absorbed_by": by or {"the series elasticity (k_B, c_B)": 0.97}}


def test_an_effect_that_gains_but_that_the_base_absorbs_is_reported_with_its_figures():
    ranking = [_row("valve_lag", -4.0, valve_tau=5e-3), _row("friction", -2.0, friction_force=80.0),
               _row("inertia", +1.0, inertia_mass=30.0), _row("none", 0.0)]
    limits = {"valve_lag": _limit(0.96), "friction": _limit(0.5), "inertia": _limit(0.99)}
    out = indistinguishable(ranking, [], limits)
    # friction: its force is not absorbed (it would have been named if it earned it); inertia: no gain
    assert [r["effect"] for r in out] == ["valve_lag"]
    text = told_apart_text(out)
    assert "valve lag" in text and "5 ms" in text and "-4 %" in text and "96 %" in text
    assert "series elasticity (k_B, c_B)" in text


def test_the_row_on_top_of_the_causes_counts_and_the_threshold_is_the_rule():
    ranking = [_row("valve_lag", +2.0, valve_tau=1e-3)]  # on the base: no gain
    on_top = {**_row("preload+valve_lag", -3.0, valve_tau=6e-3), "added": "valve_lag"}
    selection = [{"cause": "none", "tried": [on_top]}]
    at = {"valve_lag": _limit(CONFOUNDED_SHARE)}
    below = {"valve_lag": _limit(CONFOUNDED_SHARE - 0.01)}
    assert [r["parameters"]["valve_tau"] for r in indistinguishable(ranking, selection, at)] == [6e-3]
    assert indistinguishable(ranking, selection, below) == []
    assert told_apart_text([]) == ""


def test_a_limit_the_base_absorbs_says_what_absorbs_it_and_a_verdict_with_causes_lists_it():
    from tuner.diagnosis.verdict import limit_text, untold_text

    absorbed = {"reachable": False, "absorbed_share": 0.99, "absorbed_by": {"the elastic table": 0.97},
                "parameter": "preload_force"}
    weak = {"reachable": False, "absorbed_share": 0.2, "absorbed_by": {}, "parameter": "thermal_beta"}
    seen = {"reachable": True, "absorbed_share": 0.95, "absorbed_by": {"the masses": 1.0}, "limit": 30.0,
            "best_test": "val1", "parameter": "inertia_mass"}
    assert limit_text(absorbed) == ("not detectable within its search range (99 % of its force absorbed by the "
                                    "elastic table)")
    assert limit_text(weak) == "not detectable within its search range"  # too little absorbed: no reason given
    text = untold_text({"preload": absorbed, "thermal_drift": weak, "inertia": seen})
    assert "preload (99 % of its force absorbed by the elastic table)" in text
    assert "thermal_drift" not in text and "inertia" not in text  # an inertia above 30 kg these tests would name
    assert untold_text({"thermal_drift": weak}) == "" and untold_text(None) == ""


def test_an_absorbed_effect_detectable_only_beyond_its_physical_range_is_said_untold():
    """Blind seed 1363 (a 106 N preload beside a valve lag): the damping table absorbs 98 % of the preload's
    force and the limit, 2.34 kN, lies within the search bound but far above any preload a damper this size
    has; the verdict said nothing of it. Now it says these tests cannot tell it apart; a limit within the
    physical range, or a force the base does not absorb, is not said."""
    from tuner.diagnosis.rules import untold
    from tuner.diagnosis.verdict import limit_text, untold_text

    beyond = {"reachable": True, "within_plausible": False, "plausible_top": 800.0, "limit": 2340.0,
              "absorbed_share": 0.98, "absorbed_by": {"the damping table": 0.98}, "best_test": "val5",
              "parameter": "preload_force"}
    within = {**beyond, "within_plausible": True, "limit": 300.0}
    free = {**beyond, "absorbed_share": 0.5}
    assert untold(beyond) and not untold(within) and not untold(free)
    assert "preload (98 % of its force absorbed by the damping table)" in untold_text({"preload": beyond})
    assert untold_text({"preload": within}) == "" and untold_text({"preload": free}) == ""
    text = limit_text(beyond)
    assert text == ("above 2.34e+03 N (val5; beyond the 800 N a damper this size plausibly has; 98 % of its force "
                    "absorbed by the damping table)")


def test_the_absorbing_elements_are_summed_by_group_and_read_at_most_whole():
    from types import SimpleNamespace

    from tuner.diagnosis.search.run import absorbing_groups

    par = SimpleNamespace(model="lumped", names=["Fc_01", "Fc_02", "k_B", "c_B", "M_C", "Fk_01"])
    groups = absorbing_groups(par, [0.7, 0.35, 0.02, 0.03, -0.15, 0.05])
    assert groups == {"the damping table": 1.0}  # 1.05 read as whole; the others below 10 % or negative
    groups = absorbing_groups(par, [0.3, 0.1, 0.3, 0.3, 0.0, 0.0])
    assert list(groups) == ["the series elasticity (k_B, c_B)", "the damping table"]
    assert groups["the series elasticity (k_B, c_B)"] == pytest.approx(0.6)
