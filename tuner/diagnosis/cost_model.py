"""The expected simulations of each step of a diagnosis on one base form: what the progress display's time
left is made of (``tuner.progress``: the job's stage then says its seconds left instead of a share of a plan
measured on other data).

Counted in simulations of the identification tests (a held-out run counts by its share of the samples), from
the same settings the steps use (``tuner.diagnosis.search.CandidateSearch``): a Jacobian of a model of ``d``
coordinates is d + 1 simulations; a candidate's refit is its profile (``grid_points`` values, each re-balanced
by up to ``profile_steps`` batches: half of them on average, measured) and a joint polish of at most
``polish_jacobians / 2`` Jacobians; the screen is one batch of ``grid_points`` values per candidate; the
forms screen their shapes (``tuner.diagnosis.forms.shape_grid``) and refit one shape; the detection limits
take the Jacobian on both test sets and up to three signatures per candidate on each. Unknown before the step
that decides it (how many candidates the screen passes, whether the forms run), the count assumes
``EXPECTED_REFITS`` refits and forms that run when the base leaves a residual above the floor; the search
replaces each assumption by what happened as it goes, so the estimate is a forecast that is corrected at
every step, never a share that stays at "100 %".
"""
from __future__ import annotations

from dataclasses import dataclass

from tuner.diagnosis.forms import shape_grid

__all__ = ["EXPECTED_REFITS", "DiagnosisCost", "shapes", "refit_cost", "expected_cost"]

#: catalogue candidates refitted after the screen, assumed before it (measured: 0 on clean data, 2 on the
#: real MR damper, 1 where an effect is hidden)
EXPECTED_REFITS = 2


@dataclass
class DiagnosisCost:
    """Expected simulations [identification-test equivalents] of the steps of one diagnosis still to come;
    ``total`` their sum. Each field is replaced by 0 once its step is done (``done``)."""

    reference: float  # the base refitted alike ('none'), its Jacobian
    screen: float
    refits: float
    forms: float
    detection: float

    @property
    def total(self) -> float:
        return self.reference + self.screen + self.refits + self.forms + self.detection

    def done(self, step: str) -> None:
        """Step ``step`` (a field name) is finished: nothing of it is left."""
        setattr(self, step, 0.0)


def shapes(form: str) -> int:
    """Shapes the screen of ``form`` simulates (``tuner.diagnosis.forms.shape_grid``, with a fade: its count
    depends on neither the bounds nor the knee's value)."""
    bounds = {"hysteresis_displacement": (1e-5, 1e-3), "bypass_center": (-0.01, 0.01), "bypass_width": (2e-3, 8e-3)}
    return len(shape_grid(form, bounds, knee_m_s=0.1))


def refit_cost(d: int, extra: int, settings) -> float:
    """Simulations of one candidate's refit: the profile and the joint polish of a model of d base and
    ``extra`` effect coordinates."""
    profile = settings.grid_points * (1 + settings.profile_steps / 2)
    return profile + max(1, settings.polish_jacobians // 2) * (d + extra + 1)


def expected_cost(d: int, settings, *, settled: bool, forms_run: bool, held_out_share: float,
                  refits: int = EXPECTED_REFITS) -> DiagnosisCost:
    """The cost of a whole diagnosis on a base of d coordinates (``DiagnosisSettings`` ``settings``):
    ``settled``: its refinement converged on these tests (no 'none' refit); ``forms_run``: the base leaves a
    residual above the floor; ``held_out_share``: held-out samples per identification sample."""
    n = len(settings.candidates)
    jac = d + 1
    reference = jac if settled else jac + max(1, settings.polish_jacobians // 2) * (jac + 2)
    screen = n * settings.grid_points + (0 if settled else jac)
    forms = 0.0
    if forms_run:
        forms = jac + sum(shapes(f) for f in settings.forms) + refit_cost(d, 3, settings)
    detection = jac * (1 + held_out_share) + 6 * n * (1 + held_out_share)
    return DiagnosisCost(float(reference), float(screen), float(refits * refit_cost(d, 1, settings)), float(forms),
                         float(detection))
