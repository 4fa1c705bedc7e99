"""Tuner: identification, validation, diagnosis and reports for damper models (SI units throughout).

One sub-package per stage:

- ``data``: rig files in, to SI units, checked, prepared at the fit rate;
- ``identification``: the Firefly search and the local refinement, validation through the FMU;
- ``diagnosis``: what the fitted model gets wrong, and why;
- ``vehicle``: the tuned FMUs as the yaw dampers of the campaign's vehicle;
- ``datasheet``: the damper's datasheet (force-velocity and dynamic characteristics) from an FMU and from sine tests;
- ``fleet``: a batch of dampers from a manifest, on a local pool or Dask;
- ``results``: the reports and the one recommendation of which model to use;
- ``cli``: the command line, one module per sub-command.

At the top:

- ``job``: the whole job (prepare -> fit -> choose the base -> diagnose -> export FMUs -> vehicle -> datasheet ->
  report);
- ``metrics``: the error metrics [N, N^2], in one place;
- ``formatting``: number formatting for people, in one place;
- ``time_budget``: where a run's minutes went (each stage's and section's seconds and share);
- ``strict_json``: strict JSON for every file written (non-finite values as ``null``);
- ``progress``: the one progress display over a whole job;
- ``worker_processes``: how the worker pools start (a fork server with the simulation modules loaded);
- ``executors``: where independent tasks run (a local process pool or Dask): the fleet's rows, the vehicle's draws;
- ``__main__``: the parser of ``python -m tuner``.

No import circle; modules import each other's public names by absolute path.
"""
from __future__ import annotations

import importlib

#: the library's public names -> the module that defines them. Imported on first use (PEP 562): the
#: stages import scipy, pandas and fmpy (1.7 s), and every worker process and ``python -m tuner --help``
#: imports this package first.
_EXPORTS = {
    # reading rig data (tuner.data.reading), its options (tuner.data.read_options) and its error
    # (damper_dataset.format)
    "RigTest": "tuner.data.reading", "load_tests": "tuner.data.reading", "load_test": "tuner.data.reading",
    "load_files": "tuner.data.reading", "load_dataset": "tuner.data.reading",
    "ReadOptions": "tuner.data.read_options", "read_column_mapping": "tuner.data.read_options",
    "DataError": "damper_dataset.format",
    # the identification problem, the fit and its result
    "Problem": "tuner.identification.problem", "DataSettings": "tuner.identification.problem",
    "FitSettings": "tuner.identification.fit", "FitResult": "tuner.identification.fit",
    "fit": "tuner.identification.fit", "validation_run": "tuner.identification.fit",
    "quality_gate": "tuner.identification.fit",
    # the diagnosis
    "Diagnosis": "tuner.diagnosis.result", "DiagnosisSettings": "tuner.diagnosis.diagnose",
    "DiagnosisFailed": "tuner.diagnosis.result",
    "diagnose": "tuner.diagnosis.diagnose", "choose_base": "tuner.diagnosis.diagnose",
    "FittedBases": "tuner.diagnosis.bases",
    # the whole job, as the command line runs it
    "run": "tuner.job", "run_diagnosis": "tuner.job", "JobResult": "tuner.job", "JobOptions": "tuner.job",
    "export_fmus": "tuner.job",
    "write_diagnosis": "tuner.job", "diagnosis_settings": "tuner.job", "vehicle_consequences": "tuner.job",
    # the report and the recommendation of an output folder
    "make_report": "tuner.results.report", "recommend": "tuner.results.recommendation",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    """``tuner.<name>`` for a public name: imported from its module on first use, then cached here."""
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'tuner' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted({*globals(), *_EXPORTS})
