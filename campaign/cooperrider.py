"""The Cooperrider car on tabulated wheel-rail contact, on straight track: car body, two bogie
frames and four wheelsets, suspended as in the DTU group's simulator DYTSI
(``CooperriderOrthogonalModel``), written independently from its description.

Frame and signs: x forward, y left, z up, small rotations ``phi`` (roll, about x), ``chi`` (pitch,
about y), ``psi`` (yaw, about z), all relative to the track; speed ``V`` [m/s] forward. Bodies:
0 car body, 1 leading bogie frame (x = +u1), 2 trailing one (x = -u1), 3..6 wheelsets at
x = u1 + u2, u1 - u2, -u1 + u2, -u1 - u2 (leading bogie's leading, its trailing, then the trailing
bogie's). State (66 values, SI units): positions ``q`` (31: car body and bogies ``y, z, phi, chi,
psi``; wheelsets ``y, z, phi, psi``), their rates (31), then each wheelset's spin perturbation
``beta`` [rad/s] (the wheelset's spin is ``V / r0 + beta``). Zero is the nominal position; the
vertical springs carry the static load at zero deflection.

Suspension: each link joins a point of an upper body to a point of the lower one (points in body
axes relative to the centre of mass; a point moves with ``(0, y, z) + S p``, ``S`` the skew matrix
of the small rotations) and acts along one track axis: a spring with ``k`` times the change of that
component of the vector between its points (plus, for the vertical ones, the static load), a
dashpot with ``c`` times the relative velocity's component. Moments are ``p x (F - S F)`` (the force
in the body's axes). Primary dampers act along the link (``D3``..``D5``; zero in the published
car).

Contact (each wheel, left at +y read from the table at ``y``, right at ``-y``, see
:mod:`campaign.contact_table`): normal force from the tabulated one by Hertz's law on the extra
penetration of the wheelset's vertical and roll motion, ellipse semi-axes scaled by the cube root of
the load ratio, Kalker's linear creep forces with spin, saturated by Shen-Hedrick-Elkins
(:func:`campaign.contact.saturation_factor`) at ``mu N``, then projected into the track frame with
the contact angle. The wheelset has the gyroscopic moments of its spin, and its spin perturbation
obeys the contact's pitch moment.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .contact import saturation_factor
from .contact_table import ContactTable
from .cooperrider_params import CooperriderParams

__all__ = ["CooperriderCar", "WheelForces", "N_STATES", "N_POS", "LEADING_WHEELSET", "YAW_DAMPER_NAMES", "state_index"]

N_BODIES = 7
N_POS = 31
N_STATES = 2 * N_POS + 4
LEADING_WHEELSET = 3
"""Body index of the leading bogie's leading wheelset (its ``y`` is the hunting signal)."""
YAW_DAMPER_NAMES = ("front_right", "front_left", "rear_right", "rear_left")
"""The four yaw dampers (the ``D6`` dashpots), in the order of :func:`yaw_damper_links`: front = leading
bogie (body 1), right = -y; the names and order of :data:`campaign.vehicle.DAMPER_NAMES`."""

_COORDS = ("y", "z", "phi", "chi", "psi")
_POS_MAP = np.full((N_BODIES, 5), -1, dtype=int)
_POS_MAP[:3] = np.arange(15).reshape(3, 5)
_POS_MAP[3:, [0, 1, 2, 4]] = 15 + np.arange(16).reshape(4, 4)


def state_index(body: int, coord: str, rate: bool = False) -> int:
    """Index in the state vector of ``coord`` (``y``, ``z``, ``phi``, ``chi``, ``psi``) of ``body``
    (0 car body, 1-2 bogies, 3-6 wheelsets), or of its rate with ``rate=True``; ``coord='beta'``
    for a wheelset's spin perturbation."""
    if coord == "beta":
        if not 3 <= body < N_BODIES:
            raise ValueError("only wheelsets (3..6) have a spin perturbation")
        return 2 * N_POS + body - 3
    k = int(_POS_MAP[body, _COORDS.index(coord)])
    if k < 0:
        raise ValueError(f"body {body} has no coordinate {coord!r}")
    return k + (N_POS if rate else 0)


