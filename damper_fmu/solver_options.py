"""How the damper models are integrated over a sampled stroke: the solver options record shared by the
Python reference (``integrator.simulate``) and the C kernel (``native.simulate``), with its defaults.

Input modes (what the stroke and velocity set before a communication step mean; ``integrator``'s
docstring says how each is interpolated): ``EXTRAPOLATE`` the values at the start of the step, as a
multibody master sets them; ``REPLAY`` the values at its end, as a known stroke history is replayed.
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["EXTRAPOLATE", "REPLAY", "DEFAULT_MAX_STEP", "DEFAULT_TOLERANCE", "SolverOptions"]

EXTRAPOLATE = 0
REPLAY = 1
#: Default largest internal step [s].
DEFAULT_MAX_STEP = 1e-3
#: Default local error tolerance of the internal steps, relative to the model's force scale.
DEFAULT_TOLERANCE = 1e-4


@dataclass(frozen=True)
class SolverOptions:
    """Internal stepping of a simulated stroke.

    max_step: largest internal step [s]; tolerance: local error tolerance of the internal steps,
    relative to the model's force scale (largest |Fc,O| ordinate) [-], 0 for fixed sub-steps of
    ``max_step``; input_mode: ``REPLAY`` (default: the samples are those at the end of each step) or
    ``EXTRAPOLATE`` (those at its start)."""

    max_step: float = DEFAULT_MAX_STEP
    tolerance: float = DEFAULT_TOLERANCE
    input_mode: int = REPLAY
