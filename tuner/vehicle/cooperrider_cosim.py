"""The Cooperrider car on tabulated S1002/UIC60 contact (:mod:`campaign.cooperrider`) as co-simulation master
of four yaw damper FMUs per car, several speeds at once.

The FMUs replace the car's yaw dampers, the longitudinal secondary dashpots ``D6`` (one each side of each
bogie, between the bogie frame and the car body at 1.5 m from the centre line, see
:func:`campaign.cooperrider.build_links`): ``D6`` is set to zero and each FMU's force acts where its dashpot
acted. The secondary longitudinal spring ``k6`` in parallel stays as it is; any series stiffness is the
FMU's own (the Maxwell FMU's ``k_s``, the lumped model's silent blocks).

Signs (those of the FMUs, ``damper_fmu.parameters``, and of :mod:`tuner.vehicle.cosim`): ``stroke`` [m]
the elongation, positive in extension (the bogie's and the car body's attachment points moving apart
along the track), ``stroke_velocity`` [m/s] its rate, ``force`` [N] positive in tension (pulling the two
points together).

Coupling, as :mod:`tuner.vehicle.nonlinear_cosim` does it, communication step ``h`` (default 0.5 ms, the step
of the car's Runge-Kutta integration in the DYTSI benchmark; 1 ms works, with four times the coupling
error), at ``t_k = k h``:

1. each FMU gets the elongation and its rate at ``t_k`` and, where it interpolates its inputs
   (``canInterpolateInputs``), the elongation's acceleration at ``t_k`` from the car's equations with the
   forces at ``t_k``;
2. ``fmi2DoStep(t_k, h)``; the force at ``t_{k+1}`` is read;
3. the car advances over ``[t_k, t_{k+1}]`` by ``substeps`` classical Runge-Kutta steps (default 1) with
   each damper force linear between its values at ``t_k`` and ``t_{k+1}`` (the stages see the force at
   their own times).

With a Maxwell FMU made a pure dashpot equal to ``D6`` (series stiffness 1e11 N/m) the co-simulated car
follows the built-in one to second order in ``h`` (``tests/test_cooperrider_cosim.py``).

A batch of ``m`` speeds is one ``(66, m)`` car (one column per speed) with ``4 m`` FMU instances (four per
speed). A speed whose wheelsets leave ``abort`` [m] laterally is dropped from the batch (its states are
NaN from then on, ``stopped_at`` its time): its response grows, and the contact table ends at the flange.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from campaign.contact_table import ContactTable
from campaign.cooperrider import N_STATES, YAW_DAMPER_NAMES, CooperriderCar, state_index
from campaign.cooperrider_params import CooperriderParams
from campaign.cooperrider_runs import CarRun
from tuner.vehicle.cosim import DamperInstance, check_damper_fmu, rk4_linear_forces

__all__ = ["CooperriderCosim", "DamperCarRun", "DEFAULT_COMM_STEP", "DEFAULT_SUBSTEPS", "DEFAULT_ABORT", "WHEELSET_Y"]

DEFAULT_COMM_STEP = 5e-4
"""Communication step [s] (RK4 of the car stable from about 25 m/s up at this step)."""
DEFAULT_SUBSTEPS = 1
"""Runge-Kutta steps of the car per communication step."""
DEFAULT_ABORT = 5e-3
"""Lateral displacement [m] of any wheelset beyond which a speed's run stops (response grown 50-fold from
the 0.1 mm offset; the flange starts at 7.5 mm, the table ends beyond it)."""
WHEELSET_Y = np.array([state_index(b, "y") for b in range(3, 7)])
"""State indices of the four wheelsets' lateral displacements."""


@dataclass(frozen=True)
class DamperCarRun(CarRun):
    """A :class:`campaign.cooperrider_runs.CarRun` of the car with damper FMUs: also ``forces`` (nt, 4, m)
    [N] the yaw damper forces (tension positive, :data:`campaign.cooperrider.YAW_DAMPER_NAMES` order) and
    ``stopped_at`` (m,) [s] the time a speed's run stopped at the abort limit (NaN: ran to the end; states
    and forces are NaN after it)."""

    forces: np.ndarray
    stopped_at: np.ndarray


