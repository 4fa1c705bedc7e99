"""Is the grid the diagnosis simulated on fine enough for the model it ended with?

The identification simulates on fixed sub-steps (``DataSettings.sim_step_s``, 1 ms by default) so that the
objective is smooth in the parameters. That grid integrates a smooth damper to a fraction of a newton, but a free
play closing on stiff silent blocks only to tens of newtons (``tests/test_sim_step.py``). An integration error
above the force noise is a systematic residual the search can explain with a false cause (an inertia at the
contact frequency) or a biased one (a friction beside the play): docs/identification.md. Whether the grid is
fine enough depends on the model found, not on the base (which has no gap), so it is checked on the final model:
its force on the identification tests on the grid used and on one ``GRID_REFINEMENT`` times finer; when the two
differ by more than ``GRID_ERROR_SHARE`` x the force noise, the diagnosis is run again on the finer grid
(``tuner.diagnosis.diagnose``). SI units; forces in N."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from tuner.identification.engine import simulate_signals
from tuner.identification.problem import DataSettings, Problem

__all__ = ["GRID_REFINEMENT", "GRID_ERROR_SHARE", "GRID_PART", "GridCheck", "grid_check"]

#: the finer grid is this many times finer than the one checked
GRID_REFINEMENT = 4
#: the grid is too coarse when the force moves by more than this share of the force noise [rms] on the finer grid:
#: a smooth damper moves by well under 1 % of the noise at 1 ms, a free play in impact-like contact by 1-5 x it
GRID_ERROR_SHARE = 0.5
#: the part of the diagnosis's progress plan that runs it again on the finer grid
GRID_PART = "diagnosis on a finer grid"


@dataclass(frozen=True)
class GridCheck:
    """The final model's force on the grid the diagnosis used and on a finer one: ``step_s`` and ``finer_step_s``
    [s]; ``change_n``, the rms of the difference over the counted samples of the identification tests [N] (an
    estimate of the integration error on ``step_s``: on a first-order method, 3/4 of it); ``noise_n``, the force
    noise [N rms] it is weighed against; ``cost_ratio``, the time a simulation on the finer grid took over one on
    ``step_s`` (what a diagnosis on the finer grid costs more); ``noise_credible``, whether the noise estimate is
    credible (``tuner.data.noise``): one that is not (filtered data) judges nothing, as for the residual floor."""

    step_s: float
    finer_step_s: float
    change_n: float
    noise_n: float
    cost_ratio: float = 1.0
    noise_credible: bool = True

    @property
    def too_coarse(self) -> bool:
        """The force moves by more than ``GRID_ERROR_SHARE`` x the noise on the finer grid (False when the noise
        estimate is not credible or zero)."""
        return self.noise_credible and self.noise_n > 0.0 and not self.change_n <= GRID_ERROR_SHARE * self.noise_n

    def to_dict(self) -> dict:
        """The record of ``diagnosis.json`` (units in the names)."""
        return {"step_s": self.step_s, "finer_step_s": self.finer_step_s, "change_n": self.change_n,
                "noise_n": self.noise_n, "noise_credible": self.noise_credible, "share_allowed": GRID_ERROR_SHARE,
                "too_coarse": self.too_coarse, "cost_ratio": self.cost_ratio}

    def text(self) -> str:
        """One sentence for the log and the verdict."""
        return (f"the final model's force moves by {self.change_n:.3g} N rms between a {1e3 * self.step_s:g} ms and a "
                f"{1e3 * self.finer_step_s:g} ms grid ({self.change_n / self.noise_n:.2g} x the force noise)"
                if self.noise_credible and self.noise_n > 0.0 else
                f"the final model's force moves by {self.change_n:.3g} N rms between a {1e3 * self.step_s:g} ms and "
                f"a {1e3 * self.finer_step_s:g} ms grid (not judged: the force noise estimate is not credible)")


def grid_check(kind: str, values: dict, problem: Problem, engine: str) -> GridCheck:
    """The force of model ``kind`` at ``values`` [SI] on ``problem``'s identification tests, simulated as the
    identification does (fixed sub-steps, band-limited to the fit rate) on its grid and on one
    ``GRID_REFINEMENT`` times finer (``Problem.on_grid``), compared over the counted samples."""
    step = problem.settings.sim_step_s
    finer = problem.on_grid(step / GRID_REFINEMENT)
    t0 = time.perf_counter()
    coarse = [_force(kind, values, s, engine, problem.settings) for s in problem.sig_id]
    t1 = time.perf_counter()
    fine = [_force(kind, values, f, engine, finer.settings) for f in finer.sig_id]
    t2 = time.perf_counter()
    d = np.concatenate([(c - f)[s.mask] for c, f, s in zip(coarse, fine, problem.sig_id)])
    return GridCheck(step, finer.settings.sim_step_s, float(math.sqrt(np.mean(d * d))), float(problem.noise_n),
                     (t2 - t1) / max(t1 - t0, 1e-9), bool(problem.noise.get("credible", True)))


def _force(kind: str, values: dict, s, engine: str, data: DataSettings) -> np.ndarray:
    """The identification's force [N] at the samples of ``s``: fixed sub-steps of at most ``data.internal_step_s``
    (the grid's intervals when the signals are oversampled to it)."""
    return simulate_signals(kind, values, s, engine=engine, max_internal_step=data.internal_step_s, tolerance=0.0)
