"""The settings of a diagnosis run and its candidate causes."""
from __future__ import annotations

from dataclasses import dataclass, field, fields

from damper_fmu.effect_catalogue import CATALOGUE_EFFECTS, FORM_EFFECTS

from tuner.identification.problem import DataSettings

__all__ = ["CANDIDATES", "DiagnosisSettings"]

#: the candidate causes: the effect catalogue of the design notes (effect_catalogue.CATALOGUE_EFFECTS); the
#: forms beyond it (effect_catalogue.FORM_EFFECTS) are tried after them, when a residual above the floor remains
CANDIDATES = CATALOGUE_EFFECTS


@dataclass
class DiagnosisSettings:
    """Settings of a diagnosis run (units in the names).

    data: the problem definition when the diagnosis prepares the tests itself (no fit's problem given):
    fit rate [Hz], warm-up [s], differentiator band [Hz], table abscissae [m/s, m] (without a base fit
    given), force limit [N], spring reference [N/m] (``DataSettings``); its parametrization must be
    'improved' (the local solver needs monotone tables)."""

    data: DataSettings = field(default_factory=DataSettings)
    workers: int = 2
    engine: str = "fmu"
    seed: int = 0
    #: Firefly iterations of a base form the diagnosis identifies itself (no fit given): none, its first population
    #: only (the data-driven guess, the preset, random members), then the local refinements from its best and from
    #: the guess (and the lumped form's restart ladder) do the work, as in the confusion benchmark. With 30, the
    #: two-chamber search on seed 500 of benchmarks/blind_class.py took 39-57 s to end at 1479 N rms, its
    #: refinement at 864 N, behind the guess's own (847 N), which the diagnosis kept
    base_iterations: int = 0
    base_polish_jacobians: int = 100  # a cap: the base refinement stops when converged
    polish_jacobians: int = 16  # per candidate, split between the two starts
    grid_points: int = 7
    guess_start: bool = True
    profile_steps: int = 8
    final_jacobians: int = 100  # continued refit of the leading candidate: a cap, it stops when converged
    max_causes: int = 3  # forward selection stops here at the latest
    candidates: tuple = CANDIDATES
    #: forms beyond the catalogue tried when a residual above the floor remains (tuner.diagnosis.forms)
    forms: tuple = FORM_EFFECTS
    #: base model: 'auto' (identify every one of BASE_MODELS, keep the lowest held-out MSE), or a kind
    base_model: str = "auto"
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.data.parametrization != "improved":
            raise ValueError(f"DiagnosisSettings: data.parametrization must be 'improved' (the local solver needs "
                             f"monotone tables), got {self.data.parametrization!r}; pass "
                             f"dataclasses.replace(data, parametrization='improved')")

    def to_dict(self) -> dict:
        """One flat record (the problem definition's fields beside the run's), ``extra`` left out."""
        run = {f.name: getattr(self, f.name) for f in fields(self) if f.name not in ("data", "extra")}
        return {**run, **self.data.to_dict()}