class CooperriderCosim:
    """The Cooperrider car (``params``, contact ``table``) with an FMU as each of its four yaw dampers.

    ``fmu``: path of a damper FMU (inputs ``stroke`` [m], ``stroke_velocity`` [m/s], output ``force`` [N]), or
    None for the car's own ``D6`` dashpots (the same loop without FMUs: the reference row).
    ``fmu_parameters``: FMU parameter name -> SI value applied to every instance before each run. ``step``
    [s] the communication step, ``substeps`` Runge-Kutta steps per communication step. Use as a context
    manager or call :meth:`close`."""

    def __init__(self, fmu, params: CooperriderParams, table: ContactTable, *, step: float = DEFAULT_COMM_STEP,
                 substeps: int = DEFAULT_SUBSTEPS, fmu_parameters: dict | None = None):
        if not (math.isfinite(step) and 0.0 < step <= 2e-3):
            raise ValueError(f"communication step must be in (0, 2 ms], got {step} s")
        if not (isinstance(substeps, int) and substeps >= 1):
            raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")
        self.fmu = None if fmu is None else Path(fmu)
        if self.fmu is not None:
            check_damper_fmu(self.fmu)
        self.params = params if self.fmu is None else params.with_values(D6=0.0)
        self.table = table
        self.step, self.substeps = float(step), substeps
        self.fmu_parameters = dict(fmu_parameters or {})
        self._pool: list[DamperInstance] = []

    def _instances(self, m: int) -> list[list[DamperInstance]]:
        """Four FMU instances per speed ((m, 4), created once and reused across runs)."""
        while len(self._pool) < 4 * m:
            k = len(self._pool)
            self._pool.append(DamperInstance(self.fmu, f"{YAW_DAMPER_NAMES[k % 4]}_{k // 4}", self.fmu_parameters))
        return [self._pool[4 * j:4 * j + 4] for j in range(m)]

    def run(self, speeds, x0: np.ndarray, t_end: float, *, store: float = 0.01,
            abort: float = DEFAULT_ABORT) -> DamperCarRun:
        """Run at each of ``speeds`` [m/s] from ``x0`` (66,) or (66, m) for ``t_end`` [s], storing every
        ``store`` [s] (a multiple of the communication step); a speed stops once a wheelset's lateral
        displacement exceeds ``abort`` [m] (checked every communication step). FMUs start afresh at the
        elongations and rates of ``x0``."""
        speeds = np.atleast_1d(np.asarray(speeds, dtype=float))
        x = np.array(x0, dtype=float)
        x = np.repeat(x[:, None], speeds.size, axis=1) if x.ndim == 1 else x
        if x.shape != (N_STATES, speeds.size) or not np.all(np.isfinite(x)):
            raise ValueError(f"x0 must be finite with shape (66,) or (66, {speeds.size}), got {x.shape}")
        every = int(round(store / self.step))
        if every < 1 or abs(every * self.step - store) > 1e-9 * store:
            raise ValueError(f"store={store} s must be a multiple of the communication step {self.step} s")
        n_out = int(round(t_end / store))
        m = speeds.size
        states = np.full((n_out + 1, N_STATES, m), np.nan)
        forces = np.full((n_out + 1, 4, m), np.nan)
        stopped = np.full(m, np.nan)
        cols = np.arange(m)
        car = CooperriderCar(self.params, self.table, speeds)
        dampers = self._instances(m) if self.fmu is not None else None
        F = self._start(car, x, dampers)
        states[0], forces[0] = x, F
        for step in range(n_out * every):
            x, F = self._exchange(car, x, F, step * self.step, dampers)
            out = np.max(np.abs(x[WHEELSET_Y]), axis=0) > abort
            if np.any(out):
                stopped[cols[out]] = (step + 1) * self.step
                cols, x, F = cols[~out], x[:, ~out], F[:, ~out]
                if not cols.size:
                    break
                car = CooperriderCar(self.params, self.table, speeds[cols])
                dampers = None if dampers is None else [d for d, gone in zip(dampers, out) if not gone]
            if (step + 1) % every == 0:
                k = (step + 1) // every
                states[k][:, cols], forces[k][:, cols] = x, F
        return DamperCarRun(t=np.arange(n_out + 1) * store, speeds=speeds, states=states, forces=forces,
                            stopped_at=stopped)

    def _start(self, car: CooperriderCar, x: np.ndarray, dampers) -> np.ndarray:
        """The yaw damper forces (4, m) [N] at the start: each FMU initialised at its elongation and rate,
        or the ``D6`` dashpots' forces without FMUs."""
        e, v = car.yaw_damper_strokes(x)
        if dampers is None:
            return self.params.D6 * v
        return np.array([[four[i].start(0.0, float(e[i, j]), float(v[i, j])) for j, four in enumerate(dampers)]
                         for i in range(4)])

    def _exchange(self, car: CooperriderCar, x: np.ndarray, F: np.ndarray, t: float, dampers) -> tuple:
        """One communication step from ``t`` [s]: the FMUs' step, then the car's; the new state and forces."""
        h = self.step
        dx = car.rhs(t, x, F if dampers is not None else None)
        if dampers is None:
            return rk4_linear_forces(lambda y, f: car.rhs(0.0, y, f), x, None, None, h, self.substeps, dx), F
        e, v = car.yaw_damper_strokes(x)
        a = car.yaw_damper_acceleration(dx)
        F1 = np.empty_like(F)
        for j, four in enumerate(dampers):
            for i in range(4):
                F1[i, j] = four[i].step(t, h, float(e[i, j]), float(v[i, j]), float(a[i, j]))
        return rk4_linear_forces(lambda y, f: car.rhs(0.0, y, f), x, F, F1, h, self.substeps, dx), F1

    def close(self) -> None:
        """Free the FMU instances and their extracted files."""
        for d in self._pool:
            d.close()
        self._pool = []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
