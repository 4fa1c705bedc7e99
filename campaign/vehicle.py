"""Linear lateral/yaw dynamics of one high-speed car with Maxwell yaw dampers.

Seven rigid bodies, each with a lateral and a yaw degree of freedom (carbody roll is not
modelled: it couples to lateral motion but hardly to the bogie-carbody yaw angle that
drives the yaw dampers):

    body 0 carbody (x = 0), 1 front bogie (x = +L), 2 rear bogie (x = -L),
    3..6 wheelsets at x = L + a, L - a, -L + a, -L - a      (x forward, y left, z up)

Coordinates of body k at track position ``s_k = s0 + V t + x_k`` [m]:

* ``y_k`` [m] lateral displacement relative to the design track centreline at ``s_k``;
* ``Psi_k`` [rad] absolute heading in the small-angle frame of the track (yaw relative to
  the local tangent is ``Psi_k - theta(s_k)``), with rate ``omega_k`` [rad/s].

Using absolute headings makes the kinematic yaw of bodies following the curve exact:
yaw deflections between bodies are ``Psi_Q - Psi_P`` and the curvature appears through the
track heading theta(s) and lateral position Y(s) (see :mod:`campaign.track`) as forcing:

* wheelset creep (linear Kalker, equivalent conicity lambda, radius r0, contact half
  distance b0):  F_y = -2 f22 (y'/V - (Psi - theta(s_w))),
  M_z = -2 f11 b0 (b0 omega / V + lambda (y - y_irr(s_w)) / r0) (the usual steering
  term -2 f11 b0^2 kappa appears through the absolute yaw rate omega = V kappa + ...);
* lateral suspension deflection between P and Q at the station of Q:
  ``y_Q - y_P - l_P Psi_P + Y(s_Q) - Y(s_P)`` with lever ``l_P = x_Q - x_P``;
* uncompensated lateral acceleration ``V^2 kappa - g h / 1.5`` on every body.

Yaw dampers (two per bogie, lateral offset +-d, longitudinal) are Maxwell elements: a series
spring ``k_s`` and a dashpot with linear damping ``c1`` up to the blow-off velocity ``v_b``
and ``c2`` beyond. Each carbody bracket is inboard of its bogie attachment, so the front
right damper elongation is ``e = d (Psi_front_bogie - Psi_carbody)`` (positive = extension;
it extends in a left-hand curve), force positive in tension. Force state equation:
``F' = k_s (e' - v_dashpot(F))``.

The system is linear apart from the dashpot blow-off. It is integrated with the exact
first-order-hold discretisation of the linear part (matrix exponential, valid for any
stiffness) and a predictor-corrector for the blow-off term, at ``dt <= 0.5 ms``.
:meth:`VehicleModel.rhs` gives the same equations for an independent ``solve_ivp`` check.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from scipy.linalg import expm

from .track import CONTACT_BASE, GRAVITY

N_BODIES = 7
N_DOF = 2 * N_BODIES
N_DAMPERS = 4
N_STATES = 2 * N_DOF + N_DAMPERS
DAMPER_NAMES = ("front_right", "front_left", "rear_right", "rear_left")
DT_MAX = 5e-4
"""Largest internal integration step [s]."""


@dataclass(frozen=True)
class VehicleParams:
    """Parameters of a generic high-speed car (SI units). Suspension values are per
    element as named: per axlebox (primary), per air spring (secondary), per damper."""

    m_carbody: float = 40000.0  # [kg]
    i_carbody: float = 2.3e6  # yaw inertia [kg m^2]
    m_bogie: float = 2600.0  # [kg]
    i_bogie: float = 1800.0  # [kg m^2]
    m_wheelset: float = 1800.0  # [kg]
    i_wheelset: float = 1100.0  # [kg m^2]
    half_bogie_distance: float = 8.75  # L [m]
    semi_wheelbase: float = 1.25  # a [m]
    wheel_radius: float = 0.46  # r0 [m]
    conicity: float = 0.15  # lambda [-]
    contact_half_distance: float = CONTACT_BASE / 2.0  # b0 [m] (gauge 1.435 m + rail head)
    f11: float = 1.0e7  # longitudinal creep coefficient [N]
    f22: float = 1.0e7  # lateral creep coefficient [N]
    k_px: float = 1.2e7  # primary longitudinal stiffness per axlebox [N/m]
    k_py: float = 4.0e6  # primary lateral stiffness per axlebox [N/m]
    c_py: float = 0.0  # primary lateral damping per axlebox [N s/m]
    b_primary: float = 1.0  # lateral semi-spacing of axleboxes [m]
    k_sx: float = 1.6e5  # air spring longitudinal stiffness [N/m]
    k_sy: float = 1.6e5  # air spring lateral stiffness [N/m]
    b_secondary: float = 1.0  # lateral semi-spacing of air springs [m]
    c_sy: float = 3.0e4  # secondary lateral damper, one per bogie [N s/m]
    yaw_damper_offset: float = 1.3  # d, lateral offset of the yaw dampers [m]
    yaw_series_stiffness: float = 1.0e7  # k_s [N/m]
    yaw_damping: float = 1.2e6  # c1, below blow-off [N s/m]
    yaw_blowoff_velocity: float = 0.010  # v_b [m/s]; inf = linear dashpot
    yaw_damping_blowoff: float = 1.4e5  # c2, beyond blow-off [N s/m]

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if not (isinstance(v, (int, float)) and not math.isnan(v)):
                raise ValueError(f"vehicle parameter {f.name} must be a number, got {v!r}")
            zero_ok = f.name in ("c_py", "c_sy", "k_sx", "k_sy")
            if v < 0.0 or (v == 0.0 and not zero_ok):
                raise ValueError(f"vehicle parameter {f.name} must be > 0, got {v}")
            if math.isinf(v) and f.name != "yaw_blowoff_velocity":
                raise ValueError(f"vehicle parameter {f.name} must be finite, got {v}")

    @property
    def positions(self) -> np.ndarray:
        """Longitudinal positions x_k of the 7 bodies relative to the carbody centre [m]."""
        L, a = self.half_bogie_distance, self.semi_wheelbase
        return np.array([0.0, L, -L, L + a, L - a, -L + a, -L - a])

    @property
    def blowoff_force(self) -> float:
        """Dashpot force at the blow-off velocity [N]."""
        return self.yaw_damping * self.yaw_blowoff_velocity

    def dashpot_velocity(self, force):
        """Dashpot velocity [m/s] carrying ``force`` [N] (bilinear, odd)."""
        F = np.asarray(force, dtype=float)
        return F / self.yaw_damping + self._excess(F)

    def _excess(self, F):
        """Nonlinear part of the dashpot velocity beyond the linear law F / c1 [m/s]."""
        if math.isinf(self.yaw_blowoff_velocity):
            return np.zeros_like(F)
        over = np.maximum(np.abs(F) - self.blowoff_force, 0.0)
        return np.sign(F) * over * (1.0 / self.yaw_damping_blowoff - 1.0 / self.yaw_damping)


# body indices
CARBODY, FRONT_BOGIE, REAR_BOGIE = 0, 1, 2
WHEELSETS = (3, 4, 5, 6)
# suspension connections (P, Q): primary bogie -> wheelset, secondary carbody -> bogie
CONNECTIONS = ((1, 3), (1, 4), (2, 5), (2, 6), (0, 1), (0, 2))
N_INPUTS = 4 + 4 + N_BODIES + 2 * len(CONNECTIONS)


def _y(k: int) -> int:
    return k


def _psi(k: int) -> int:
    return N_BODIES + k


class VehicleModel:
    """State-space model at constant ``speed`` [m/s].

    State x = [y_0..y_6, Psi_0..Psi_6, y'_0..y'_6, omega_0..omega_6, F_0..F_3] (SI units,
    damper forces F in N, order :data:`DAMPER_NAMES`). Inputs u (see :meth:`inputs`):
    wheelset track headings theta [rad] (4), wheelset irregularity y_irr [m] (4), body
    uncompensated accelerations [m/s^2] (7), connection geometry Y(s_Q) - Y(s_P) [m] (6)
    and its rate [m/s] (6). ``x' = A x + B u + Bw w`` with ``w = excess dashpot velocity``.
    ``creep=False`` leaves the wheel-rail creep forces out (the nonlinear contact of
    :mod:`campaign.vehicle_nonlinear` adds its own).
    """

    def __init__(self, params: VehicleParams | None = None, speed: float = 250.0 / 3.6, *, creep: bool = True):
        if not (math.isfinite(speed) and speed > 0.0):
            raise ValueError(f"speed must be finite and > 0 m/s, got {speed}")
        self.p = p = params if params is not None else VehicleParams()
        self.speed = V = float(speed)
        xk = p.positions
        mass = np.array([p.m_carbody, p.m_bogie, p.m_bogie] + [p.m_wheelset] * 4)
        inertia = np.array([p.i_carbody, p.i_bogie, p.i_bogie] + [p.i_wheelset] * 4)
        M = np.diag(np.concatenate([mass, inertia]))
        K = np.zeros((N_DOF, N_DOF))
        C = np.zeros((N_DOF, N_DOF))
        G = np.zeros((N_DOF, N_INPUTS))
        nc = len(CONNECTIONS)
        for c, (P, Q) in enumerate(CONNECTIONS):
            primary = c < 4
            ky = 2.0 * (p.k_py if primary else p.k_sy)
            cy = 2.0 * p.c_py if primary else p.c_sy
            kpsi = 2.0 * (p.k_px * p.b_primary**2 if primary else p.k_sx * p.b_secondary**2)
            lat = np.zeros(N_DOF)
            lat[_y(Q)] += 1.0
            lat[_y(P)] -= 1.0
            lat[_psi(P)] -= xk[Q] - xk[P]
            yaw = np.zeros(N_DOF)
            yaw[_psi(Q)] += 1.0
            yaw[_psi(P)] -= 1.0
            K += ky * np.outer(lat, lat) + kpsi * np.outer(yaw, yaw)
            C += cy * np.outer(lat, lat)
            G[:, 15 + c] = -ky * lat
            G[:, 15 + nc + c] = -cy * lat
        b0, lam, r0 = p.contact_half_distance, p.conicity, p.wheel_radius
        for j, w in enumerate(WHEELSETS if creep else ()):
            C[_y(w), _y(w)] += 2.0 * p.f22 / V
            K[_y(w), _psi(w)] -= 2.0 * p.f22
            G[_y(w), j] = -2.0 * p.f22
            C[_psi(w), _psi(w)] += 2.0 * p.f11 * b0**2 / V
            K[_psi(w), _y(w)] += 2.0 * p.f11 * b0 * lam / r0
            G[_psi(w), 4 + j] = 2.0 * p.f11 * b0 * lam / r0
        for k in range(N_BODIES):
            G[_y(k), 8 + k] = -mass[k]
        # damper elongations e = E q
        d = p.yaw_damper_offset
        E = np.zeros((N_DAMPERS, N_DOF))
        for i, (bogie, sign) in enumerate(((1, 1.0), (1, -1.0), (2, -1.0), (2, 1.0))):
            E[i, _psi(bogie)] = sign * d
            E[i, _psi(CARBODY)] = -sign * d
        Minv = np.diag(1.0 / np.diag(M))
        ks, c1 = p.yaw_series_stiffness, p.yaw_damping
        n = N_STATES
        A = np.zeros((n, n))
        A[:N_DOF, N_DOF : 2 * N_DOF] = np.eye(N_DOF)
        A[N_DOF : 2 * N_DOF, :N_DOF] = -Minv @ K
        A[N_DOF : 2 * N_DOF, N_DOF : 2 * N_DOF] = -Minv @ C
        A[N_DOF : 2 * N_DOF, 2 * N_DOF :] = -Minv @ E.T
        A[2 * N_DOF :, N_DOF : 2 * N_DOF] = ks * E
        A[2 * N_DOF :, 2 * N_DOF :] = -(ks / c1) * np.eye(N_DAMPERS)
        B = np.zeros((n, N_INPUTS))
        B[N_DOF : 2 * N_DOF] = Minv @ G
        Bw = np.zeros((n, N_DAMPERS))
        Bw[2 * N_DOF :] = -ks * np.eye(N_DAMPERS)
        self.A, self.B, self.Bw, self.E = A, B, Bw, E
        self.mass, self.inertia = mass, inertia

    # ------------------------------------------------------------------ inputs
    def inputs(self, track, irregularity, s0: float, t) -> np.ndarray:
        """Input matrix (len(t), N_INPUTS) for carbody centre at ``s0 + V t`` [m].

        track: :class:`campaign.track.Track`; irregularity: callable s [m] -> lateral
        alignment [m], or None; t [s] array."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        V = self.speed
        s = s0 + V * t[:, None] + self.p.positions[None, :]  # (N, 7)
        U = np.empty((t.size, N_INPUTS))
        th = track.heading(s)
        U[:, 0:4] = th[:, 3:7]
        U[:, 4:8] = 0.0 if irregularity is None else irregularity(s[:, 3:7])
        U[:, 8:15] = track.uncompensated_acceleration(s, V)
        Y = track.lateral(s)
        nc = len(CONNECTIONS)
        for c, (P, Q) in enumerate(CONNECTIONS):
            U[:, 15 + c] = Y[:, Q] - Y[:, P]
            U[:, 15 + nc + c] = V * (th[:, Q] - th[:, P])
        return U

    def initial_state(self, track, s0: float) -> np.ndarray:
        """Bodies centred on the track and aligned with it, at rest relative to it, no
        damper force (exact equilibrium on straight track without irregularity)."""
        x = np.zeros(N_STATES)
        sk = s0 + self.p.positions
        x[N_BODIES:N_DOF] = track.heading(sk)
        x[N_DOF + N_BODIES : 2 * N_DOF] = self.speed * track.curvature(sk)
        return x

    # ------------------------------------------------------------------ dynamics
    def rhs(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """State derivative for state ``x`` and input vector ``u`` (SI units)."""
        return self.A @ x + self.B @ u + self.Bw @ self.p._excess(x[2 * N_DOF :])

    def eigenvalues(self) -> np.ndarray:
        """Eigenvalues [1/s] of the linearised system (dashpot below blow-off)."""
        return np.linalg.eigvals(self.A)

    def discretize(self, h: float):
        """First-order-hold exact discretisation over step ``h`` [s] of inputs u and w:
        ``x1 = Phi x0 + G1 u0 + G2 (u1 - u0)`` (same for w). Returns
        (Phi, G1u, G2u, G1w, G2w)."""
        n, m = N_STATES, N_INPUTS + N_DAMPERS
        Bf = np.hstack([self.B, self.Bw])
        Z = np.zeros((n + 2 * m, n + 2 * m))
        Z[:n, :n] = self.A * h
        Z[:n, n : n + m] = Bf * h
        Z[n : n + m, n + m :] = np.eye(m)
        X = expm(Z)
        Phi = X[:n, :n]
        G1, G2 = X[:n, n : n + m], X[:n, n + m :]
        return Phi, G1[:, :N_INPUTS], G2[:, :N_INPUTS], G1[:, N_INPUTS:], G2[:, N_INPUTS:]

    def simulate(self, t: np.ndarray, U: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """States (len(t), N_STATES) on the uniform time grid ``t`` [s] (step <= DT_MAX)
        for inputs ``U`` sampled on ``t`` (linear between samples)."""
        t = np.asarray(t, dtype=float)
        if t.ndim != 1 or t.size < 2:
            raise ValueError("t must be a 1-D array with at least 2 samples")
        h = float(t[1] - t[0])
        if not h > 0.0 or not np.allclose(np.diff(t), h, rtol=1e-9, atol=1e-12):
            raise ValueError("t must be uniformly spaced and increasing")
        if h > DT_MAX * (1.0 + 1e-9):
            raise ValueError(f"time step {h} s exceeds the largest internal step {DT_MAX} s")
        if U.shape != (t.size, N_INPUTS):
            raise ValueError(f"U must have shape {(t.size, N_INPUTS)}, got {U.shape}")
        Phi, G1, G2, G1w, G2w = self.discretize(h)
        forced = U[:-1] @ (G1 - G2).T + U[1:] @ G2.T
        X = np.empty((t.size, N_STATES))
        x = np.array(x0, dtype=float)
        X[0] = x
        iF = slice(2 * N_DOF, N_STATES)
        excess = self.p._excess
        Fb = self.p.blowoff_force
        linear = math.isinf(self.p.yaw_blowoff_velocity)
        w0 = excess(x[iF])
        active = bool(np.any(w0))
        for k in range(t.size - 1):
            xn = Phi @ x + forced[k]
            if not linear:
                if active:
                    xn += G1w @ w0
                if active or np.max(np.abs(xn[iF])) > Fb:
                    # predictor (w held) -> corrector (w linear over the step)
                    w1 = excess(xn[iF])
                    xn += G2w @ (w1 - w0)
                    w0 = excess(xn[iF])
                    active = bool(np.any(w0))
            x = xn
            X[k + 1] = x
        return X

    def damper_strokes(self, X: np.ndarray):
        """Elongations [m] and elongation rates [m/s] of the 4 yaw dampers, each
        (len(X), 4) in the order :data:`DAMPER_NAMES`."""
        return X[:, :N_DOF] @ self.E.T, X[:, N_DOF : 2 * N_DOF] @ self.E.T


def max_real_eigenvalue(params: VehicleParams | None, speed: float) -> float:
    """Largest real part [1/s] of the eigenvalues at ``speed`` [m/s]."""
    return float(np.max(VehicleModel(params, speed).eigenvalues().real))


def critical_speed(params: VehicleParams | None = None, v_max: float = 200.0, dv: float = 2.0, tol: float = 0.05) -> float:
    """Lowest speed [m/s] at which an eigenvalue crosses into the right half plane
    (linear hunting onset), searched up to ``v_max`` [m/s] on a ``dv`` grid and refined
    by bisection to ``tol`` [m/s]; ``inf`` if stable up to ``v_max``."""
    if not (v_max > dv > 0.0):
        raise ValueError("need v_max > dv > 0")
    lo = None
    for v in np.arange(dv, v_max + dv / 2, dv):
        if max_real_eigenvalue(params, v) > 0.0:
            hi = float(v)
            break
        lo = float(v)
    else:
        return math.inf
    if lo is None:
        raise ValueError(f"vehicle unstable already at {dv} m/s")
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if max_real_eigenvalue(params, mid) > 0.0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)
