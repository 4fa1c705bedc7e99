"""Which candidates are refitted whatever the profile screen predicts (tuner.diagnosis.search.nonsmooth.
signalled_nonsmooth): the nonsmooth effects whose residual signature the joint screen keeps above the noise."""
from damper_fmu.effect_catalogue import ALL_EFFECTS

from tuner.diagnosis.search.nonsmooth import signalled_nonsmooth
from tuner.diagnosis.search.state import SearchState
from tuner.diagnosis.settings import DiagnosisSettings


def search_with(kept: list[str], candidates=None) -> SearchState:
    search = SearchState.__new__(SearchState)  # only the fields the rule reads
    search.evidence = {"joint_screen": {"kept": kept}}
    search.settings = DiagnosisSettings() if candidates is None else DiagnosisSettings(candidates=candidates)
    search.log = lambda message: None
    return search


def test_a_nonsmooth_effect_with_its_signature_above_the_noise_is_refitted_whatever_the_screen():
    nonsmooth = [e for e in DiagnosisSettings().candidates if ALL_EFFECTS[e].nonsmooth]
    smooth = [e for e in DiagnosisSettings().candidates if not ALL_EFFECTS[e].nonsmooth]
    assert nonsmooth and smooth
    assert signalled_nonsmooth(search_with(nonsmooth + smooth)) == set(nonsmooth)
    assert signalled_nonsmooth(search_with(smooth)) == set()  # a smooth effect's screen is to first order right
    assert signalled_nonsmooth(search_with([])) == set()  # nothing above the noise: the screen decides


def test_a_signalled_effect_that_is_not_a_candidate_is_not_refitted():
    nonsmooth = [e for e in DiagnosisSettings().candidates if ALL_EFFECTS[e].nonsmooth]
    others = tuple(e for e in DiagnosisSettings().candidates if e not in nonsmooth)
    assert signalled_nonsmooth(search_with(nonsmooth, candidates=others)) == set()
