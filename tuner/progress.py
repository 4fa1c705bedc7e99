"""One progress display for a whole job (build, fits, validation, diagnosis, report).

A :class:`JobProgress` is the ``log`` callable the pipeline writes its messages to; it also
receives where the job stands: ``stage(name)`` when a stage starts and ``advance(fraction)``
inside it (0-1). The estimate of the time left is the elapsed time scaled by the expected cost of
the remaining stages over that of the finished part; the expected costs are relative weights
(seconds of the default run), so the estimate is refined as stages finish. A stage whose cost depends on
the data more than a plan can know (the diagnosis: how many candidates the screen passes, whether the forms
run, the model's simulation cost on these tests) says its own seconds left as it goes (``expect``); the
later stages are then scaled by how the finished ones went against their plan.

On a terminal: a tqdm bar over the whole job, messages printed above it. Otherwise (CI, logs):
plain lines ``[HH:MM:SS +M:SS] message`` and, at most every ``interval_s``, a progress line
``[HH:MM:SS +M:SS] progress 37 % (stage: fit lumped 80 %), about 2.1 min left``. ``quiet``:
nothing is printed.

Pipeline functions call the progress hooks only when their ``log`` has them (:func:`stage`,
:func:`advance`), so a plain ``print`` still works as ``log``.
"""
from __future__ import annotations

import sys
import time

from tuner.time_budget import section as _section

__all__ = ["JobProgress", "SubStages", "Plan", "stage", "advance", "expect", "forecast"]


def stage(log, name: str) -> None:
    """Tell ``log`` that stage ``name`` starts, if it keeps progress."""
    hook = getattr(log, "stage", None)
    if hook is not None:
        hook(name)


def advance(log, fraction: float) -> None:
    """Tell ``log`` how far [0-1] the current stage is, if it keeps progress."""
    hook = getattr(log, "advance", None)
    if hook is not None:
        hook(fraction)


def forecast(log, stage_name: str, seconds: float, maybe: tuple[float, str] | None = None) -> None:
    """Tell ``log`` that stage ``stage_name``, still to come, is expected to take ``seconds`` [s] on this machine
    (in place of its planned weight), if it keeps progress; ``maybe``: (seconds [s], what) it may take more if
    what happens (said beside the time left, as ``expect``'s)."""
    hook = getattr(log, "forecast", None)
    if hook is not None:
        hook(stage_name, seconds, maybe)


def expect(log, seconds_left: float, maybe: tuple[float, str] | None = None) -> None:
    """Tell ``log`` the current stage's expected seconds left on this machine, if it keeps progress; ``maybe``:
    (seconds [s], what) of a part that may still run, not counted in them (the display says it beside)."""
    hook = getattr(log, "expect", None)
    if hook is not None:
        if maybe is None:
            hook(seconds_left)
        else:
            hook(seconds_left, maybe)


class SubStages:
    """A ``log`` for a function that reports stages of its own (``n`` of them) inside one stage of a
    job: their starts and progress advance the job's current stage; lines go to the job's log."""

    def __init__(self, log, n: int):
        self.log, self.n, self.k = log, max(int(n), 1), 0

    def __call__(self, msg: str) -> None:
        self.log(msg)

    def stage(self, name: str) -> None:
        self.k = min(self.k + 1, self.n)
        advance(self.log, (self.k - 1) / self.n)

    def section(self, name: str) -> None:
        """A section of the job's current stage starts (``tuner.time_budget.section``)."""
        _section(self.log, name)

    def advance(self, fraction: float) -> None:
        advance(self.log, (max(self.k, 1) - 1 + min(max(float(fraction), 0.0), 1.0)) / self.n)


