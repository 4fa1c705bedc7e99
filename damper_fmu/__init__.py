"""Railway hydraulic damper models as plain Python (no FMI here).

SI units throughout. Sign convention: stroke x1 [m] positive in extension, stroke
velocity v1 [m/s] its time derivative, force [N] positive in tension.

- ``parameters``: parameter names, units, reference presets (paper Table 2) and bounds;
- ``tables``: piecewise-linear characteristics through the origin;
- ``models``: the model equations (lumped, Maxwell, table Maxwell), single source for all engines;
- ``integrator``: L-stable SDIRK2 stepping with sub-steps, and the in-process ``simulate``.
"""
from .integrator import EXTRAPOLATE, REPLAY, Simulator, simulate
from .models import ConvergenceError, make_model
from .parameters import MODEL_PARAMETERS, defaults, tunable_names

__all__ = ["EXTRAPOLATE", "REPLAY", "Simulator", "simulate", "ConvergenceError", "make_model",
           "MODEL_PARAMETERS", "defaults", "tunable_names"]
