"""The time budget: stages and sections clocked against a known clock, the hooks passed on, and the job's record."""
from __future__ import annotations

from tuner.progress import Plan
from tuner.time_budget import SETUP, TimeBudget, section


class Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


class Inner:
    """A log with the progress hooks, recording what reaches it."""

    def __init__(self):
        self.lines, self.stages, self.fractions = [], [], []

    def __call__(self, msg):
        self.lines.append(msg)

    def stage(self, name):
        self.stages.append(name)

    def advance(self, fraction):
        self.fractions.append(fraction)


def test_stages_and_sections_add_up_to_the_clock():
    clock, inner = Clock(), Inner()
    b = TimeBudget(inner, clock=clock)
    clock.t += 2.0  # prepare
    b.stage("fit lumped")
    clock.t += 1.0  # setup of the fit
    section(b, "Firefly search")
    clock.t += 10.0
    section(b, "restart check")
    clock.t += 5.0
    b.stage("diagnosis")
    plan = Plan(b, {"part": 1.0})
    section(plan.part("part"), "screen")  # a section through the diagnosis's plan reaches the budget
    clock.t += 4.0
    section(plan, "screen")  # the same section again: summed
    clock.t += 3.0
    rec = b.record()
    assert rec["total_s"] == 25.0
    stages = {s["stage"]: s for s in rec["stages"]}
    assert [s["stage"] for s in rec["stages"]] == ["prepare", "fit lumped", "diagnosis"]
    assert stages["prepare"]["seconds"] == 2.0
    fit = {s["section"]: s["seconds"] for s in stages["fit lumped"]["sections"]}
    assert fit == {SETUP: 1.0, "Firefly search": 10.0, "restart check": 5.0}
    assert stages["fit lumped"]["seconds"] == 16.0 and abs(stages["fit lumped"]["share"] - 16 / 25) < 1e-12
    assert {s["section"]: s["seconds"] for s in stages["diagnosis"]["sections"]}["screen"] == 7.0
    assert sum(s["seconds"] for s in rec["stages"]) == rec["total_s"]
    assert inner.stages == ["fit lumped", "diagnosis"]  # passed on


def test_hooks_pass_through_and_a_plain_log_has_none():
    inner = Inner()
    b = TimeBudget(inner)
    b("hello")
    b.advance(0.5)
    assert inner.lines == ["hello"] and inner.fractions == [0.5]
    assert not hasattr(TimeBudget(print), "advance")  # what the inner log lacks, the budget lacks
    section(print, "ignored")  # a log without the hook: nothing happens


def test_text_lists_every_stage():
    clock = Clock()
    b = TimeBudget(lambda m: None, clock=clock)
    b.stage("fit")
    clock.t += 3.0
    b.stage("report")
    clock.t += 1.0
    text = b.text()
    assert "4 s in all" in text and "fit" in text and "report" in text and "75.0 %" in text
