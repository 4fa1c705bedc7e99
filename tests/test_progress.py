"""The job progress display: estimate over the whole job, plain timestamped lines off a terminal."""
import io
import re

import pytest

from tuner.progress import JobProgress, SubStages, advance, stage


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_estimate_covers_the_whole_job_and_is_refined_as_stages_finish():
    clock, out = Clock(), io.StringIO()
    p = JobProgress({"fit": 60.0, "diagnosis": 60.0}, stream=out, tty=False, clock=clock)
    stage(p, "fit")
    clock.t = 30.0
    advance(p, 0.5)  # a quarter of the job in 30 s -> 90 s left, not the fit's 30 s
    assert p.completed() == pytest.approx(0.25)
    assert p.remaining_s() == pytest.approx(90.0)
    clock.t = 120.0  # the fit took twice as long as expected: the estimate follows
    stage(p, "diagnosis")
    assert p.remaining_s() == pytest.approx(120.0)
    advance(p, 0.2)
    advance(p, 0.1)  # progress never goes back
    assert p.fraction == pytest.approx(0.2)


def test_the_first_of_a_group_to_start_takes_its_extra_cost_whichever_it_is():
    """The base forms' fits: the first to run costs more (every restart), the others race it; which is first
    follows from the data. Planned on the first listed, the extra moves to the one that starts first, so a fit
    that took its planned time does not make the stages to come look slower."""
    clock, out = Clock(), io.StringIO()
    p = JobProgress({"fit a": 6.0, "fit b": 6.0, "report": 4.0}, stream=out, tty=False, clock=clock,
                    first_of=(("fit a", "fit b"), 20.0))
    assert p.weights["fit a"] == 26.0 and sum(p.weights.values()) == 36.0
    stage(p, "fit b")  # b runs first
    assert (p.weights["fit a"], p.weights["fit b"]) == (6.0, 26.0)
    clock.t = 26.0
    stage(p, "fit a")  # b took its 26 s: the 10 s planned after it are 10 s
    assert p.remaining_s() == pytest.approx(10.0)
    clock.t = 32.0
    stage(p, "report")
    assert (p.weights["fit a"], p.weights["fit b"]) == (6.0, 26.0)  # moved once only


def test_plain_lines_when_not_a_terminal():
    clock, out = Clock(), io.StringIO()
    p = JobProgress({"a": 1.0, "b": 3.0}, stream=out, tty=False, clock=clock, interval_s=10.0)
    p("hello")
    stage(p, "a")
    clock.t = 65.0
    advance(p, 1.0)
    advance(p, 1.0)  # within the interval: no second progress line
    stage(p, "b")
    p.finish()
    lines = out.getvalue().splitlines()
    stamp = r"\[\d\d:\d\d:\d\d \+\d+:\d\d\] "
    assert re.fullmatch(stamp + "hello", lines[0])
    assert re.fullmatch(stamp + r"progress 0 % \(stage: a 0 %\), estimating time left", lines[1])
    assert re.fullmatch(stamp.replace(r"\d+:\d\d", "1:05") + r"progress 25 % \(stage: a 100 %\), about 3\.2 min left",
                        lines[2])
    assert len([ln for ln in lines if "progress" in ln]) == 3  # the stage change forces a line


def test_quiet_prints_nothing_and_plain_print_still_works_as_log():
    out = io.StringIO()
    p = JobProgress({"a": 1.0}, stream=out, tty=False, quiet=True)
    p("x")
    stage(p, "a")
    advance(p, 0.5)
    assert out.getvalue() == ""
    stage(print, "a")  # a log without hooks is left alone
    advance(print, 0.5)


