"""Confidence intervals of fitted parameters when the residuals are correlated.

A least-squares fit's textbook covariance sigma^2 (J^T J)^-1 assumes white residuals. The residual
of a damper fit is not white: model-form error is smooth in time and repeats at every velocity
reversal, so the textbook interval is far too narrow and would make any effect "significant".
``block_sandwich`` uses the sandwich (heteroscedasticity and autocorrelation consistent) estimate

    Cov = (J^T J)^+ [ sum over blocks b of (J_b^T r_b)(J_b^T r_b)^T ] (J^T J)^+

with contiguous blocks (within one test) several residual correlation times long: the analytic
counterpart of a residual block bootstrap. ``correlation_time`` (``tuner.metrics``, the one definition)
gives that time from the residual's autocorrelation.

Units: J [N per scaled unit], r [N]; covariances in scaled units^2 (the caller converts).

The functions live in ``tuner.metrics`` (the one definition, shared with the identified parameters'
intervals of ``tuner.identification.intervals``); they are re-exported here under their names.
"""
from __future__ import annotations

from tuner.metrics import Z95, block_sandwich, correlation_time, interval

__all__ = ["correlation_time", "block_sandwich", "interval", "Z95"]
