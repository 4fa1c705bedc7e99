"""Railway hydraulic damper models: the Python reference, the C kernel and the FMUs built from them.

SI units throughout. Sign convention: stroke x1 [m] positive in extension, stroke
velocity v1 [m/s] its time derivative, force [N] positive in tension. It imports nothing of the
tuner or the campaign.

- ``parameter_spec``: the record of one parameter (unit, default, bounds) and the rule its values are checked by;
- ``parameters``: parameter names, units, reference presets (paper Table 2) and bounds;
- ``effect_catalogue``: one record per effect element (parameters, typical ranges, scaling, search-bounds rule,
  residual signature, notes): everything an effect means outside its physics;
- ``tables``: piecewise-linear characteristics through the origin;
- ``models``: the model equations (lumped, Maxwell, table Maxwell, two-chamber), single source for all engines;
- ``effects``: the optional effect elements (the diagnosis's catalogue and the forms beyond it);
- ``solver_options``: the solver options record (largest internal step, tolerance, input mode) and its defaults;
- ``integrator``: L-stable SDIRK2 stepping with sub-steps, and the in-process ``simulate``;
- ``native``: the same in C (``c/damper_kernel.c``), compiled on first use, through ctypes;
- ``c_header``: the C names of the parameters' indices (``c/damper_index.h``), generated from ``parameters``;
- ``model_description``: the FMI 2.0 and 3.0 model descriptions, written from one variable list;
- ``fmu``: the FMUs (FMI 2.0, 3.0; native and pythonfmu), built, stamped and validated
  (``python build_fmu.py`` is their command line).

C sources in ``c/``: the kernel ``damper_kernel.c``, the FMI-independent ``fmu_common.c``, the FMI
wrappers ``fmi2_damper.c`` and ``fmi3_damper.c``, and the standard FMI headers ``fmi2/``, ``fmi3/``
with their ``ORIGIN``.
"""
from .integrator import EXTRAPOLATE, REPLAY, Simulator, SolverOptions, simulate
from .models import ConvergenceError, make_model
from .parameters import MODEL_PARAMETERS, defaults, tunable_names

__all__ = ["EXTRAPOLATE", "REPLAY", "Simulator", "SolverOptions", "simulate", "ConvergenceError", "make_model",
           "MODEL_PARAMETERS", "defaults", "tunable_names"]
