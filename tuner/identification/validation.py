"""The one definition of the validation figures (the paper's Table 3, the diagnosis's before and after, the
residual floor): a model's force through the built FMU at its own default internal steps, band-limited as the
identification objective, and its error metrics. Units SI: forces [N]."""
from __future__ import annotations

import numpy as np

from tuner.identification.engine import Signals, simulate_signals
from tuner.metrics import error_metrics

__all__ = ["validation_run"]


def validation_run(model: str, params: dict, s: Signals, engine: str = "fmu") -> tuple[np.ndarray, dict]:
    """(simulated force [N] at the samples of ``s``, error metrics dict over its counted samples).

    Band-limited as the identification objective (``tuner.identification.engine.simulate_signals``), but through
    the built FMU (engine 'fmu') at its own default internal steps (error-controlled), i.e. the model the user
    gets. engine 'native' gives the same numbers without FMI (tests hold them equal).
    """
    sim = simulate_signals(model, params, s, engine=engine, max_internal_step=None, tolerance=None)
    return sim, error_metrics(s.force[s.mask], sim[s.mask]).to_dict()
