"""Tuner: identification, validation, diagnosis and reports for damper models (SI units throughout).

One sub-package per stage:

- ``data``: rig files in, to SI units, checked, prepared at the fit rate;
- ``identification``: the Firefly search and the local refinement, validation through the FMU;
- ``diagnosis``: what the fitted model gets wrong, and why;
- ``vehicle``: the tuned FMUs as the yaw dampers of the campaign's vehicle;
- ``fleet``: a batch of dampers from a manifest, on a local pool or Dask;
- ``results``: the reports and the one recommendation of which model to use;
- ``cli``: the command line, one module per sub-command.

At the top:

- ``job``: the whole job (prepare -> fit -> choose the base -> diagnose -> export FMUs -> vehicle -> report);
- ``metrics``: the error metrics [N, N^2], in one place;
- ``formatting``: number formatting for people, in one place;
- ``strict_json``: strict JSON for every file written (non-finite values as ``null``);
- ``progress``: the one progress display over a whole job;
- ``__main__``: the parser of ``python -m tuner``.

No import circle; modules import each other's public names by absolute path.
"""
