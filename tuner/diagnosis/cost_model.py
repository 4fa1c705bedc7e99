"""The expected simulations of each step of a diagnosis on one base form: what the progress display's time
left is made of (``tuner.progress``: the job's stage then says its seconds left instead of a share of a plan
measured on other data).

Counted in simulations of the identification tests (a held-out run counts by its share of the samples), from the
same settings the steps use (``tuner.diagnosis.search``): a Jacobian of a model of ``d``
coordinates is d + 1 simulations; a candidate's refit is its profile (``grid_points`` values, each re-balanced by
up to ``profile_steps`` batches: half of them on average, measured) and a joint polish of
``JOINT_POLISH_JACOBIANS`` Jacobians (its cap ``polish_jacobians / 2``); the screen is one batch of
``grid_points`` values per candidate; the forms screen their shapes (``tuner.diagnosis.forms.shape_grid``) and
refit one shape; the detection limits take the Jacobian on both test sets, each candidate switched off once and at
up to three magnitudes on each. Once the candidates are ranked (``after_ranking``), what a leading candidate
brings follows: its continuation and the base's (``CONTINUATION_JACOBIANS`` each), an interval (one Jacobian) per
candidate that scores, the forward selection (each other scoring candidate refitted on top of the first, the best
continued), and the forms twice (weighed with the cause on the base, then on top of the causes) when the base
leaves a residual above the floor, each pass with the best form's continuation. Unknown before the step that
decides it (how many candidates the screen passes, whether the forms run), the count assumes ``EXPECTED_REFITS``
refits, no cause, and forms that run when the base leaves a residual above the floor; the search replaces each
assumption by what happened as it goes, so the estimate is a forecast that is corrected at every step, never a
share that stays at "100 %".
"""
from __future__ import annotations

from dataclasses import dataclass

from tuner.diagnosis.forms import shape_grid
from tuner.diagnosis.held_profiles import HELD_PROFILE_JACOBIANS, SERIES_HELD_JACOBIANS

__all__ = ["EXPECTED_REFITS", "JOINT_POLISH_JACOBIANS", "CONTINUATION_JACOBIANS", "REFINEMENT_JACOBIANS",
           "EXTENDED_COST", "DiagnosisCost",
           "shapes", "refit_cost", "form_pass_cost", "expected_cost", "after_ranking", "identification_cost"]

#: catalogue candidates refitted after the screen, assumed before it (measured: 0 on clean virtual-rig data, 2 on the
#: real MR damper and on the bundled data, 1 where an effect is hidden)
EXPECTED_REFITS = 2
#: Jacobians a continuation (``final_jacobians`` cap) takes until its rule holds, assumed (measured on blind free
#: plays: 4-5 on the lumped base, 6-7 on the two-chamber base)
CONTINUATION_JACOBIANS = 5
#: Jacobians a refit's joint polish takes after its profile, assumed (measured on the bundled data, clean: 1-2; on
#: virtual-rig data with a friction hidden: 4-5; its cap is half the refit's budget, 8, which the forecast counted
#: before: a clean diagnosis forecast at 2.4 x its time)
JOINT_POLISH_JACOBIANS = 4
#: Jacobians a base identification's local refinement takes from one start until it converges, assumed (measured
#: on held-out-sized data, six 12-16 s tests: 9-12)
REFINEMENT_JACOBIANS = 12
#: wall time per simulation in a diagnosis over that of its base's identification (measured on held-out-sized
#: data: 1.6 on the lumped base, 1.9 on the two-chamber base; the effects' elements, a free play's contact above
#: all, take the integrator's smaller steps)
EXTENDED_COST = 1.8


@dataclass
class DiagnosisCost:
    """Expected simulations [identification-test equivalents] of the steps of one diagnosis still to come;
    ``total`` their sum. Each field is replaced by 0 once its step is done (``done``)."""

    reference: float  # the base refitted alike ('none'), its Jacobian
    screen: float
    refits: float
    forms: float  # every pass of the forms still to come
    detection: float
    continuation: float = 0.0  # the leading candidate's and the base's continuation
    intervals: float = 0.0  # the intervals of the candidates that score
    selection: float = 0.0  # the forward selection on top of the first cause

    @property
    def total(self) -> float:
        return (self.reference + self.screen + self.refits + self.forms + self.detection + self.continuation
                + self.intervals + self.selection)

    def done(self, step: str) -> None:
        """Step ``step`` (a field name) is finished: nothing of it is left."""
        setattr(self, step, 0.0)


def shapes(form: str) -> int:
    """Shapes the screen of ``form`` simulates (``tuner.diagnosis.forms.shape_grid``, with a fade: its count
    depends on neither the bounds nor the knee's value)."""
    bounds = {"hysteresis_displacement": (1e-5, 1e-3), "bypass_center": (-0.01, 0.01), "bypass_width": (2e-3, 8e-3)}
    return len(shape_grid(form, bounds, knee_m_s=0.1))


