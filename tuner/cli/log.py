"""The commands' log: plain lines, or the job's progress display while a job runs (``start_job``)."""
from __future__ import annotations

from tuner.progress import JobProgress

__all__ = ["log", "start_job", "end_job", "progress", "job_log"]

_OUT: JobProgress | None = None  # the job's progress display while a job runs


def log(msg: str) -> None:
    """One line: to the progress display when a job runs, else to stdout."""
    if _OUT is not None:
        _OUT(msg)
    else:
        print(msg, flush=True)


def start_job(args, weights: dict, first_of: tuple[tuple, float] = ((), 0.0)) -> JobProgress:
    """Progress display over the job's stages (``weights``: expected seconds; ``first_of``: ``JobProgress``'s); it
    is the log."""
    global _OUT
    _OUT = JobProgress(weights, quiet=getattr(args, "quiet", False), first_of=first_of)
    return _OUT


def end_job() -> None:
    global _OUT
    if _OUT is not None:
        _OUT.finish()
    _OUT = None


def progress() -> JobProgress | None:
    """The running job's progress display, None between jobs."""
    return _OUT


def job_log():
    """What a library function gets as its ``log``: the progress display (it keeps the stages) or ``log``."""
    return _OUT or log
