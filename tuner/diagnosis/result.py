"""The result of a diagnosis (``tuner.diagnosis.diagnose.diagnose``): a read-only object over the record
that ``diagnosis.json`` holds.

The principal answers are attributes (``cause``, ``causes``, ``form``, ``verdict``, ``base_model``,
``effect_parameters``, ...); the whole record (ranking rows, selection steps, evidence, detection limits,
settings: the keys of ``diagnosis.json``, documented in ``docs/diagnosis.md``) is read by key,
``diagnosis["ranking"]``, and given whole by ``to_dict()`` (a copy: the result itself cannot be changed
after the diagnosis, so what a report or a caller reads is what was decided). Units as in the record:
SI, forces in N, MSE in N^2.
"""
from __future__ import annotations

import copy
from collections.abc import Mapping

__all__ = ["Diagnosis"]


class Diagnosis(Mapping):
    """What the diagnosis found: the cause(s) named, the form, the verdict and the whole record.

    ``record``: the dict written as ``diagnosis.json`` (strict JSON). Reading a key returns a copy of
    its value, so the result cannot be altered through what it hands out."""

    def __init__(self, record: dict):
        self._record = copy.deepcopy(dict(record))

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
