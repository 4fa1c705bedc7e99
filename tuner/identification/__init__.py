"""The identification: from the prepared tests to the identified parameters (SI units).

- ``problem``: the tests prepared once for every stage (``Problem``, ``DataSettings``);
- ``damper_scale``: the damper's force, stroke and velocity scale from its data, and every bound and fixed
  constant of the models mapped to it;
- ``parametrization``: the design variables of each model;
- ``runner``: the FMU through fmpy, with its C stepping loop (``c/fmi2_stepper.c``);
- ``engine``: simulation engines (FMU, C kernel, Python) and the worker pool;
- ``reference``: the converged ODE reference (scipy's LSODA);
- ``firefly``: the Firefly algorithm;
- ``search_window``: the start of each test the Firefly search runs on (its range covered twice);
- ``polish``: the local solver (projected Levenberg-Marquardt);
- ``restart_check``: whether a refined fit is the minimum or only its basin's (restarts from elsewhere);
- ``intervals``: 95 % intervals and identifiability flags of every identified parameter at the fit;
- ``parameter_draws``: parameter sets drawn from a fitted model's covariance (for the vehicle's intervals);
- ``rig_test_design``: the rig tests that would shrink the intervals of the parameters not determined;
- ``validation``: the one definition of the validation figures (the FMU at its own steps, error metrics);
- ``floor``: the residual floor (force noise and the stroke noise through the model) and when a fit is at it;
- ``fit``: identification and validation (``fit`` returns a ``FitResult``);
- ``best_point``: a fit continued from a lower point a later stage found (the diagnosis's base refit), so that
  the files and FMUs are those of the best point;
- ``full_rate``: the full-rate check of a decimated fit.
"""
