"""When the forms are weighed with a named cause (tuner.diagnosis.search.form_steps.weigh_forms): only while
the base and the cause's model both leave a residual above the floor. The rule alone: the search's state is built
with only the fields it reads, ``forms`` records its calls."""
import pytest

from tuner.diagnosis.rules import UNEXPLAINED_RATIO
from tuner.diagnosis.search import form_steps
from tuner.diagnosis.search.form_steps import weigh_forms
from tuner.diagnosis.search.state import SearchState
from tuner.diagnosis.settings import DiagnosisSettings

FLOOR = 30.0  # [N] the residual floor of the base and of the cause's model


def search_with(base_rmse: float, monkeypatch) -> SearchState:
    search = SearchState.__new__(SearchState)
    search.settings, search.credible, search.floor = DiagnosisSettings(), True, FLOOR
    search.none_row = {"identification_rmse_n": base_rmse}
    search.floor_of = lambda causes: (10.0, FLOOR)
    search.log = lambda message: None
    search.at = lambda stage, fraction=None: None
    search.par = type("Par", (), {"to_params": staticmethod(lambda z: {})})()
    search.z_none = None
    search.calls = []
    monkeypatch.setattr(form_steps, "forms",
                        lambda s, current, row, causes: search.calls.append(causes) or {"form": None, "row": None})
    return search


@pytest.mark.parametrize("cause_rmse, weighed", [(0.9 * UNEXPLAINED_RATIO * FLOOR, False),
                                                 (1.1 * UNEXPLAINED_RATIO * FLOOR, True)])
def test_forms_are_weighed_only_against_a_cause_that_leaves_a_residual_above_the_floor(cause_rmse, weighed,
                                                                                      monkeypatch):
    search = search_with(base_rmse=20 * FLOOR, monkeypatch=monkeypatch)
    best = {"identification_rmse_n": cause_rmse, "score": 1.0}
    cause, row, step = weigh_forms(search, "free_play", best)
    assert (cause, row) == ("free_play", best)
    assert bool(search.calls) == weighed
    assert (step is not None) == weighed


def test_no_form_is_weighed_when_the_base_itself_is_at_the_floor_or_nothing_is_named(monkeypatch):
    search = search_with(base_rmse=FLOOR, monkeypatch=monkeypatch)
    assert weigh_forms(search, "free_play", {"identification_rmse_n": 100 * FLOOR, "score": 1.0})[2] is None
    search = search_with(base_rmse=20 * FLOOR, monkeypatch=monkeypatch)
    assert weigh_forms(search, "none", {"identification_rmse_n": 20 * FLOOR, "score": 0.0})[2] is None
    assert not search.calls