class Plan:
    """A ``log`` for a function whose parts are known in advance with their expected costs (``weights``:
    name -> relative cost), some of which may turn out not to run (``skip``). ``part(name)`` is the log of
    one part: its progress advances the job's current stage by the part's share of the planned total. A
    part that will not run counts as done only when skipped, so the time left covers every part that may
    still run (a repeat on another base form), and no stage reads 100 % while parts remain.

    Parts may say their expected seconds (``expect``); once every open part has, their sum goes to the job,
    again at every step of a part: a part that has started counts down from what it said (never below 0),
    one that has not keeps its whole forecast, so a part that overruns its forecast does not eat the
    time of the parts still to come. A part that runs only if something turns out so (``maybe``: a repeat on
    another base form) is said beside the sum, with what it depends on, until it starts or is skipped: the
    time left is then right whether it runs or not."""

    def __init__(self, log, weights: dict[str, float], *, clock=time.monotonic):
        if not weights or any(w <= 0 for w in weights.values()):
            raise ValueError("weights must be a non-empty dict of positive expected costs")
        self.log, self.weights, self.clock = log, dict(weights), clock
        self.fractions = {name: 0.0 for name in weights}
        self.started: set[str] = set()  # parts that reported progress
        self.conditional: dict[str, str] = {}  # parts that may not run -> what they depend on (``maybe``)
        self.seconds_left: dict[str, tuple[float, float]] = {}  # part -> (seconds it said, when) (``expect``)

    def __call__(self, msg: str) -> None:
        self.log(msg)

    def section(self, name: str) -> None:
        """A section of the job's current stage starts (``tuner.time_budget.section``)."""
        _section(self.log, name)

    def part(self, name: str) -> "_PlanPart":
        if name not in self.weights:
            raise KeyError(f"{name!r} is not a part of the plan ({', '.join(self.weights)})")
        return _PlanPart(self, name)

    def maybe(self, name: str, what: str | None) -> None:
        """Part ``name`` runs only if ``what`` (words: 'the diagnosis is repeated on the lumped base'); None: it
        runs for certain."""
        if what is None:
            self.conditional.pop(name, None)
        else:
            self.conditional[name] = what
        self._forward()

    def skip(self, name: str) -> None:
        """The part ``name`` will not run (or was taken from a checkpoint): count it as done."""
        self.set(name, 1.0)

    def set(self, name: str, fraction: float) -> None:
        self.fractions[name] = min(max(float(fraction), self.fractions[name]), 1.0)
        if name not in self.started and name in self.seconds_left:  # said before it started: counted from now
            self.seconds_left[name] = (self.seconds_left[name][0], self.clock())
        self.started.add(name)
        total = sum(self.weights.values())
        advance(self.log, sum(self.weights[k] * f for k, f in self.fractions.items()) / total)
        self._forward()

    def expect(self, name: str, seconds_left: float) -> None:
        """Part ``name`` expects ``seconds_left`` [s] more from now (0 once done)."""
        self.seconds_left[name] = (max(0.0, float(seconds_left)), self.clock())
        self._forward()

    def _forward(self) -> None:
        """The open parts' seconds left to the job (``expect``) when every one of them has said its own."""
        open_parts = [k for k, f in self.fractions.items() if f < 1.0]
        if not all(k in self.seconds_left for k in open_parts):
            return
        now, left, maybe = self.clock(), 0.0, []
        for k in open_parts:
            said, at = self.seconds_left[k]
            if k in self.conditional and k not in self.started:
                maybe.append((said, self.conditional[k]))
                continue
            left += max(0.0, said - (now - at)) if k in self.started else said
        expect(self.log, left, (sum(m[0] for m in maybe), " or ".join(m[1] for m in maybe)) if maybe else None)


class _PlanPart:
    """The log of one part of a :class:`Plan` (messages to the plan's log, progress to the part)."""

    def __init__(self, plan: Plan, name: str):
        self.plan, self.name = plan, name

    def __call__(self, msg: str) -> None:
        self.plan.log(msg)

    def section(self, name: str) -> None:
        """A section of the job's current stage starts (``tuner.time_budget.section``)."""
        _section(self.plan.log, name)

    def advance(self, fraction: float) -> None:
        self.plan.set(self.name, fraction)

    def expect(self, seconds_left: float, maybe: tuple[float, str] | None = None) -> None:
        """The part's seconds left [s]; what may still run (``maybe``: seconds, what) is counted in them: a part's
        forecast is all it may take (the plan says its conditional parts beside, ``Plan.maybe``)."""
        self.plan.expect(self.name, seconds_left + (maybe[0] if maybe is not None else 0.0))