def test_sub_stages_advance_the_jobs_stage_without_adding_stages():
    """A function's own stages inside one job stage (the vehicle scenarios): the job keeps its
    planned stages and the stage's fraction goes 0 -> 1 over the sub-stages."""
    clock, out = Clock(), io.StringIO()
    p = JobProgress({"fit": 10.0, "vehicle": 10.0}, stream=out, tty=False, clock=clock)
    stage(p, "fit")
    stage(p, "vehicle")
    sub = SubStages(p, 4)
    seen = []
    for k in range(4):
        stage(sub, f"scenario {k}")
        seen.append(p.fraction)
        advance(sub, 0.5)
        seen.append(p.fraction)
    advance(sub, 1.0)
    assert seen == pytest.approx([0.0, 0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875])
    assert p.fraction == pytest.approx(1.0)
    assert set(p.weights) == {"fit", "vehicle"}
    sub("a line")  # lines reach the job's log
    p.finish()
    assert "a line" in out.getvalue()


def test_a_plan_keeps_time_for_parts_that_may_still_run_and_counts_skipped_ones_as_done():
    """The diagnosis's plan: identification of two base forms, the diagnosis on the first and a possible
    repeat on the second. A part that finished does not make its stage read 100 % while another may
    follow; the time left covers the repeat until it is known not to run."""
    from tuner.progress import Plan

    clock, out = Clock(), io.StringIO()
    p = JobProgress({"diagnosis": 100.0}, stream=out, tty=False, clock=clock)
    stage(p, "diagnosis")
    plan = Plan(p, {"identify a": 1.0, "identify b": 1.0, "diagnose a": 1.0, "diagnose b": 1.0})
    for name in ("identify a", "identify b", "diagnose a"):
        advance(plan.part(name), 1.0)
    clock.t = 75.0
    assert p.fraction == pytest.approx(0.75)  # the repeat on b may still run
    assert p.remaining_s() == pytest.approx(25.0)
    plan.skip("diagnose b")  # it will not: the stage is done
    assert p.fraction == pytest.approx(1.0)
    with pytest.raises(KeyError):
        plan.part("vehicle")


def test_a_stage_that_says_its_seconds_left_is_believed_and_later_stages_follow_the_measured_speed():
    """The diagnosis forecasts its own time (its cost depends on the data more than a plan can know): the
    display then shows what it said, less the time since, plus the later stages' plan scaled by how the
    finished stages went against theirs; the percentages follow the same forecast."""
    from tuner.progress import expect

    clock, out = Clock(), io.StringIO()
    p = JobProgress({"fit": 60.0, "diagnosis": 60.0, "report": 10.0}, stream=out, tty=False, clock=clock)
    stage(p, "fit")
    clock.t = 120.0  # the fit took twice its plan
    stage(p, "diagnosis")
    expect(p, 300.0)
    assert p.remaining_s() == pytest.approx(300.0 + 2.0 * 10.0)
    clock.t = 220.0
    assert p.remaining_s() == pytest.approx(200.0 + 20.0)
    assert p.stage_fraction() == pytest.approx(100.0 / 300.0)
    assert p.completed() == pytest.approx(220.0 / 440.0)
    clock.t = 600.0  # the forecast ran out: the stage reads 100 % only until it says more
    assert p.remaining_s() == pytest.approx(20.0)
    expect(p, 50.0)
    assert p.remaining_s() == pytest.approx(70.0)
    stage(p, "report")  # a new stage starts without a forecast: the plan again
    assert p._said is None


def test_a_plan_forwards_the_sum_of_its_open_parts_seconds_once_every_one_has_said():
    from tuner.progress import Plan

    clock, out = Clock(), io.StringIO()
    p = JobProgress({"diagnosis": 100.0}, stream=out, tty=False, clock=clock)
    stage(p, "diagnosis")
    plan = Plan(p, {"diagnose a": 1.0, "diagnose b": 1.0})
    plan.part("diagnose a").expect(100.0)
    assert p._said is None  # b has not said: no forecast yet
    plan.part("diagnose b").expect(50.0)
    assert p.remaining_s() == pytest.approx(150.0)  # the repeat on b is counted until it is known not to run
    plan.skip("diagnose b")
    assert p.remaining_s() == pytest.approx(100.0)
    advance(plan.part("diagnose a"), 1.0)
    assert p.remaining_s() == pytest.approx(0.0)