@dataclass(frozen=True)
class Links:
    """The suspension links as arrays (one row per link): ``upper``/``lower`` body indices,
    points ``p_up``/``p_low`` (n, 3) [m] in body axes, ``axis`` 0/1/2 (x/y/z) or -1 (along the link),
    ``rest`` (n, 3) [m] the vector lower->upper point at rest, ``k`` [N/m], ``c`` [N s/m] and
    ``preload`` [N] (force on the lower body at zero deflection, along ``axis``); ``yaw_dampers`` (4,) the
    rows of the yaw dampers (the ``D6`` dashpots, present whatever ``D6``) in :data:`YAW_DAMPER_NAMES` order."""

    upper: np.ndarray
    lower: np.ndarray
    p_up: np.ndarray
    p_low: np.ndarray
    axis: np.ndarray
    rest: np.ndarray
    k: np.ndarray
    c: np.ndarray
    preload: np.ndarray
    yaw_dampers: np.ndarray


def body_centres(p: CooperriderParams) -> np.ndarray:
    """Nominal centres of mass (7, 3) [m], z measured from the rail top."""
    zb, zc = p.r0 + p.h1, p.r0 + p.h1 + p.h2
    xs = (0.0, p.u1, -p.u1, p.u1 + p.u2, p.u1 - p.u2, -p.u1 + p.u2, -p.u1 - p.u2)
    zs = (zc, zb, zb, p.r0, p.r0, p.r0, p.r0)
    return np.array([[x, 0.0, z] for x, z in zip(xs, zs)])


def build_links(p: CooperriderParams) -> Links:
    """The 24 secondary and 24 primary links (and the primary dampers if their coefficient is
    non-zero), placed as the simulator's Cooperrider model places them. The yaw dampers (``D6``): one each
    side of each bogie, longitudinal, from the bogie frame's centre line to the car body at the lateral
    offset ``a + l1 + l2 + l3 / 2``, the car body's point ``s4`` further from the car's centre."""
    g = p.gravity
    sec_load = -p.car_mass * g / 4.0
    prim_load = -(p.car_mass + 2.0 * p.bogie_mass) * g / 8.0
    rows, yaw = [], {}
    for bogie, sign in ((1, 1.0), (2, -1.0)):
        for s in (1.0, -1.0):
            lat_up = (sign * p.u1, s * (p.a + p.l1 + p.l2 + p.l3), -(p.h2 - p.s2))
            lat_low = (0.0, s * (p.a + p.l1 + p.l2), p.s2)
            ver_up, ver_low = (sign * p.u1, s * p.s3, -p.v4), (0.0, s * p.s3, p.v1 + p.v2)
            yaw_y = s * (p.a + p.l1 + p.l2 + p.l3 / 2.0)
            yaw_up, yaw_low = (sign * (p.u1 + p.s4), yaw_y, -p.h2), (0.0, yaw_y, 0.0)
            yaw[("front" if bogie == 1 else "rear") + ("_left" if s > 0 else "_right")] = len(rows) + 4  # D6 below
            rows += [(0, bogie, lat_up, lat_low, 1, p.k4, 0.0, 0.0), (0, bogie, lat_up, lat_low, 1, 0.0, p.D2, 0.0),
                     (0, bogie, ver_up, ver_low, 2, p.k5, 0.0, sec_load),
                     (0, bogie, ver_up, ver_low, 2, 0.0, p.D1, 0.0),
                     (0, bogie, yaw_up, yaw_low, 0, 0.0, p.D6, 0.0), (0, bogie, yaw_up, yaw_low, 0, p.k6, 0.0, 0.0)]
        for wheelset, ahead in ((2 * bogie + 1, 1.0), (2 * bogie + 2, -1.0)):
            rows += _primary_rows(p, bogie, wheelset, ahead, prim_load)
    return _links_from_rows(p, rows, [yaw[name] for name in YAW_DAMPER_NAMES])


def _primary_rows(p: CooperriderParams, bogie: int, wheelset: int, ahead: float, load: float) -> list:
    rows = []
    for s in (1.0, -1.0):
        lat = ((ahead * p.u2, s * (p.a + p.l1), -p.h1), (0.0, s * p.a, 0.0))
        ver = ((ahead * p.u2, s * p.s1, p.v1), (0.0, s * p.s1, 0.0))
        lon = ((ahead * p.x1, s * p.s1, -p.h1), (0.0, s * p.s1, 0.0))
        rows += [(bogie, wheelset, *lat, 1, p.k1, 0.0, 0.0), (bogie, wheelset, *ver, 2, p.k3, 0.0, load),
                 (bogie, wheelset, *lon, 0, p.k2, 0.0, 0.0)]
        rows += [(bogie, wheelset, *pts, -1, 0.0, c, 0.0) for pts, c in ((lat, p.D5), (ver, p.D4), (lon, p.D3)) if c]
    return rows


