"""What the fitted model gets wrong and why (SI units; forces in N).

- ``diagnose``: the procedure (base form, candidates, forward selection, forms, verdict; ``diagnose``);
- ``residuals``: the base model's residual as evidence (signatures, loops, spectra) and its figures;
- ``screen``: one batch that predicts what each candidate's refit could win (its profile over the magnitude);
- ``refit``: refits of a base model extended by effect elements, and their intervals;
- ``forms``: the forms beyond the catalogue (pre-yield hysteresis, bypass groove) and their shape screen;
- ``significance``: block-sandwich statistics for correlated residuals;
- ``effect_sizes``: typical and meaningful effect magnitudes scaled to the damper;
- ``detection``: the smallest magnitude of each effect these tests could have named.
"""
