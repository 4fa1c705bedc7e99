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
