"""Nonlinear lateral/yaw dynamics of the car of :mod:`campaign.vehicle` on straight ideal track: the
same seven bodies, suspension and yaw dampers, with the wheel-rail contact of :mod:`campaign.contact`
(saturating creep, flange as a dead-band spring) instead of linear Kalker creep, for hunting limit
cycles.

One place per concept: the bodies, suspension and the Maxwell yaw dampers (series stiffness, dashpot
with blow-off) are ``campaign.vehicle.VehicleModel(params, speed, creep=False)``'s matrices; the
contact forces come from :class:`campaign.contact.WheelRailContact`, built from the same
:class:`campaign.vehicle.VehicleParams` (conicity, wheel radius, contact half distance, Kalker
coefficients; wheel load from the masses) and the :class:`ContactSettings` (friction, flange).
For small motion the model is the linear one (its Jacobian at rest is ``VehicleModel.A``, tested).

States (SI units, as in :mod:`campaign.vehicle`): ``x = [y_0..y_6, Psi_0..Psi_6, y'_0..y'_6,
omega_0..omega_6, F_0..F_3]``: lateral displacements [m] (positive left), yaw angles [rad] (positive
counter-clockwise; on straight track relative to the track), their rates, yaw damper forces [N]
(tension positive, order ``DAMPER_NAMES``). The first :data:`N_MECH` states are the mechanical ones; a
damper FMU co-simulation (``tuner.vehicle``) supplies the forces through :meth:`NonlinearVehicle.
mechanical_rhs` instead.

Integration: fixed-step classical Runge-Kutta (:func:`rk4_step`, ``h = 1 ms`` by default; the
fastest eigenvalue of the car, creep damping of a wheelset at low speed, is a few hundred 1/s, well
inside RK4's stability region at 1 ms); :meth:`NonlinearVehicle.rhs` is the right-hand side for a
``scipy.integrate.solve_ivp`` check (tested).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from .contact import WheelRailContact, WheelsetForces
from .track import GRAVITY
from .vehicle import N_BODIES, N_DAMPERS, N_DOF, N_STATES, WHEELSETS, VehicleModel, VehicleParams

__all__ = ["ContactSettings", "NonlinearVehicle", "NonlinearRun", "vehicle_contact", "kick_state", "rk4_step",
           "N_MECH", "LEADING_WHEELSET", "DEFAULT_STEP"]

N_MECH = 2 * N_DOF
"""Mechanical states: y_0..y_6, Psi_0..Psi_6 [m, rad] and their rates."""
LEADING_WHEELSET = WHEELSETS[0]
"""Body (and lateral state) index of the leading wheelset (front bogie, front axle)."""
DEFAULT_STEP = 1e-3
"""Default Runge-Kutta step [s]."""
_W = np.asarray(WHEELSETS)


@dataclass(frozen=True)
class ContactSettings:
    """The contact parameters beyond :class:`campaign.vehicle.VehicleParams` (generic values, SI units):
    ``friction_coefficient`` mu [-] (dry rail 0.3-0.4), ``flange_clearance`` [m] per side before the
    flange touches, ``flange_stiffness`` [N/m] of the flange contact and the rail laterally."""

    friction_coefficient: float = 0.3
    flange_clearance: float = 7e-3
    flange_stiffness: float = 1.5e7

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0.0):
                raise ValueError(f"contact setting {f.name} must be a finite number > 0, got {v!r}")


def vehicle_contact(params: VehicleParams, settings: ContactSettings | None = None) -> WheelRailContact:
    """The wheel-rail contact of the car ``params``: its conicity, wheel radius, contact half distance and
    Kalker coefficients, the static wheel load ``g (m_carbody + 2 m_bogie + 4 m_wheelset) / 8`` [N]."""
    s = settings if settings is not None else ContactSettings()
    load = GRAVITY * (params.m_carbody + 2.0 * params.m_bogie + 4.0 * params.m_wheelset) / 8.0
    return WheelRailContact(conicity=params.conicity, wheel_radius=params.wheel_radius,
                            contact_half_distance=params.contact_half_distance, f11=params.f11, f22=params.f22,
                            friction_coefficient=s.friction_coefficient, wheel_load=load,
                            flange_clearance=s.flange_clearance, flange_stiffness=s.flange_stiffness)


def kick_state(amplitude: float, n_states: int = N_STATES) -> np.ndarray:
    """Initial state on straight track: bogies and wheelsets displaced ``amplitude`` [m] to the left
    (+y), carbody centred, no yaw, at rest, no damper force; ``n_states`` = N_STATES or N_MECH."""
    if not (math.isfinite(amplitude) and amplitude >= 0.0):
        raise ValueError(f"amplitude must be finite and >= 0 m, got {amplitude}")
    if n_states not in (N_STATES, N_MECH):
        raise ValueError(f"n_states must be {N_STATES} or {N_MECH}, got {n_states}")
    x = np.zeros(n_states)
    x[1:N_BODIES] = amplitude
    return x


def rk4_step(f, t: float, x: np.ndarray, h: float) -> np.ndarray:
    """One classical Runge-Kutta step of ``x' = f(t, x)`` from ``t`` over ``h`` [s]."""
    k1 = f(t, x)
    k2 = f(t + 0.5 * h, x + 0.5 * h * k1)
    k3 = f(t + 0.5 * h, x + 0.5 * h * k2)
    k4 = f(t + h, x + h * k3)
    return x + (h / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)