def _joint_polish(settings) -> int:
    """Jacobians a joint polish is counted at: JOINT_POLISH_JACOBIANS, within its cap (half the refit's budget)."""
    return min(JOINT_POLISH_JACOBIANS, max(1, settings.polish_jacobians // 2))


def refit_cost(d: int, extra: int, settings, nonsmooth: bool = False) -> float:
    """Simulations of one candidate's refit: the profile and the joint polish of a model of d base and
    ``extra`` effect coordinates; a ``nonsmooth`` effect's held profile besides (``tuner.diagnosis.
    held_profiles.held_profile``: as many values as the grid has, measured 7-9 on blind free plays, each its Jacobians with
    two trial steps)."""
    profile = settings.grid_points * (1 + settings.profile_steps / 2)
    held = settings.grid_points * HELD_PROFILE_JACOBIANS * (d + extra + 3) if nonsmooth else 0.0
    return profile + held + _joint_polish(settings) * (d + extra + 1)


def series_cost(d: int, settings, held: int, coarse_share: float = 1.0) -> float:
    """Simulations of ``tuner.diagnosis.held_profiles.series_profiles`` with the series element held at ``held``
    values and the joint polish after: per held value, the coarse pass (the grid's values, each SERIES_HELD_JACOBIANS
    Jacobians, counted at d + 1 simulations: an upper bound, as the series element and the magnitude are held; each
    ``coarse_share`` of a simulation of the tests: the search's windows' samples per sample) and the chained sweep
    from its release (about the grid's values again, HELD_PROFILE_JACOBIANS each)."""
    per_value = coarse_share * SERIES_HELD_JACOBIANS * (d + 1) + HELD_PROFILE_JACOBIANS * (d + 3)
    return held * settings.grid_points * per_value + _joint_polish(settings) * (d + 2)


def form_pass_cost(d: int, settings) -> float:
    """Simulations of one pass of the forms on a model of d coordinates: the current model's Jacobian, every
    form's shape screen, one shape refitted, the best form continued."""
    screen = d + 1 + sum(shapes(f) for f in settings.forms)
    return screen + refit_cost(d, 3, settings) + CONTINUATION_JACOBIANS * (d + 4)


def expected_cost(d: int, settings, *, settled: bool, forms_run: bool, held_out_share: float,
                  refits: int = EXPECTED_REFITS) -> DiagnosisCost:
    """The cost of a whole diagnosis on a base of d coordinates (``DiagnosisSettings`` ``settings``):
    ``settled``: its refinement converged on these tests (no 'none' refit); ``forms_run``: the base leaves a
    residual above the floor; ``held_out_share``: held-out samples per identification sample."""
    n = len(settings.candidates)
    jac = d + 1
    reference = jac if settled else jac + max(1, settings.polish_jacobians // 2) * (jac + 2)
    screen = n * settings.grid_points + (0 if settled else jac)
    forms = form_pass_cost(d, settings) if forms_run and settings.forms else 0.0
    detection = jac * (1 + held_out_share) + 4 * n * (1 + held_out_share)  # each effect off, then at 3 magnitudes
    return DiagnosisCost(float(reference), float(screen), float(refits * refit_cost(d, 1, settings)), float(forms),
                         float(detection))


def after_ranking(cost: DiagnosisCost, d: int, settings, *, scoring: int, forms_run: bool) -> None:
    """``cost`` once the candidates are ranked (module docstring): ``scoring`` candidates score above the
    acceptance line with a resolved force (the first of them leads); ``forms_run``: the base leaves a residual
    above the floor."""
    cost.continuation = 2.0 * CONTINUATION_JACOBIANS * (d + 2) if scoring and settings.final_jacobians > 0 else 0.0
    cost.intervals = float(scoring * (d + 2))
    others = max(0, min(scoring, settings.max_causes) - 1)
    cost.selection = float(others * refit_cost(d, 2, settings)
                           + (CONTINUATION_JACOBIANS * (d + 3) + d + 3 if others else 0))
    passes = (2 if scoring else 1) if forms_run and settings.forms else 0
    cost.forms = passes * form_pass_cost(d, settings)


def identification_cost(d: int, starts: int, iterations: int, population: int) -> float:
    """Simulations of a base identification of d coordinates (``tuner.identification.fit.identify``): the Firefly
    search's first population and ``iterations`` more of ``population`` each (at most: it stops early once at the
    data's resolution) and ``starts`` local refinements of REFINEMENT_JACOBIANS Jacobians of d + 1 simulations
    each."""
    return float((iterations + 1) * population + starts * REFINEMENT_JACOBIANS * (d + 1))