def test_the_diagnosis_forecast_counts_the_steps_a_leading_cause_brings_and_none_that_will_not_run():
    """Once the candidates are ranked, a leading cause brings its continuation, its interval, the forward
    selection over the other scoring candidates and a second pass of the forms (weighed with it, then on top);
    with nothing scoring and the residual at the floor none of those steps is counted."""
    from tuner.diagnosis.cost_model import after_ranking, expected_cost, form_pass_cost
    from tuner.diagnosis.settings import DiagnosisSettings

    s, d = DiagnosisSettings(), 29
    clean = expected_cost(d, s, settled=True, forms_run=False, held_out_share=0.5)
    after_ranking(clean, d, s, scoring=0, forms_run=False)
    assert clean.continuation == clean.intervals == clean.selection == clean.forms == 0.0
    hidden = expected_cost(d, s, settled=True, forms_run=True, held_out_share=0.5)
    after_ranking(hidden, d, s, scoring=2, forms_run=True)
    assert hidden.forms == pytest.approx(2 * form_pass_cost(d, s))
    assert hidden.continuation >= 2 * (d + 2)  # at least a Jacobian of the base and of the lead
    assert hidden.intervals == pytest.approx(2 * (d + 2))
    assert hidden.selection > 0.0
    one = expected_cost(d, s, settled=True, forms_run=True, held_out_share=0.5)
    after_ranking(one, d, s, scoring=1, forms_run=True)
    assert one.selection == 0.0 and one.total < hidden.total


def test_a_part_that_overruns_its_forecast_does_not_eat_the_time_of_the_parts_still_to_come():
    """The base identification said 20 s and the diagnosis after it 100 s; the identification takes 50 s: the
    time left never drops below the diagnosis's 100 s while it has not started, and counts down from its start
    (its first progress report) once it has."""
    from tuner.progress import Plan

    clock, out = Clock(), io.StringIO()
    p = JobProgress({"diagnosis": 100.0}, stream=out, tty=False, clock=clock)
    stage(p, "diagnosis")
    plan = Plan(p, {"identify": 1.0, "diagnose": 1.0}, clock=clock)
    plan.part("identify").expect(20.0)
    plan.part("diagnose").expect(100.0)
    advance(plan.part("identify"), 0.0)  # it starts
    assert p.remaining_s() == pytest.approx(120.0)
    clock.t = 10.0
    advance(plan.part("identify"), 0.3)
    assert p.remaining_s() == pytest.approx(110.0)
    clock.t = 50.0  # 30 s past its forecast
    advance(plan.part("identify"), 0.9)
    assert p.remaining_s() == pytest.approx(100.0)
    advance(plan.part("identify"), 1.0)
    clock.t = 60.0
    advance(plan.part("diagnose"), 0.0)  # it starts: its 100 s count from now
    assert p.remaining_s() == pytest.approx(100.0)
    clock.t = 70.0
    advance(plan.part("diagnose"), 0.1)
    assert p.remaining_s() == pytest.approx(90.0)