def _links_from_rows(p: CooperriderParams, rows: list, yaw_dampers: list) -> Links:
    centres = body_centres(p)
    upper = np.array([r[0] for r in rows])
    lower = np.array([r[1] for r in rows])
    p_up = np.array([r[2] for r in rows], dtype=float)
    p_low = np.array([r[3] for r in rows], dtype=float)
    rest = centres[upper] + p_up - centres[lower] - p_low
    return Links(upper=upper, lower=lower, p_up=p_up, p_low=p_low, axis=np.array([r[4] for r in rows]),
                 rest=rest, k=np.array([r[5] for r in rows], dtype=float),
                 c=np.array([r[6] for r in rows], dtype=float), preload=np.array([r[7] for r in rows], dtype=float),
                 yaw_dampers=np.array(yaw_dampers, dtype=int))


def _point_maps(links: Links) -> tuple:
    """Linear maps (n, 3, 31) from the positions ``q`` to the change of the vector lower->upper
    point of each link, and (n, 3, 31) from ``q`` to the upper/lower body's small-rotation vector
    ``(phi, chi, psi)``: a point ``p`` of a body moves by ``(0, y, z) + w x p``."""
    n = links.k.size
    A = np.zeros((n, 3, N_POS))
    rot_up, rot_low = np.zeros((n, 3, N_POS)), np.zeros((n, 3, N_POS))
    for body, p, sign, rot in ((links.upper, links.p_up, 1.0, rot_up), (links.lower, links.p_low, -1.0, rot_low)):
        for j, coord in enumerate(_COORDS):
            cols = _POS_MAP[body, j]
            rows = np.nonzero(cols >= 0)[0]
            unit = np.zeros((rows.size, 3))
            if j < 2:                                           # translation y or z
                unit[:, j + 1] = 1.0
            else:                                               # rotation about x, y or z
                rot[rows, j - 2, cols[rows]] = 1.0
                axis = np.zeros((rows.size, 3))
                axis[:, j - 2] = 1.0
                unit = np.cross(axis, p[rows])
            A[rows, :, cols[rows]] += sign * unit
    return A, rot_up, rot_low