@dataclass
class NonlinearRun:
    """A run of :class:`NonlinearVehicle` (or of the FMU co-simulation): times ``t`` [s], ``states``
    (n, N_STATES or N_MECH) as in the module docstring, the ``speed`` [m/s]."""

    t: np.ndarray
    states: np.ndarray
    speed: float

    @property
    def leading_wheelset(self) -> np.ndarray:
        """Lateral displacement [m] of the leading wheelset (positive left)."""
        return self.states[:, LEADING_WHEELSET]

    @property
    def final_state(self) -> np.ndarray:
        return self.states[-1].copy()


class NonlinearVehicle:
    """The car of ``params`` at constant ``speed`` [m/s] on straight ideal track with the nonlinear
    contact ``settings`` (see the module docstring); built-in Maxwell yaw dampers of ``params``."""

    def __init__(self, params: VehicleParams | None = None, speed: float = 250.0 / 3.6,
                 settings: ContactSettings | None = None):
        self.params = params if params is not None else VehicleParams()
        self.linear = VehicleModel(self.params, speed, creep=False)
        self.speed = self.linear.speed
        self.contact = vehicle_contact(self.params, settings)
        self.A = self.linear.A
        self._amech = np.ascontiguousarray(self.A[:N_MECH, :N_MECH])
        self._aforce = np.ascontiguousarray(self.A[:N_MECH, N_MECH:])
        self._inv_mass = 1.0 / self.linear.mass[_W]
        self._inv_inertia = 1.0 / self.linear.inertia[_W]

    def contact_forces(self, x: np.ndarray) -> WheelsetForces:
        """Contact forces [N, N m] on the four wheelsets in the state ``x`` (mechanical part used)."""
        return self.contact.forces(x[_W], x[N_BODIES + _W], x[N_DOF + _W], x[N_DOF + N_BODIES + _W], self.speed)

    def mechanical_rhs(self, x: np.ndarray, damper_forces: np.ndarray) -> np.ndarray:
        """Derivative of the mechanical state ``x`` (N_MECH,) with the yaw damper forces ``damper_forces``
        [N] (4, tension positive) acting between bogies and carbody."""
        dx = self._amech @ x + self._aforce @ damper_forces
        f = self.contact_forces(x)
        dx[N_DOF + _W] += f.lateral * self._inv_mass
        dx[N_DOF + N_BODIES + _W] += f.yaw_moment * self._inv_inertia
        return dx

    def rhs(self, t: float, x: np.ndarray) -> np.ndarray:
        """Derivative of the full state ``x`` (N_STATES,) with the built-in yaw dampers (time ``t`` [s]
        unused: straight ideal track)."""
        return self.derivative(x, self.speed)

    def derivative(self, x: np.ndarray, speed: float) -> np.ndarray:
        """:meth:`rhs` at another ``speed`` [m/s]: the matrices without creep do not depend on speed, the
        contact's creepages do (for shooting, where the speed is an unknown)."""
        dx = self.A @ x + self.linear.Bw @ self.params._excess(x[N_MECH:])
        f = self.contact.forces(x[_W], x[N_BODIES + _W], x[N_DOF + _W], x[N_DOF + N_BODIES + _W], speed)
        dx[N_DOF + _W] += f.lateral * self._inv_mass
        dx[N_DOF + N_BODIES + _W] += f.yaw_moment * self._inv_inertia
        return dx

    def simulate(self, x0: np.ndarray, t_end: float, *, step: float = DEFAULT_STEP, record_every: int = 1,
                 t0: float = 0.0) -> NonlinearRun:
        """Fixed-step RK4 run from the state ``x0`` (N_STATES,) over ``t_end`` [s] with ``step`` [s],
        keeping every ``record_every``-th state (the first and the last always)."""
        x = np.array(x0, dtype=float)
        if x.shape != (N_STATES,) or not np.all(np.isfinite(x)):
            raise ValueError(f"x0 must be {N_STATES} finite values")
        if not (math.isfinite(step) and 0.0 < step <= 2e-3):
            raise ValueError(f"step must be in (0, 2 ms], got {step} s")
        if not (math.isfinite(t_end) and t_end >= step):
            raise ValueError(f"t_end must be >= step {step} s, got {t_end}")
        if record_every < 1:
            raise ValueError(f"record_every must be >= 1, got {record_every}")
        n = int(round(t_end / step))
        keep = list(range(0, n + 1, record_every))
        if keep[-1] != n:
            keep.append(n)
        out = np.empty((len(keep), N_STATES))
        out[0] = x
        j = 1
        for k in range(1, n + 1):
            x = rk4_step(self.rhs, t0 + (k - 1) * step, x, step)
            if j < len(keep) and k == keep[j]:
                out[j] = x
                j += 1
        return NonlinearRun(t0 + np.asarray(keep) * step, out, self.speed)

