"""What the fitted model gets wrong and why (SI units; forces in N).

- ``diagnose``: the procedure's entry (``diagnose``): stages, checkpoints; returns a ``Diagnosis``, writes no output;
- ``result``: the result of a diagnosis (``Diagnosis``: the causes, the verdict, the record of ``diagnosis.json``, the
  final values and residual series the job writes from) and of a failed stage (``DiagnosisFailed``, its record);
- ``settings``: the settings of a diagnosis run (``DiagnosisSettings``) and its candidate causes;
- ``bases``: the base forms: which, their identification, the choice by held-out MSE, the repeat rule;
- ``search``: the diagnosis on one base form (a package: one module per step of the procedure, sharing one
  record, ``search.state.SearchState``);
- ``rules``: the decision rules, pure functions of ranking rows (score, decide, cross-check, bounds);
- ``verdict``: the verdict's words and the records of causes and of what stays unexplained;
- ``residuals``: the base model's residual as evidence (signatures, loops, spectra) and its figures' file names;
- ``residual_tests``: one test's residual and its derived signals (acceleration, dF/dt, reversals);
- ``residual_signatures``: each catalogue effect's signature fitted to the residual, alone and all at once;
- ``residual_map``: where the residual lives on the restoring-force plane;
- ``screen``: one batch that predicts what each candidate's refit could win (its profile over the magnitude);
- ``refit``: refits of a base model extended by effect elements, and their intervals;
- ``extended_parametrization``: the base design vector extended by effect parameters, the line search's grid, the
  base Jacobian;
- ``held_profiles``: a nonsmooth effect's magnitude profiled with the model re-fitted at each value;
- ``forms``: the forms beyond the catalogue (pre-yield hysteresis, bypass groove) and their shape screen;
- ``significance``: block-sandwich statistics for correlated residuals;
- ``effect_sizes``: typical and meaningful effect magnitudes scaled to the damper;
- ``detection``: the smallest magnitude of each effect these tests could have named;
- ``grid_check``: whether the simulation grid is fine enough for the final model (its force on a 4 x finer grid);
- ``cost_model``: the expected simulations of each step still to come (the progress display's time left).
"""
