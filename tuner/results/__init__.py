"""Results for people: the reports and the one recommendation.

- ``recommendation``: which model and FMU to use, and why (one decision, read from the output folder);
- ``report``: the HTML report of a fit output folder;
- ``fit_folder``: what the report reads (``FitFolder``);
- ``fit_figures``: the fit report's figures (the paper's Figs. 6-11 and the loops);
- ``report_figures``: the fit report's figures drawn in one go, in worker processes when the job has them;
- ``intervals_report``: the identified parameters' intervals and flags (tables, characteristics with bands);
- ``diagnosis_report``: the diagnosis section, and the report of a diagnosis on its own;
- ``diagnosis_figures``: the diagnosis's figures (the base model's residual), drawn from a ``Diagnosis``;
- ``vehicle_report``: the vehicle section (the tuned FMUs in the vehicle, side by side, and their intervals);
- ``design_report``: the test design section (the rig tests that would pin down the rest);
- ``datasheet_report``: the datasheet section (force-velocity table, figures, measured points, nominal band);
- ``datasheet_figures``: the datasheet's figures (force-velocity, K' and K'' per amplitude, loss angle);
- ``html``: HTML building blocks (tables, figures, numbers, the page);
- ``figure_layout``: the figures' margins, fixed in inches (in place of matplotlib's constrained layout);
- ``fleet_summary``: the fleet summary of a batch (table, outliers, characteristics).
"""