@dataclass(frozen=True)
class WheelForces:
    """Forces of the rails on the wheels, index [wheel (0 left, 1 right), wheelset, car]:
    ``creep`` (3, 2, 4, m) [N] the saturated creep force in the track frame (x, y, z), ``normal``
    (2, 2, 4, m) [N] the normal force's lateral and vertical components, and the moments [N m] they
    exert on the wheelset about its roll (``roll``) and yaw (``yaw``) axes and about its axle
    (``spin``, driving the spin perturbation)."""

    creep: np.ndarray
    normal: np.ndarray
    roll: np.ndarray
    yaw: np.ndarray
    spin: np.ndarray


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product along axis 1 of (n, 3, m) arrays (broadcasting)."""
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=1)


class CooperriderCar:
    """Equations of motion of the car at speed ``speed`` [m/s] on straight track (see module doc).

    ``params``: :class:`CooperriderParams`; ``table``: the contact table (:func:`read_contact_table`);
    ``speed``: one speed, or an array of m speeds for a batch of m cars integrated together.
    :meth:`rhs` gives ``dx/dt`` for the 66-state vector, or for a batch (66, m) of them (one car per
    column: the cars' speeds, or one speed for finite-difference Jacobians); it raises
    :class:`campaign.contact_table.ContactTableError` when a wheelset leaves the table (derailment).
    """

    def __init__(self, params: CooperriderParams, table: ContactTable, speed):
        speed = np.asarray(speed, dtype=float)
        if speed.ndim > 1 or not np.all(speed > 0.0):
            raise ValueError(f"speed must be a number or 1-d array of numbers > 0 m/s, got {speed!r}")
        self.params = params
        self.table = table
        self.speed = speed
        self.links = build_links(params)
        self._A, self._rot_up, self._rot_low = _point_maps(self.links)
        self.r0_table = float(table.evaluate(0.0)[table.column("rw")])
        p = params
        self.mass = np.array([p.car_mass, p.bogie_mass, p.bogie_mass] + [p.wheelset_mass] * 4)
        inertia = np.array([p.car_inertia, p.bogie_inertia, p.bogie_inertia] + [p.wheelset_inertia] * 4)
        # the simulator divides the pitch equation of car body and bogies by the roll inertia
        self.inertia = np.column_stack([inertia[:, 0], inertia[:, 0], inertia[:, 2]])
        self.spin_inertia = p.wheelset_inertia[1]
        self._cols = [table.column(n) for n in ("N", "angle", "a", "b", "aw", "rw", "c11", "c22", "c23", "qN")]
        L = self.links
        self._incidence = np.zeros((N_BODIES, L.k.size))
        np.add.at(self._incidence, (L.lower, np.arange(L.k.size)), 1.0)
        self._incidence_up = np.zeros((N_BODIES, L.k.size))
        np.add.at(self._incidence_up, (L.upper, np.arange(L.k.size)), 1.0)
        self._net = self._incidence - self._incidence_up
        self._A2 = self._A.reshape(-1, N_POS)
        self._rot_low2 = self._rot_low.reshape(-1, N_POS)
        self._rot_up2 = self._rot_up.reshape(-1, N_POS)
        self._on_axis = np.nonzero(L.axis >= 0)[0]
        self._along = np.nonzero(L.axis < 0)[0]
        self._yaw_sign = np.sign(L.rest[L.yaw_dampers, 0])[:, None]
        self._yaw_map = self._yaw_sign * self._A[L.yaw_dampers, 0, :]

    def yaw_damper_strokes(self, x: np.ndarray) -> tuple:
        """Elongations [m] and their rates [m/s], (4, m) each, of the yaw dampers (:data:`YAW_DAMPER_NAMES`
        order) at the states ``x`` (66, m): the change of the distance between the bogie's and the car body's
        attachment points along the track (x), positive in extension (the points moving apart)."""
        return self._yaw_map @ x[:N_POS], self._yaw_map @ x[N_POS:2 * N_POS]

    def yaw_damper_acceleration(self, dx: np.ndarray) -> np.ndarray:
        """Rates [m/s^2] (4, m) of the yaw dampers' elongation rates from ``dx`` = :meth:`rhs` (66, m)."""
        return self._yaw_map @ dx[N_POS:2 * N_POS]

    def body_states(self, x: np.ndarray) -> tuple:
        """Positions and rates (7, 5, m) of every body (``y, z, phi, chi, psi``; wheelset pitch 0)
        for states ``x`` (66, m)."""
        mask = (_POS_MAP >= 0)[..., None]
        pos = np.where(mask, x[np.maximum(_POS_MAP, 0)], 0.0)
        vel = np.where(mask, x[N_POS + np.maximum(_POS_MAP, 0)], 0.0)
        return pos, vel

    def suspension(self, q: np.ndarray, qd: np.ndarray, damper_forces: np.ndarray | None = None) -> tuple:
        """Forces and moments (7, 3, m) [N], [N m] of all links on all bodies (track-frame forces,
        body-axis moments) at positions ``q`` and rates ``qd`` (31, m). ``damper_forces`` (4, m) [N]:
        forces of the yaw dampers (:data:`YAW_DAMPER_NAMES` order), tension positive (pulling the bogie's
        and the car body's points together), applied where the ``D6`` dashpots act, in addition to them."""
        L = self.links
        n, m = L.k.size, q.shape[1]
        d = (self._A2 @ q).reshape(n, 3, m)
        v = (self._A2 @ qd).reshape(n, 3, m)
        F = np.zeros_like(d)
        k = self._on_axis
        ax = L.axis[k]
        F[k, ax] = L.k[k, None] * d[k, ax] + L.c[k, None] * v[k, ax] + L.preload[k, None]
        if damper_forces is not None:                           # on the bogie: towards the car body's point
            F[L.yaw_dampers, 0] += self._yaw_sign * damper_forces
        if self._along.size:
            j = self._along
            vec = L.rest[j][..., None] + d[j]
            u = vec / np.linalg.norm(vec, axis=1, keepdims=True)
            F[j] = L.c[j, None, None] * np.sum(v[j] * u, axis=1, keepdims=True) * u
        w_low = (self._rot_low2 @ q).reshape(n, 3, m)
        w_up = (self._rot_up2 @ q).reshape(n, 3, m)
        m_low = _cross(L.p_low[..., None], F - _cross(w_low, F))
        m_up = _cross(L.p_up[..., None], _cross(w_up, F) - F)
        force = (self._net @ F.reshape(n, 3 * m)).reshape(N_BODIES, 3, m)
        moment = (self._incidence @ m_low.reshape(n, 3 * m) + self._incidence_up @ m_up.reshape(n, 3 * m))
        return force, moment.reshape(N_BODIES, 3, m)

    def wheel_forces(self, pos: np.ndarray, vel: np.ndarray, beta: np.ndarray) -> "WheelForces":
        """Forces of the rails on each wheel (left, right) of the four wheelsets, (2, 4, m) each,
        from the wheelsets' positions and rates (``pos``, ``vel`` (7, 5, m) of :meth:`body_states`)
        and spin perturbations ``beta`` (4, m) [rad/s]; see :class:`WheelForces`."""
        y, z, phi, psi = pos[3:, 0], pos[3:, 1], pos[3:, 2], pos[3:, 4]
        yd, zd, phid, psid = vel[3:, 0], vel[3:, 1], vel[3:, 2], vel[3:, 4]
        s = np.array([1.0, -1.0])[:, None, None]                # left (+y) and right wheel
        tab = self.table.evaluate(s * y)                        # (2, 4, m, 12)
        N0, delta, ca, cb, aw, rw, c11, c22, c23, qN = (tab[..., k] for k in self._cols)
        roll = s * phi
        dprime = delta + roll
        ry = (rw - np.tan(roll) * aw) * np.sin(roll) + aw / np.cos(phi) + s * y
        dq = -(ry - s * y - aw - s * phi * rw) * np.sin(dprime) + (-z - s * phi * aw) * np.cos(dprime)
        base = 1.0 + dq / qN
        N = np.where(base > 0.0, N0 * np.maximum(base, 0.0) ** 1.5, 0.0)
        shrink = np.cbrt(N / N0)
        ab = ca * cb * shrink * shrink
        V, omega = self.speed, self.speed / self.r0_table + beta
        xi_x = (V + psi * yd + rw * (psi * phid - omega) - s * aw * psid) / V
        xi_y = ((-V * psi + phi * zd + yd + phid * rw) * np.cos(delta)
                + s * (-phi * yd + zd + s * aw * phid) * np.sin(delta)) / V
        xi_s = (-s * (omega - psi * phid) * np.sin(delta) + psid * np.cos(delta)) / V
        G = self.params.shear_modulus
        fx = -ab * G * c11 * xi_x
        fy = -ab * G * (c22 * xi_y + np.sqrt(ab) * c23 * xi_s)
        limit = self.params.mu * N
        loaded = limit > 0.0
        factor = np.where(loaded, saturation_factor(np.hypot(fx, fy) / np.where(loaded, limit, 1.0)), 0.0)
        fx, fy = factor * fx, factor * fy
        Fx = fx - fy * psi * np.cos(delta)
        Fy = fx * psi + fy * np.cos(dprime)
        Fz = s * fy * np.sin(dprime)
        Ny, Nz = -s * N * np.sin(dprime), N * np.cos(dprime)
        lever = Fx + (Fy + Ny) * psi
        return WheelForces(creep=np.stack([Fx, Fy, Fz]), normal=np.stack([Ny, Nz]),
                           roll=s * aw * (Fz + Nz - (Fy + Ny) * phi), yaw=-s * aw * lever, spin=-rw * lever)

    def rhs(self, t: float, x: np.ndarray, damper_forces: np.ndarray | None = None) -> np.ndarray:
        """``dx/dt`` of the state ``x`` (66,) or (66, m) at time ``t`` [s] (autonomous: ``t`` unused);
        ``damper_forces`` (4,) or (4, m) [N]: yaw damper forces added to the ``D6`` dashpots' (see
        :meth:`suspension`; zero ``D6`` in the parameters to replace them)."""
        single = x.ndim == 1
        x = x[:, None] if single else x
        if damper_forces is not None and single:
            damper_forces = np.asarray(damper_forces, dtype=float)[:, None]
        pos, vel = self.body_states(x)
        beta = x[2 * N_POS:]
        force, moment = self.suspension(x[:N_POS], x[N_POS:2 * N_POS], damper_forces)
        wf = self.wheel_forces(pos, vel, beta)
        force[3:, 1] += (wf.creep[1] + wf.normal[0]).sum(0)
        force[3:, 2] += (wf.creep[2] + wf.normal[1]).sum(0)
        m_roll, m_yaw, m_spin = wf.roll.sum(0), wf.yaw.sum(0), wf.spin.sum(0)
        p = self.params
        omega = self.speed / self.r0_table + beta
        jx, jy, jz = p.wheelset_inertia
        moment[3:, 0] += m_roll + (jy - jz) * omega * vel[3:, 4]
        moment[3:, 2] += m_yaw + (jx - jy) * vel[3:, 2] * omega
        force[:, 2] -= (self.mass * p.gravity)[:, None]
        acc = np.concatenate([force[:, 1:3] / self.mass[:, None, None], moment / self.inertia[..., None]], axis=1)
        out = np.empty_like(x)
        out[:N_POS] = x[N_POS:2 * N_POS]
        valid = _POS_MAP >= 0
        out[N_POS + _POS_MAP[valid]] = acc[valid]
        out[2 * N_POS:] = m_spin / self.spin_inertia
        return out[:, 0] if single else out
