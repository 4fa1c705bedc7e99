"""The settings of a diagnosis run and its candidate causes."""
from __future__ import annotations

from dataclasses import dataclass, field

from damper_fmu.parameters import CATALOGUE_EFFECTS, FK_REFERENCE_STIFFNESS, FORM_EFFECTS

from tuner.identification.problem import DataSettings

__all__ = ["CANDIDATES", "DiagnosisSettings"]

#: the candidate causes: the effect catalogue of the design notes (parameters.CATALOGUE_EFFECTS); the forms
#: beyond it (parameters.FORM_EFFECTS) are tried after them, when a residual above the floor remains
CANDIDATES = CATALOGUE_EFFECTS


@dataclass
class DiagnosisSettings:
    """Settings of a diagnosis run (units in the names)."""

    fit_rate_hz: float = 200.0
    warmup_s: float = 0.5
    workers: int = 2
    engine: str = "fmu"
    seed: int = 0
    base_iterations: int = 30
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
    diff_band_hz: float | None = None  # as tuner.identification.problem.DataSettings
    damping_abscissae_m_s: tuple | None = None  # as DataSettings (without a base fit given)
    elastic_abscissae_m: tuple | None = None
    force_limit_n: float | None = None  # as DataSettings
    spring_reference_n_per_m: float = FK_REFERENCE_STIFFNESS  # as DataSettings
    extra: dict = field(default_factory=dict)

    def data(self) -> DataSettings:
        """The problem definition when the diagnosis prepares the tests itself (no fit's problem given);
        the parametrization is always 'improved' (the local solver needs monotone tables)."""
        return DataSettings(fit_rate_hz=self.fit_rate_hz, warmup_s=self.warmup_s, diff_band_hz=self.diff_band_hz,
                            damping_abscissae_m_s=self.damping_abscissae_m_s,
                            elastic_abscissae_m=self.elastic_abscissae_m, force_limit_n=self.force_limit_n,
                            spring_reference_n_per_m=self.spring_reference_n_per_m, parametrization="improved")
