"""The result of a diagnosis (``tuner.diagnosis.diagnose.diagnose``): a read-only object over the record
that ``diagnosis.json`` holds, with what the job needs to write the rest (the final model's values, the
residual series the figures show); and the failure of a stage (``DiagnosisFailed``, with its record).

The principal answers are attributes (``cause``, ``causes``, ``form``, ``verdict``, ``base_model``,
``effect_parameters``, ...); the whole record (ranking rows, selection steps, evidence, detection limits,
settings: the keys of ``diagnosis.json``, documented in ``docs/diagnosis.md``) is read by key,
``diagnosis["ranking"]``, and given whole by ``to_dict()`` (a copy: the result itself cannot be changed
after the diagnosis, so what a report or a caller reads is what was decided). Units as in the record:
SI, forces in N, MSE in N^2.

Neither writes a file: ``tuner.job.write_diagnosis`` writes ``diagnosis.json``, the figures and the extended
FMU from a ``Diagnosis``, ``tuner.job.write_diagnosis_failure`` the record of a ``DiagnosisFailed``.
"""
from __future__ import annotations

import copy
import traceback
from collections.abc import Mapping
from pathlib import Path

__all__ = ["Diagnosis", "DiagnosisFailed", "failure_record"]


class DiagnosisFailed(RuntimeError):
    """A stage of the diagnosis raised. ``stage`` names it (e.g. 'forms beyond the catalogue on the lumped
    base'); ``record`` is what ``diagnosis.json`` holds for it (``failure_record``: ``failed_stage``, the error,
    the stages finished, the ranking so far); ``path`` is that file once the job wrote it
    (``tuner.job.write_diagnosis_failure``), None before; the original exception is chained (``__cause__``).
    Called again with the same checkpoints (``--resume``), the diagnosis continues from the last finished
    stage."""

    def __init__(self, stage: str, record: dict, error: BaseException):
        super().__init__(stage, error)
        self.stage, self.record, self.error = stage, record, error
        self.path: Path | None = None

    def __str__(self) -> str:
        where = self.path if self.path is not None else "its record (DiagnosisFailed.record, not written yet)"
        return (f"the diagnosis failed in its stage '{self.stage}': {type(self.error).__name__}: {self.error}. "
                f"What it had finished is in {where}; run the same command with --resume to continue from the "
                f"last finished stage")

    def __reduce__(self):  # across processes (a batch row's pool) with its record and path
        return type(self), (self.stage, self.record, self.error), {"path": self.path}


def failure_record(stage: str, error: BaseException, stages: dict, settings: dict) -> dict:
    """The record (``diagnosis.json``) of a diagnosis that failed in ``stage``: no verdict, the error and its
    traceback, the stages finished, and what the failing stage had (the ranking so far, the causes named so
    far). ``stages``: {'finished': [stage names], 'partial': what the failing stage had (or None),
    'base_choice': how the base was chosen}; ``settings``: the settings block of the record."""
    partial = stages.get("partial") or {}
    return {"failed_stage": stage, "error": f"{type(error).__name__}: {error}",
            "traceback": traceback.format_exception(error), "finished_stages": list(stages["finished"]),
            "cause": None, "causes": list(partial.get("causes") or []),
            "verdict": (f"no verdict: the diagnosis failed in its stage '{stage}' "
                        f"({type(error).__name__}: {error}); run the same command with --resume to continue"),
            "base_model": partial.get("base_model"), "base_choice": copy.deepcopy(stages.get("base_choice")),
            "ranking": list(partial.get("ranking") or []), "selection": list(partial.get("selection") or []),
            "forms_tried": partial.get("forms_tried"), "settings": settings}


class Diagnosis(Mapping):
    """What the diagnosis found: the cause(s) named, the form, the verdict and the whole record.

    ``record``: the dict written as ``diagnosis.json`` (strict JSON). Reading a key returns a copy of
    its value, so the result cannot be altered through what it hands out. ``final_values``: the final
    model's parameter values (SI; the base's when nothing was named): the extended FMU's start values.
    ``residuals``: {figure folder relative to the output folder: the base model's residual series
    (``tuner.diagnosis.residual_tests.TestResidual``)} of every base form diagnosed, which the figures show.
    ``stages``: the stages finished and how the base was chosen (``failure_record``), for a stage the job
    runs after the diagnosis (the export of the extended FMU, ``failed``)."""

    def __init__(self, record: dict, *, final_values: dict | None = None, residuals: dict | None = None,
                 stages: dict | None = None):
        self._record = copy.deepcopy(dict(record))
        self._final_values = dict(final_values or {})
        self._residuals = {folder: list(series) for folder, series in (residuals or {}).items()}
        self._stages = copy.deepcopy(stages or {"finished": [], "partial": None, "base_choice": None})

    # -- the principal answers ---------------------------------------------------------------------
    @property
    def cause(self) -> str:
        """The first cause named, 'none' (nothing to explain) or 'unexplained' (a form error no
        candidate explains)."""
        return self._record["cause"]

    @property
    def causes(self) -> list[str]:
        """Every cause named, in the order they were selected (catalogue effects and forms)."""
        return list(self._record.get("causes") or [])

    @property
    def form(self) -> str | None:
        """The form beyond the catalogue named (e.g. 'hysteresis'), or None."""
        return self._record.get("form")

    @property
    def verdict(self) -> str:
        """The verdict in words, as the log and the report give it."""
        return self._record["verdict"]

    @property
    def base_model(self) -> str:
        """The base form the causes were added to ('lumped' or 'twochamber')."""
        return self._record["base_model"]

    @property
    def effect_parameters(self) -> dict:
        """{parameter: {value, unit, low, high, ...}} of the causes named (SI), empty without a cause."""
        return copy.deepcopy(self._record.get("effect_parameters") or {})

    @property
    def unexplained(self) -> dict | None:
        """The residual above the floor that no cause explains (its RMS [N], ratio to the floor, evidence),
        or None."""
        return copy.deepcopy(self._record.get("unexplained"))

    @property
    def final_values(self) -> dict:
        """{parameter: value} (SI) of the final model: the base extended by the causes named (the base
        alone without one); the start values of the extended FMU."""
        return dict(self._final_values)

    @property
    def residuals(self) -> dict:
        """{figure folder (relative to the output folder): [``TestResidual``]}: the base model's residual on
        every test, for each base form diagnosed (the figures' data; the series are not copied)."""
        return {folder: list(series) for folder, series in self._residuals.items()}

    def failed(self, stage: str, error: BaseException) -> DiagnosisFailed:
        """The failure of ``stage``, run after the diagnosis (the export of the extended FMU): the record of
        a failed diagnosis with the stages this one finished (``failure_record``)."""
        return DiagnosisFailed(stage, failure_record(stage, error, self._stages, self["settings"]), error)

    # -- the whole record ----------------------------------------------------------------------------
    def __getitem__(self, key: str):
        return copy.deepcopy(self._record[key])

    def __iter__(self):
        return iter(self._record)

    def __len__(self) -> int:
        return len(self._record)

    def to_dict(self) -> dict:
        """The whole record (a copy), as written to ``diagnosis.json``."""
        return copy.deepcopy(self._record)

    def __repr__(self) -> str:
        return f"Diagnosis(cause={self.cause!r}, causes={self.causes!r}, base_model={self.base_model!r})"