def test_a_part_that_may_not_run_is_said_beside_the_time_left_and_counted_once_it_starts():
    """A repeat of the diagnosis on another base runs only if the first leaves a residual above the floor: the
    time left counts the first, says what the repeat would add, and counts it once it starts; the percentages
    count it from the start (a share near 100 % stood for minutes while a repeat ran)."""
    from tuner.progress import Plan

    clock, out = Clock(), io.StringIO()
    p = JobProgress({"diagnosis": 100.0}, stream=out, tty=False, clock=clock)
    stage(p, "diagnosis")
    plan = Plan(p, {"diagnose a": 1.0, "diagnose b": 1.0}, clock=clock)
    plan.maybe("diagnose b", "the diagnosis is repeated on b")
    plan.part("diagnose a").expect(60.0)
    plan.part("diagnose b").expect(90.0)
    assert p.remaining_s() == pytest.approx(60.0)
    assert "about 1.0 min left (1.5 min more if the diagnosis is repeated on b)" in p.status()
    advance(plan.part("diagnose a"), 1.0)
    clock.t = 60.0
    # the shares count what may still run: 60 s done of 60 + 90, not 100 % while the repeat may take 90 s more
    assert p.completed() == pytest.approx(60.0 / 150.0) and p.stage_fraction() == pytest.approx(60.0 / 150.0)
    assert "progress 40 % (stage: diagnosis 40 %)" in p.status()
    plan.maybe("diagnose b", None)  # it runs
    assert p.remaining_s() == pytest.approx(90.0)
    assert "more if" not in p.status()
    clock.t = 105.0
    assert p.completed() == pytest.approx(105.0 / 150.0)  # the repeat half done


def test_a_stage_forecast_in_seconds_counts_in_place_of_its_weight_before_and_while_it_runs():
    """The job prices the diagnosis from the start (one simulation of each base form): while the fit runs the
    time left counts the diagnosis's forecast seconds, not its planned share; once it starts, the forecast
    stands until the stage says its own."""
    from tuner.progress import expect, forecast

    clock, out = Clock(), io.StringIO()
    p = JobProgress({"fit": 50.0, "diagnosis": 50.0}, stream=out, tty=False, clock=clock)
    stage(p, "fit")
    forecast(p, "diagnosis", 200.0)
    clock.t = 25.0
    advance(p, 0.5)  # half the fit in 25 s: 25 s of it left
    assert p.remaining_s() == pytest.approx(25.0 + 200.0)
    clock.t = 50.0
    stage(p, "diagnosis")
    clock.t = 60.0
    assert p.remaining_s() == pytest.approx(190.0)
    expect(p, 100.0)
    assert p.remaining_s() == pytest.approx(100.0)


def test_what_a_later_stage_may_add_is_said_beside_the_time_left_and_is_its_own_once_it_starts():
    """The job prices the diagnosis without the forms (they run only where the base leaves a residual above the
    floor: counted in, the bundled job's display said 107 s for a diagnosis of 26 s) and says what they would add
    beside: not in the time left, in the shares; once the diagnosis starts, it is that stage's until it says its
    own."""
    from tuner.progress import expect, forecast

    clock, out = Clock(), io.StringIO()
    p = JobProgress({"fit": 50.0, "diagnosis": 50.0}, stream=out, tty=False, clock=clock)
    stage(p, "fit")
    forecast(p, "diagnosis", 30.0, (45.0, "the diagnosis tries the forms"))
    clock.t = 25.0
    advance(p, 0.5)
    assert p.remaining_s() == pytest.approx(25.0 + 30.0)
    assert "(45 s more if the diagnosis tries the forms)" in p.status()
    assert p.completed() == pytest.approx(25.0 / (25.0 + 55.0 + 45.0))
    assert p.stage_fraction() == pytest.approx(0.5)  # the fit's own share: the diagnosis's maybe is not the fit's
    clock.t = 50.0
    stage(p, "diagnosis")
    assert "(45 s more if the diagnosis tries the forms)" in p.status()
    expect(p, 20.0)  # it says its own: no forms
    assert p.remaining_s() == pytest.approx(20.0) and "more if" not in p.status()


def test_a_plan_part_counts_what_its_step_may_add():
    """A diagnosis's base identification is a part of its plan: what its fit says may still run (the refinement's
    restarts) is counted in the part's seconds (the plan says only its own conditional parts beside)."""
    from tuner.progress import Plan, expect

    clock, out = Clock(), io.StringIO()
    p = JobProgress({"diagnosis": 100.0}, stream=out, tty=False, clock=clock)
    stage(p, "diagnosis")
    plan = Plan(p, {"identify": 1.0}, clock=clock)
    expect(plan.part("identify"), 20.0, (30.0, "the refinement is restarted"))
    assert p.remaining_s() == pytest.approx(50.0)


