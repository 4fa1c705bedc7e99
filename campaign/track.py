"""Design track geometry: straights, clothoids and constant curves.

Conventions (SI units throughout):

* ``s`` [m] is the distance along the track centreline.
* Curvature ``kappa`` [1/m] is signed: positive for a left-hand curve (the track turns
  towards +y, y pointing to the left of the direction of travel).
* Cant ``h`` [m] is the height difference between the rails, signed like the curvature:
  positive raises the right rail (the proper cant of a left-hand curve).
* In a clothoid (transition) section curvature and cant vary linearly with ``s``.
* Before ``s = 0`` the track is straight without cant; after its end it continues with
  the final curvature and cant.

Besides curvature and cant the track gives the heading ``theta(s) = int kappa ds`` [rad]
and the small-angle lateral position ``Y(s) = int theta ds`` [m]. Only differences of
``theta`` and ``Y`` over a vehicle length are used by the vehicle model, where they are the
local (linearised) geometry of the track relative to a body's tangent.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

GRAVITY = 9.81
"""Gravitational acceleration [m/s^2]."""
CONTACT_BASE = 1.5
"""Distance between the wheel-rail contact points of standard gauge track [m]; the
cant angle is cant / CONTACT_BASE (EN 13803 convention)."""
TRACK_GAUGE = 1.435
"""Standard track gauge [m]."""

_KINDS = ("straight", "clothoid", "curve")
_HANDS = {"left": 1.0, "right": -1.0}


@dataclass(frozen=True)
class Section:
    """One track section; curvature [1/m] and cant [m] vary linearly from start to end."""

    kind: str
    length: float
    curvature_start: float = 0.0
    curvature_end: float = 0.0
    cant_start: float = 0.0
    cant_end: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in _KINDS:
            raise ValueError(f"section kind must be one of {_KINDS}, got {self.kind!r}")
        vals = (self.length, self.curvature_start, self.curvature_end, self.cant_start, self.cant_end)
        if not all(math.isfinite(v) for v in vals):
            raise ValueError(f"section values must be finite, got {vals}")
        if self.length <= 0.0:
            raise ValueError(f"section length must be > 0 m, got {self.length}")
        if self.kind == "straight" and (self.curvature_start or self.curvature_end or self.cant_start or self.cant_end):
            raise ValueError("a straight section has zero curvature and zero cant")
        if self.kind == "curve" and (
            self.curvature_start != self.curvature_end or self.cant_start != self.cant_end
        ):
            raise ValueError("a constant curve has equal start and end curvature and cant")


def _curvature(radius: float, hand: str) -> float:
    if hand not in _HANDS:
        raise ValueError(f"hand must be 'left' or 'right', got {hand!r}")
    if radius is None or math.isinf(radius):
        return 0.0
    if not radius > 0.0:
        raise ValueError(f"radius must be > 0 m (or inf for straight), got {radius}")
    return _HANDS[hand] / radius


def straight(length: float) -> Section:
    """Straight section of ``length`` [m]."""
    return Section("straight", float(length))


def curve(length: float, radius: float, cant: float = 0.0, hand: str = "left") -> Section:
    """Constant curve: ``length`` [m], ``radius`` [m] > 0, ``cant`` [m] >= 0 (raised outer
    rail), ``hand`` 'left' or 'right'."""
    if cant < 0.0:
        raise ValueError(f"cant must be >= 0 m (outer rail raised), got {cant}")
    k = _curvature(radius, hand)
    h = _HANDS[hand] * cant
    return Section("curve", float(length), k, k, h, h)


def clothoid(
    length: float,
    radius_from: float = math.inf,
    radius_to: float = math.inf,
    cant_from: float = 0.0,
    cant_to: float = 0.0,
    hand: str = "left",
) -> Section:
    """Clothoid transition of ``length`` [m]: curvature goes linearly from 1/``radius_from``
    to 1/``radius_to`` [m] (inf = straight) and cant linearly from ``cant_from`` to
    ``cant_to`` [m], both >= 0, on a ``hand`` curve."""
    if cant_from < 0.0 or cant_to < 0.0:
        raise ValueError(f"cant must be >= 0 m, got {cant_from}, {cant_to}")
    sign = _HANDS.get(hand)
    return Section(
        "clothoid",
        float(length),
        _curvature(radius_from, hand),
        _curvature(radius_to, hand),
        (sign or 1.0) * cant_from,
        (sign or 1.0) * cant_to,
    )


def curve_with_transitions(
    radius: float,
    cant: float,
    lead_in: float,
    transition: float,
    arc: float,
    lead_out: float,
    hand: str = "left",
) -> list[Section]:
    """Straight ``lead_in`` -> clothoid ``transition`` -> curve ``arc`` -> clothoid
    ``transition`` -> straight ``lead_out`` (lengths [m], radius [m], cant [m])."""
    return [
        straight(lead_in),
        clothoid(transition, math.inf, radius, 0.0, cant, hand),
        curve(arc, radius, cant, hand),
        clothoid(transition, radius, math.inf, cant, 0.0, hand),
        straight(lead_out),
    ]


def s_curve_switch(
    lead_in: float,
    lead_out: float,
    radius: float = 190.0,
    arc: float = 21.0,
    intermediate: float = 6.0,
    first_hand: str = "left",
) -> list[Section]:
    """S-curve of a crossover (EN 14363 annex F style): straight ``lead_in`` -> curve
    ``radius`` of length ``arc`` -> straight ``intermediate`` -> curve of the opposite hand
    -> straight ``lead_out``. No cant, no transitions (curvature steps as in a turnout).

    Defaults: R 190 m, arc 21 m (about the 6.3 deg diverging angle of a 1:9 turnout),
    6 m intermediate straight. Lengths [m]."""
    if first_hand not in _HANDS:
        raise ValueError(f"first_hand must be 'left' or 'right', got {first_hand!r}")
    second = "right" if first_hand == "left" else "left"
    return [
        straight(lead_in),
        curve(arc, radius, 0.0, first_hand),
        straight(intermediate),
        curve(arc, radius, 0.0, second),
        straight(lead_out),
    ]


class Track:
    """Piecewise track geometry built from a sequence of :class:`Section`.

    All methods are vectorised over ``s`` [m] (scalar or array)."""

    def __init__(self, sections):
        sections = list(sections)
        if not sections:
            raise ValueError("a track needs at least one section")
        for sec in sections:
            if not isinstance(sec, Section):
                raise ValueError(f"track sections must be Section instances, got {type(sec).__name__}")
        self.sections = tuple(sections)
        n = len(sections)
        self._start = np.zeros(n)
        self._len = np.array([sec.length for sec in sections])
        self._k0 = np.array([sec.curvature_start for sec in sections])
        self._k1 = np.array([sec.curvature_end for sec in sections])
        self._h0 = np.array([sec.cant_start for sec in sections])
        self._h1 = np.array([sec.cant_end for sec in sections])
        self._start[1:] = np.cumsum(self._len)[:-1]
        # heading and lateral position at section starts (exact integrals of the polynomials)
        self._th0 = np.zeros(n)
        self._y0 = np.zeros(n)
        for i in range(1, n):
            L, k0, k1 = self._len[i - 1], self._k0[i - 1], self._k1[i - 1]
            self._th0[i] = self._th0[i - 1] + k0 * L + (k1 - k0) * L / 2.0
            self._y0[i] = self._y0[i - 1] + self._th0[i - 1] * L + k0 * L**2 / 2.0 + (k1 - k0) * L**2 / 6.0
        L, k0, k1 = self._len[-1], self._k0[-1], self._k1[-1]
        self._th_end = self._th0[-1] + k0 * L + (k1 - k0) * L / 2.0
        self._y_end = self._y0[-1] + self._th0[-1] * L + k0 * L**2 / 2.0 + (k1 - k0) * L**2 / 6.0

    @property
    def length(self) -> float:
        """Total length of the defined sections [m]."""
        return float(self._start[-1] + self._len[-1])

    @property
    def boundaries(self) -> np.ndarray:
        """Section start positions followed by the track end [m] (n_sections + 1 values)."""
        return np.append(self._start, self.length)

    def _locate(self, s):
        s = np.asarray(s, dtype=float)
        if not np.all(np.isfinite(s)):
            raise ValueError("track position s must be finite")
        idx = np.clip(np.searchsorted(self._start, s, side="right") - 1, 0, len(self._len) - 1)
        u = s - self._start[idx]
        return s, idx, u

    def curvature(self, s):
        """Signed curvature [1/m] at ``s`` [m] (positive = left-hand)."""
        s, i, u = self._locate(s)
        k = self._k0[i] + (self._k1[i] - self._k0[i]) * np.clip(u / self._len[i], 0.0, 1.0)
        return np.where(s < 0.0, 0.0, k)

    def cant(self, s):
        """Signed cant [m] at ``s`` [m] (positive = right rail raised)."""
        s, i, u = self._locate(s)
        h = self._h0[i] + (self._h1[i] - self._h0[i]) * np.clip(u / self._len[i], 0.0, 1.0)
        return np.where(s < 0.0, 0.0, h)

    def cant_angle(self, s):
        """Signed cant angle [rad] = cant / CONTACT_BASE (small angle)."""
        return self.cant(s) / CONTACT_BASE

    def uncompensated_acceleration(self, s, speed: float):
        """Lateral acceleration in the track plane not compensated by cant [m/s^2]:
        ``V^2 kappa - g h / CONTACT_BASE``; positive pushes a body towards -y (outwards
        in a left-hand curve). ``speed`` [m/s]."""
        return speed**2 * self.curvature(s) - GRAVITY * self.cant_angle(s)

    def cant_deficiency(self, s, speed: float):
        """Cant deficiency [m]: equilibrium cant ``CONTACT_BASE V^2 kappa / g`` minus the
        actual cant, signed like the curvature. ``speed`` [m/s]."""
        return CONTACT_BASE * self.uncompensated_acceleration(s, speed) / GRAVITY

    def heading(self, s):
        """Track heading ``theta(s) = int_0^s kappa`` [rad] (0 on the lead-in)."""
        s, i, u = self._locate(s)
        L, k0, k1 = self._len[i], self._k0[i], self._k1[i]
        uc = np.clip(u, 0.0, L)
        th = self._th0[i] + k0 * uc + (k1 - k0) * uc**2 / (2.0 * L)
        beyond = s > self.length
        th = np.where(beyond, self._th_end + self._k1[-1] * (s - self.length), th)
        return np.where(s < 0.0, 0.0, th)

    def lateral(self, s):
        """Small-angle lateral position ``Y(s) = int_0^s theta`` [m]."""
        s, i, u = self._locate(s)
        L, k0, k1 = self._len[i], self._k0[i], self._k1[i]
        uc = np.clip(u, 0.0, L)
        y = self._y0[i] + self._th0[i] * uc + k0 * uc**2 / 2.0 + (k1 - k0) * uc**3 / (6.0 * L)
        d = s - self.length
        beyond = d > 0.0
        y = np.where(beyond, self._y_end + self._th_end * d + self._k1[-1] * d**2 / 2.0, y)
        return np.where(s < 0.0, 0.0, y)
