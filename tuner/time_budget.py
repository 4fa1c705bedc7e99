"""Where a run's minutes went: each stage's and each section's wall time [s] and share of the run.

A :class:`TimeBudget` wraps the job's ``log`` (a plain callable or a ``tuner.progress.JobProgress``): messages
and the progress hooks go on to it unchanged, and it clocks the job's stages (``tuner.progress.stage``) and the
sections inside them (``section``: the Firefly search, the local refinements, the restart check, the
diagnosis's screen, each candidate's refit, ...). Time inside a stage before its first section is its
"setup"; a section lasts until the next section or stage starts. ``TimeBudget.record`` is what
``time_budget.json`` and the report's table hold, ``TimeBudget.text`` what the end of the log says.

Pipeline functions call ``section(log, name)`` whatever their ``log`` is: a log without the hook (``print``)
ignores it, as ``tuner.progress.stage`` does.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

__all__ = ["TimeBudget", "BudgetSection", "section", "SETUP"]

#: the name of a stage's time before its first section
SETUP = "setup"


def section(log, name: str) -> None:
    """Tell ``log`` that section ``name`` of the current stage starts, if it keeps a time budget."""
    hook = getattr(log, "section", None)
    if hook is not None:
        hook(name)


@dataclass
class BudgetSection:
    """One clocked span: its ``stage``, its ``section`` name within the stage (``SETUP`` for the time before the
    first) and its wall time ``seconds`` [s] (the sum when a stage runs a section of that name twice)."""

    stage: str
    section: str
    seconds: float


class TimeBudget:
    """A ``log`` that clocks stages and sections (module docstring) and passes everything on to ``log``.
    ``first_stage``: the name of the time before the first stage starts (reading and preparing the tests)."""

    def __init__(self, log, first_stage: str = "prepare", *, clock=time.perf_counter):
        self.log, self.clock = log, clock
        self.t0 = self.clock()
        self.spans: list[BudgetSection] = []
        self._stage, self._section, self._since = first_stage, SETUP, self.t0

    def __call__(self, msg: str) -> None:
        self.log(msg)

    def __getattr__(self, name: str):
        # the inner log's other hooks (advance, expect, forecast, finish): present here only when present there
        if name in ("log", "clock", "t0", "spans") or name.startswith("_"):
            raise AttributeError(name)
        return getattr(self.log, name)

    def _close(self) -> None:
        now = self.clock()
        for s in self.spans:
            if (s.stage, s.section) == (self._stage, self._section):
                s.seconds += now - self._since
                break
        else:
            self.spans.append(BudgetSection(self._stage, self._section, now - self._since))
        self._since = now

    def stage(self, name: str) -> None:
        """Stage ``name`` starts (its setup section first); passed on to the inner log's ``stage``."""
        self._close()
        self._stage, self._section = name, SETUP
        hook = getattr(self.log, "stage", None)
        if hook is not None:
            hook(name)

    def section(self, name: str) -> None:
        """Section ``name`` of the current stage starts."""
        self._close()
        self._section = name

    def total_s(self) -> float:
        """Wall time [s] since the budget started."""
        return self.clock() - self.t0

    def record(self) -> dict:
        """{"total_s", "stages": [{"stage", "seconds", "share", "sections": [{"section", "seconds", "share"}]}]}:
        seconds [s] up to now (the running section counted so far), shares of the total [0-1], stages in the
        order they ran, sections too; spans shorter than 0.05 s are left out of the sections."""
        self._close()
        total = max(self._since - self.t0, 1e-9)  # up to the close: the spans add up to it
        stages: dict[str, list[BudgetSection]] = {}
        for s in self.spans:
            stages.setdefault(s.stage, []).append(s)
        rows = []
        for name, spans in stages.items():
            seconds = sum(s.seconds for s in spans)
            rows.append({"stage": name, "seconds": seconds, "share": seconds / total,
                         "sections": [{"section": s.section, "seconds": s.seconds, "share": s.seconds / total}
                                      for s in spans if s.seconds >= 0.05]})
        return {"total_s": total, "stages": rows}

    def text(self) -> str:
        """The budget as lines for the log: one per stage and, indented, its sections of at least 1 % of the run."""
        rec = self.record()
        lines = [f"time budget: {rec['total_s']:.0f} s in all"]
        for st in rec["stages"]:
            lines.append(f"  {st['stage']:44s} {st['seconds']:7.1f} s  {100 * st['share']:5.1f} %")
            for sec in st["sections"]:
                if sec["share"] >= 0.01 and len(st["sections"]) > 1:
                    lines.append(f"    {sec['section']:42s} {sec['seconds']:7.1f} s  {100 * sec['share']:5.1f} %")
        return "\n".join(lines)