def test_the_percentage_tells_the_time_left_and_never_goes_back_when_a_forecast_stage_starts():
    """The main job's case: the diagnosis priced in seconds from the start at far more than its planned share.
    The percentage is the elapsed time over itself and the time left, so the stage's start (where the forecast
    becomes the stage's own clock) does not take it from 41 % back to 21 %; a later upward revision of the
    time left lengthens the time left and leaves the percentage where the display had it."""
    from tuner.progress import expect, forecast

    clock, out = Clock(), io.StringIO()
    p = JobProgress({"fit": 60.0, "validate": 12.0, "diagnosis": 70.0, "report": 8.0}, stream=out, tty=False,
                    clock=clock)
    stage(p, "fit")
    forecast(p, "diagnosis", 150.0)
    shown = []
    for t, step in ((20.0, lambda: advance(p, 0.5)), (44.0, lambda: stage(p, "validate")),
                    (48.0, lambda: stage(p, "diagnosis")), (59.0, lambda: expect(p, 25.0))):
        clock.t = t
        step()
        left = p.remaining_s()
        assert p.completed() == pytest.approx(t / (t + left)), t  # one story with the time left
        shown.append(p.completed())
    assert shown == sorted(shown)
    clock.t = 60.0
    expect(p, 400.0)  # the stage finds more work: more time left, the percentage stays
    assert p.remaining_s() > 400.0
    assert p.completed() == pytest.approx(shown[-1])


def test_an_identification_tells_its_log_the_seconds_left_of_its_search_and_refinements(small_lumped):
    """``identify`` (through ``fit``) says its seconds left at every Firefly iteration (the search's rest and the
    refinements priced at the measured cost per simulation) and before every refinement after the first (those
    still to run at the measured time of those done), so a stage that overruns a forecast made before it started
    still counts down from what it measures, not from zero."""
    from tuner.identification.engine import fastest_engine
    from tuner.identification.fit import FitSettings, fit, refinement_starts

    said, lines = [], []

    class Log:
        def __call__(self, msg):
            lines.append(msg)
            said.append(("line", msg))

        def stage(self, name):
            pass

        def advance(self, fraction):
            pass

        def expect(self, seconds_left, maybe=None):
            said.append(("expect", seconds_left))

    ident, valid = small_lumped
    # a random first population: the seeded one holds the preset, which made these data, and a refinement from it
    # ends at the residual floor, where no restart runs
    fit(ident, valid, FitSettings(models=("lumped",), population=4, iterations=3, workers=0, engine=fastest_engine(),
                                  polish_jacobians=2, init="random"), log=Log())
    expects = [s for kind, s in said if kind == "expect"]
    assert expects and all(s >= 0.0 for s in expects)
    first_refinement = next(k for k, (kind, m) in enumerate(said) if kind == "line" and "local refinement from" in m)
    search = [s for kind, s in said[:first_refinement] if kind == "expect"]
    refining = [s for kind, s in said[first_refinement:] if kind == "expect"]
    assert len(search) >= 3 and search[0] > 0.0  # every iteration, the refinements included
    runs = sum("local refinement from" in m and "RMSE" in m for m in lines)
    assert runs == refinement_starts("lumped") and len(refining) == runs - 1
    assert all(s > 0.0 for s in refining)  # each before a run still to come