class JobProgress:
    """Progress over the stages of one job; ``weights``: stage name -> expected cost (relative); ``first_of``:
    (stages, extra cost): whichever of these stages starts first costs ``extra`` more than its weight (the base
    forms' fits: the first gets every refinement restart, the others race it, and which is first follows from
    the data), planned on the first listed until then."""

    def __init__(self, weights: dict[str, float], *, quiet: bool = False, stream=None, tty: bool | None = None,
                 interval_s: float = 10.0, clock=time.monotonic, first_of: tuple[tuple, float] = ((), 0.0)):
        if not weights or any(w <= 0 for w in weights.values()):
            raise ValueError("weights must be a non-empty dict of positive expected costs")
        self.weights = dict(weights)
        self._first_of = (tuple(first_of[0]), float(first_of[1]))
        if self._first_of[0]:
            self.weights[self._first_of[0][0]] += self._first_of[1]
        self.quiet, self.stream = quiet, stream or sys.stdout
        self.tty = self.stream.isatty() if tty is None else tty
        self.interval_s, self.clock = interval_s, clock
        self.t0 = clock()
        self.done: list[str] = []
        self.current: str | None = None
        self.fraction = 0.0
        self._started = self.t0  # when the current stage started
        self._before_current = 0.0  # seconds the finished stages took
        self._said: tuple[float, float] | None = None  # (seconds left, when) the current stage said (``expect``)
        self._maybe: tuple[float, str] | None = None  # (seconds, what) of a part that may still run (``expect``)
        self.forecasts: dict[str, float] = {}  # stage -> seconds it is expected to take (``forecast``)
        self.forecast_maybes: dict[str, tuple[float, str]] = {}  # stage -> (seconds, what) it may take more
        self._last_line = -float("inf")
        self._shown = 0.0  # the share the display last showed (``completed`` never goes below it)
        self._bar = None
        if self.tty and not quiet:
            from tqdm import tqdm

            self._bar = tqdm(total=1000, file=self.stream, leave=False, dynamic_ncols=True,
                             bar_format="{l_bar}{bar}| {postfix}")

    # -- state -----------------------------------------------------------------------------------
    @property
    def elapsed(self) -> float:
        return self.clock() - self.t0

    def completed(self) -> float:
        """Share [0-1] of the job done: the elapsed time over itself and the time left once that is estimated
        (``remaining_s``: so the percentage and the time left tell one story, forecasts in seconds included, and
        what may still run),
        before that the share of the planned weights done. Never less than the display showed before: an
        estimate revised upward lengthens the time left, it does not take back progress."""
        left = self.remaining_s()
        if left is None:
            share = self._planned_share()
        else:
            left += self._may_still_run_s()
            share = self.elapsed / (self.elapsed + left) if self.elapsed + left > 0 else 0.0
        return max(share, self._shown)

    def _may_still_run_s(self) -> float:
        """Seconds [s] of a part that may still run (``expect``'s ``maybe``): not in the time left, which says it
        beside, but in the shares shown, so that no percentage stands near 100 while a repeat of minutes runs
        (a hidden free play: 96 % for 3 min before); when it does not run, the share jumps forward."""
        maybe = self.maybe_now()
        return maybe[0] if maybe is not None else 0.0

    def maybe_now(self) -> tuple[float, str] | None:
        """(seconds [s], what) that may still run: the current stage's (``expect``) and the later stages'
        (``forecast``), None when nothing may."""
        later = [s for s in self.weights if s not in self.done and s != self.current]
        parts = [m for m in (self._maybe, *(self.forecast_maybes.get(s) for s in later)) if m is not None and m[0] > 0]
        if not parts:
            return None
        return sum(m[0] for m in parts), " or ".join(m[1] for m in parts)

    def _planned_share(self) -> float:
        """Share [0-1] of the planned weights done (the current stage by its fraction)."""
        total = sum(self.weights.values())
        done = sum(self.weights[s] for s in self.done)
        if self.current is not None and self.current not in self.done:
            done += self.weights.get(self.current, 0.0) * self.fraction
        return min(done / total, 1.0)

    def stage_fraction(self) -> float:
        """Share [0-1] of the current stage done: of its expected time when it said its seconds left (with what
        may still run)."""
        if self._said is None:
            return self.fraction
        spent = self.clock() - self._started
        own_maybe = self._maybe[0] if self._maybe is not None and self._maybe[0] > 0 else 0.0
        left = max(0.0, self._said[0] - (self.clock() - self._said[1])) + own_maybe
        return spent / (spent + left) if spent + left > 0 else 1.0

    def remaining_s(self) -> float | None:
        """Estimated seconds left (None until some of the job is done). With the current stage's own forecast
        (``expect``): what it said, less the time since, plus the later stages' weights scaled by how the
        finished stages went against theirs. Without: the elapsed time scaled by the expected cost left over the
        cost done. A later stage forecast in seconds (``forecast``) counts with them, not its weight."""
        later = [s for s in self.weights if s not in self.done and s != self.current]
        foreseen = sum(self.forecasts[s] for s in later if s in self.forecasts)
        planned_later = sum(self.weights[s] for s in later if s not in self.forecasts)
        if self._said is not None:
            left, at = self._said
            planned_done = sum(self.weights[s] for s in self.done)
            speed = self._before_current / planned_done if planned_done > 0 else 1.0
            return max(0.0, left - (self.clock() - at)) + speed * planned_later + foreseen
        c = self._planned_share()
        if c <= 0.02:
            return None
        per_weight = self.elapsed / (c * sum(self.weights.values()))  # [s] per unit of planned cost so far
        unplanned = sum(self.weights[s] for s in later if s in self.forecasts)
        return per_weight * (sum(self.weights.values()) * (1.0 - c) - unplanned) + foreseen

    def forecast(self, stage_name: str, seconds: float, maybe: tuple[float, str] | None = None) -> None:
        """Stage ``stage_name`` (one still to come) is expected to take ``seconds`` [s] on this machine, and
        ``maybe`` (seconds [s], what) more if what happens."""
        self.forecasts[stage_name] = max(0.0, float(seconds))
        if maybe is not None:
            self.forecast_maybes[stage_name] = maybe

    # -- hooks -----------------------------------------------------------------------------------
    def stage(self, name: str) -> None:
        if self.current is not None and self.current not in self.done:
            self.done.append(self.current)
        group, extra = self._first_of
        if name in group:  # the first of the group to start: its extra cost moves to it
            self.weights[group[0]] -= extra
            self.weights[name] += extra
            self._first_of = ((), 0.0)
        if name not in self.weights:  # an unplanned stage: give it the mean weight
            self.weights[name] = sum(self.weights.values()) / len(self.weights)
        self.current, self.fraction, self._said, self._maybe = name, 0.0, None, None
        self._started = self.clock()
        if name in self.forecasts:  # its forecast stands until it says its own
            self._said = (self.forecasts[name], self._started)
            self._maybe = self.forecast_maybes.get(name)
        self._before_current = self._started - self.t0
        self._show(force=True)

    def expect(self, seconds_left: float, maybe: tuple[float, str] | None = None) -> None:
        """The current stage's own forecast: ``seconds_left`` [s] on this machine from now; ``maybe``: (seconds
        [s], what) more if what happens (said beside the time left, not counted in it)."""
        self._said = (max(0.0, float(seconds_left)), self.clock())
        self._maybe = maybe
        self._show()

    def advance(self, fraction: float) -> None:
        self.fraction = min(max(float(fraction), self.fraction), 1.0)
        self._show()

    def finish(self) -> None:
        if self.current is not None and self.current not in self.done:
            self.done.append(self.current)
        self.current = None
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __call__(self, msg: str) -> None:
        if self.quiet:
            return
        if self._bar is not None:
            self._bar.write(str(msg), file=self.stream)
        else:
            for line in str(msg).splitlines() or [""]:
                self.stream.write(f"{self._stamp()} {line}\n" if line.strip() else "\n")
            self.stream.flush()

    # -- display ---------------------------------------------------------------------------------
    def _stamp(self) -> str:
        e = int(self.elapsed)
        return f"[{time.strftime('%H:%M:%S')} +{e // 60}:{e % 60:02d}]"

    def status(self) -> str:
        """``progress 37 % (stage: fit lumped 80 %), about 2.1 min left``."""
        left = self.remaining_s()
        eta = "estimating time left" if left is None else f"about {_duration(left)} left"
        maybe = self.maybe_now()
        if left is not None and maybe is not None:
            eta += f" ({_duration(maybe[0])} more if {maybe[1]})"
        st = f" (stage: {self.current} {100 * self.stage_fraction():.0f} %)" if self.current else ""
        return f"progress {100 * self.completed():.0f} %{st}, {eta}"

    def _show(self, force: bool = False) -> None:
        if self.quiet:
            return
        if self._bar is not None:
            self._shown = self.completed()
            self._bar.n = int(1000 * self._shown)
            left = self.remaining_s()
            m = self.maybe_now()
            maybe = f" (+{_duration(m[0])} if {m[1]})" if m is not None else ""
            self._bar.set_postfix_str(f"{self.current or ''} {100 * self.stage_fraction():.0f} %"
                                      + ("" if left is None else f", ~{_duration(left)} left{maybe}"), refresh=True)
            return
        now = self.clock()
        if force or now - self._last_line >= self.interval_s:
            self._last_line = now
            line = self.status()
            self._shown = self.completed()
            self.stream.write(f"{self._stamp()} {line}\n")
            self.stream.flush()


def _duration(seconds: float) -> str:
    """'2.1 min' or '42 s'."""
    return f"{seconds / 60:.1f} min" if seconds >= 60 else f"{seconds:.0f} s"
