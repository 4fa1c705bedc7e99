"""The record of one model parameter (``Parameter``) and the rule its values are checked by.

Every parameter carries its SI unit, a description, the reference (default) value and the
identification bounds. The model parameter sets (``damper_fmu.parameters``) and the effect
elements of the catalogue (``damper_fmu.effect_catalogue``) are made of these records.
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Parameter", "check_rule"]


@dataclass(frozen=True)
class Parameter:
    """One model parameter.

    ``tunable``: identified by the base fit (else a fixed setting such as a table abscissa).
    ``log_scale``: the bounds span decades; a tuner should search this parameter in log space.
    ``effect``: name of the optional effect element the parameter belongs to (off at its default).
    ``check``: 'positive', 'nonnegative' or 'range' (within [low, high]) whatever the unit; None: the rule of
    ``check_rule`` (effects in range, masses/stiffnesses/dampings and log-scaled values positive).
    """

    name: str
    unit: str
    description: str
    default: float
    low: float
    high: float
    tunable: bool = True
    log_scale: bool = False
    effect: str | None = None
    check: str | None = None


def check_rule(p: Parameter) -> str:
    """How a value of ``p`` is checked before any run: 'range' (within [low, high]), 'positive', 'nonnegative'
    or 'none'. One rule for ``damper_fmu.parameters.check_values`` and the C kernel (``native.parameter_header``)."""
    if p.check is not None:
        return p.check
    if p.effect is not None:
        return "range"
    if p.unit in ("kg", "N/m", "N.s/m") or p.log_scale:
        return "positive"
    return "none"