def test_the_forms_are_not_forecast_after_a_lead_that_reaches_the_floor_and_long_steps_tick():
    """The forms run only where the lead (or the base, when nothing scores) leaves a residual above twice the
    floor (``weigh_forms``, ``forms_on_top``): a lead at the floor brings none to the forecast (the stiff-mount
    gap's diagnosis said 2.8 min left for two passes that never ran, 32 s before its end). Every batch of
    simulations ticks the display, so a long step is not a silence."""
    from tuner.diagnosis.cost_model import DiagnosisCost, form_pass_cost
    from tuner.diagnosis.search.selection import expect_after_ranking
    from tuner.diagnosis.search.state import SearchState
    from tuner.diagnosis.settings import DiagnosisSettings
    from tuner.identification.parametrization import Parametrization

    search = SearchState.__new__(SearchState)
    search.credible, search.floor, search.forecast = True, 20.0, lambda: None
    search.par, search.settings = Parametrization("lumped", force_limit=4e4), DiagnosisSettings()
    search.none_row = {"effect": "none", "identification_rmse_n": 500.0, "score": 0.0}
    lead = {"effect": "free_play", "score": 6.0, "effect_rms_n": 900.0, "resolved": True, "significant": True,
            "parameters": {}}
    forms = {}
    for rmse in (21.0, 300.0):
        search.cost = DiagnosisCost(reference=0.0, screen=0.0, refits=0.0, forms=0.0, detection=0.0)
        search.ranking = [{**lead, "identification_rmse_n": rmse}]
        expect_after_ranking(search)
        forms[rmse] = search.cost.forms
    assert forms[21.0] == 0.0 and forms[300.0] == pytest.approx(2 * form_pass_cost(search.par.dimension,
                                                                                   search.settings))

    clock = Clock()
    out = io.StringIO()
    log = JobProgress({"diagnosis": 1.0}, stream=out, clock=clock)
    stage(log, "diagnosis")
    log.expect(100.0)
    search.log = log
    lines = out.getvalue().count("progress")
    clock.t += 30.0
    search.tick()  # as after a batch, 30 s into a step that said nothing
    assert out.getvalue().count("progress") == lines + 1
    assert "about 1.2 min left" in out.getvalue().splitlines()[-1]


def test_an_engine_calls_its_after_batch_once_per_batch(small_lumped):
    """The diagnosis's tick (``SearchState.tick``) rides on the engines: once after every batch."""
    from damper_fmu import defaults
    from tuner.identification.engine import Engine, fastest_engine
    from tuner.identification.problem import DataSettings, Problem

    problem = Problem.build(small_lumped[0], [], DataSettings())
    calls = []
    with Engine("lumped", problem.sig_id, engine=fastest_engine(), workers=0) as eng:
        eng.after_batch = lambda: calls.append(eng.evaluations)
        eng.residuals_batch([defaults("lumped")] * 2)
        eng.sse_batch([defaults("lumped")])
    assert calls == [2, 3]


def test_the_search_is_forecast_to_its_likely_stop_not_its_whole_budget():
    """The Firefly search can stop at the data's resolution once ``stop_start`` iterations are done and its best
    has moved by less than FTOL over ``stop_window`` of them: while its best stays, the display counts to that
    stop; a best that moves pushes it back; never beyond the budget; the whole budget without the stop rule."""
    from tuner.identification.firefly import FireflyOptions
    from tuner.identification.fit import search_iterations_left

    opts = FireflyOptions(max_iterations=150, stop_start=20, stop_window=20)
    flat = [1.0] * 6  # iterations 0-5, no progress since the first population
    assert search_iterations_left(flat, 5, opts) == 15
    moved = [1.0] * 18 + [2.0, 2.0]  # a better best found at iteration 18, none since
    assert search_iterations_left(moved, 19, opts) == 18 + 20 - 19
    within = [1.0] * 18 + [1.005, 1.005]  # a move within FTOL (1 %) counts as none
    assert search_iterations_left(within, 19, opts) == 1
    assert search_iterations_left(moved, 19, FireflyOptions(max_iterations=30, stop_start=20, stop_window=20)) == 11
    assert search_iterations_left(flat, 5, FireflyOptions(max_iterations=150, stop_tol=None)) == 145
