"""Nonlinear wheel-rail contact of a wheelset: parametric conicity, flange as a dead-band spring,
creep forces that saturate (Shen-Hedrick-Elkins).

Frame and signs (those of :mod:`campaign.vehicle`): x forward, y left, z up; a wheelset's lateral
displacement ``y`` [m] relative to the track centreline is positive to the left, its yaw ``psi``
[rad] relative to the track tangent positive counter-clockwise seen from above, ``speed`` V [m/s]
forward. Forces are those the rails exert on the wheelset: lateral force positive to the left (+y),
yaw moment positive counter-clockwise (+z).

Geometry (a cone of equivalent conicity ``lambda`` on knife-edge rails, the classical model of
Wickens and of Cooperrider's bogie): the rolling radius of the left wheel is ``r0 + lambda y``, of
the right wheel ``r0 - lambda y``, i.e. the rolling-radius difference ``r_L - r_R = 2 lambda y``
(:func:`rolling_radius_difference`). Contact angles and the wheelset's roll (gravitational
stiffness) are not modelled, as in the linear reference :mod:`campaign.vehicle`. The flange closes
the clearance ``delta`` [m]: beyond it the rail pushes the wheelset back with the stiffness ``k_f``
[N/m] (:func:`flange_force`: zero for ``|y| <= delta``, ``-k_f (y - sign(y) delta)`` beyond).

Creepages (slip velocity of the wheel material at the contact relative to the rail, divided by V;
spin is neglected as in the linear model), wheel ``L`` at ``+b0``, ``R`` at ``-b0``, yaw rate
``omega`` [rad/s]::

    xi_x,L = -(b0 omega / V + (r_L - r0) / r0)      xi_x,R = +b0 omega / V - (r_R - r0) / r0
    xi_y   = y' / V - psi                             (both wheels)

Linear Kalker forces on each wheel ``F_x = -f11 xi_x``, ``F_y = -f22 xi_y`` (``f11``, ``f22`` [N]).
They saturate at ``mu N`` (friction coefficient ``mu``, wheel load ``N`` [N]) by the law of Shen,
Hedrick and Elkins (1983): with ``beta = |F_lin| / (mu N)`` the resultant is scaled by
``s(beta) / beta``, ``s(beta) = beta - beta^2 / 3 + beta^3 / 27`` for ``beta < 3`` and ``1`` beyond
(:func:`saturation`): the linear law for small creep, exactly ``mu N`` from ``beta = 3`` on, smooth
(continuous first derivative) in between. The wheelset's lateral force is ``F_y,L + F_y,R`` plus the
flange force, its yaw moment ``b0 (F_x,R - F_x,L)``; for small creep they are the linear model's
``-2 f22 (y'/V - psi)`` and ``-2 f11 b0 (b0 omega / V + lambda y / r0)``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

__all__ = ["saturation", "saturation_factor", "rolling_radius_difference", "flange_force", "WheelRailContact", "WheelsetForces"]


def saturation(beta):
    """Shen-Hedrick-Elkins saturation ``s(beta)`` [-] of the creep force resultant: ``beta`` [-] is the
    linear (Kalker) resultant divided by ``mu N``, ``s`` the saturated resultant divided by ``mu N``;
    ``s = beta - beta^2/3 + beta^3/27`` for ``0 <= beta < 3``, ``1`` for ``beta >= 3``."""
    b = np.asarray(beta, dtype=float)
    if np.any(b < 0.0) or not np.all(np.isfinite(b)):
        raise ValueError("beta must be finite and >= 0")
    return np.where(b < 3.0, b * saturation_factor(b), 1.0)


def saturation_factor(beta: np.ndarray) -> np.ndarray:
    """``s(beta) / beta`` [-], the factor on the linear creep force, without a division at small ``beta``:
    ``1 - beta/3 + beta^2/27`` below 3, ``1 / beta`` beyond (unchecked: the integrators' inner loop)."""
    return np.where(beta < 3.0, 1.0 - beta * (1.0 / 3.0 - beta / 27.0), 1.0 / np.maximum(beta, 3.0))


def rolling_radius_difference(y, conicity: float):
    """Rolling-radius difference ``r_L - r_R`` [m] of a conical wheelset displaced ``y`` [m] to the left:
    ``2 conicity y`` (conicity [-], the equivalent conicity of the profile pair)."""
    return (2.0 * conicity) * np.asarray(y, dtype=float)


def flange_force(y, clearance: float, stiffness: float):
    """Lateral flange force [N] on a wheelset displaced ``y`` [m] (positive left): zero within the
    flangeway ``|y| <= clearance`` [m], ``-stiffness (y - sign(y) clearance)`` beyond (``stiffness``
    [N/m]): a dead-band spring pushing the wheelset back towards the centreline."""
    y = np.asarray(y, dtype=float)
    return -stiffness * (np.maximum(y - clearance, 0.0) + np.minimum(y + clearance, 0.0))


@dataclass
class WheelsetForces:
    """Contact forces the rails exert on wheelsets: ``lateral`` [N] positive to the left (creep and
    flange together), ``yaw_moment`` [N m] positive counter-clockwise; ``flange`` [N] the flange part
    of ``lateral``; arrays shaped like the wheelset coordinates given."""

    lateral: np.ndarray
    yaw_moment: np.ndarray
    flange: np.ndarray


@dataclass(frozen=True)
class WheelRailContact:
    """Parametric wheel-rail contact of one wheelset (SI units): equivalent ``conicity`` [-], nominal
    rolling radius ``wheel_radius`` r0 [m], lateral semi-distance of the contact points
    ``contact_half_distance`` b0 [m], Kalker coefficients ``f11`` (longitudinal) and ``f22`` (lateral)
    [N], ``friction_coefficient`` mu [-], static ``wheel_load`` N per wheel [N], flangeway
    ``flange_clearance`` delta [m] and ``flange_stiffness`` k_f [N/m] (lateral stiffness of the
    flange contact and the rail)."""

    conicity: float
    wheel_radius: float
    contact_half_distance: float
    f11: float
    f22: float
    friction_coefficient: float
    wheel_load: float
    flange_clearance: float
    flange_stiffness: float

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if not (isinstance(v, (int, float)) and math.isfinite(v)):
                raise ValueError(f"contact parameter {f.name} must be a finite number, got {v!r}")
            if v < 0.0 or (v == 0.0 and f.name not in ("conicity", "flange_stiffness")):
                raise ValueError(f"contact parameter {f.name} must be > 0, got {v}")

    def creep_limit(self) -> float:
        """Largest creep force resultant per wheel ``mu N`` [N]."""
        return self.friction_coefficient * self.wheel_load

    def wheel_forces(self, xi_x, xi_y):
        """Saturated creep forces (F_x, F_y) [N] on one wheel for the creepages ``xi_x``, ``xi_y`` [-]
        (arrays of one shape): the linear Kalker forces scaled by ``s(beta) / beta``."""
        fx = -self.f11 * np.asarray(xi_x, dtype=float)
        fy = -self.f22 * np.asarray(xi_y, dtype=float)
        scale = saturation_factor(np.sqrt(fx * fx + fy * fy) * (1.0 / self.creep_limit()))
        return fx * scale, fy * scale

    def wheelset_forces(self, y, psi, y_dot, yaw_rate, speed: float) -> WheelsetForces:
        """Contact forces on wheelsets at lateral displacement ``y`` [m], yaw ``psi`` [rad] relative to
        the track, their rates ``y_dot`` [m/s] and ``yaw_rate`` [rad/s] (arrays of one shape), running
        at ``speed`` [m/s] on straight track (see the module docstring for the creepages and signs)."""
        if not (math.isfinite(speed) and speed > 0.0):
            raise ValueError(f"speed must be finite and > 0 m/s, got {speed}")
        return self.forces(*(np.asarray(a, dtype=float) for a in (y, psi, y_dot, yaw_rate)), speed)

    def forces(self, y: np.ndarray, psi: np.ndarray, y_dot: np.ndarray, yaw_rate: np.ndarray,
               speed: float) -> WheelsetForces:
        """:meth:`wheelset_forces` for float arrays and a valid speed, unchecked (integrators' inner loop)."""
        b0, r0 = self.contact_half_distance, self.wheel_radius
        half_dr = 0.5 * rolling_radius_difference(y, self.conicity)  # r_L - r0 = r0 - r_R
        turn = (b0 / speed) * yaw_rate
        xi_y = y_dot * (1.0 / speed) - psi
        # the right wheel's creepages are the left's with xi_x mirrored (symmetric cone, equal loads):
        # its forces are (-F_x,L, F_y,L)
        fx_l, fy_l = self.wheel_forces(-(turn + half_dr / r0), xi_y)
        fl = flange_force(y, self.flange_clearance, self.flange_stiffness)
        return WheelsetForces(2.0 * fy_l + fl, -2.0 * b0 * fx_l, fl)
