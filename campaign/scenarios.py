"""The six manoeuvres of the paper (Table 1) and the front-right yaw damper stroke.

Section lengths are chosen from the vehicle speed so that the front bogie reaches the
first transition ``T_LEAD`` = 2 s after the start and each test lasts 10-21 s (validation 3
reproduces the paper's transitions at about 2-8 s and 13-19 s). At t = 0 the rear wheelset
is at s = 0 and the carbody centre at ``START_OFFSET`` = L + a = 10 m; the vehicle starts
centred and at rest relative to the straight lead-in, and the irregularity fades in over
the first ``vehicle length + 0.5 s`` of travel to avoid a start-up kick.

Irregularity realisations: identification and validation scenarios draw from separate
streams of one master ``seed``: ``SeedSequence(seed, spawn_key=(role, realisation))``
with role 0 = identification, 1 = validation, so id1 and val1 run on different profiles
and changing the master seed changes all of them.
"""
from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from .irregularity import A_LATERAL, synthesize
from .track import Section, Track, curve_with_transitions, s_curve_switch, straight
from .vehicle import DT_MAX, VehicleModel, VehicleParams

T_LEAD = 2.0
"""Time [s] from the start until the front bogie reaches the first non-straight section."""
ROLES = ("identification", "validation")


@dataclass(frozen=True)
class Scenario:
    """One manoeuvre: constant ``speed_kmh`` [km/h] over ``sections`` for ``duration_s``
    [s]; ``irregular`` adds the lateral alignment realisation number ``realisation`` of the
    ``role`` stream, at ERRI B176 ``irregularity_level`` ('low'|'high')."""

    name: str
    role: str
    description: str
    speed_kmh: float
    sections: tuple[Section, ...]
    irregular: bool
    duration_s: float
    realisation: int = 0
    irregularity_level: str = "low"

    def __post_init__(self) -> None:
        if self.role not in ROLES:
            raise ValueError(f"role must be one of {ROLES}, got {self.role!r}")
        if not (math.isfinite(self.speed_kmh) and self.speed_kmh > 0.0):
            raise ValueError(f"speed_kmh must be > 0, got {self.speed_kmh}")
        if not (math.isfinite(self.duration_s) and self.duration_s > 0.0):
            raise ValueError(f"duration_s must be > 0, got {self.duration_s}")
        if self.irregularity_level not in A_LATERAL:
            raise ValueError(f"irregularity_level must be 'low' or 'high', got {self.irregularity_level!r}")
        if self.realisation < 0:
            raise ValueError(f"realisation must be >= 0, got {self.realisation}")

    @property
    def speed(self) -> float:
        """Speed [m/s]."""
        return self.speed_kmh / 3.6

    def track(self) -> Track:
        """The track geometry of the scenario."""
        return Track(self.sections)

    def time_at(self, s: float, x: float = 0.0) -> float:
        """Time [s] at which the vehicle point at longitudinal position ``x`` [m]
        (relative to the carbody centre, forward positive) passes track position ``s`` [m]."""
        return (s - START_OFFSET - x) / self.speed

    def seed_sequence(self, seed: int = 0) -> np.random.SeedSequence:
        """Seed of this scenario's irregularity from the master ``seed``."""
        return np.random.SeedSequence(seed, spawn_key=(ROLES.index(self.role), self.realisation))


_PARAMS = VehicleParams()
START_OFFSET = _PARAMS.half_bogie_distance + _PARAMS.semi_wheelbase
"""Track position [m] of the carbody centre at t = 0 (rear wheelset at s = 0)."""
_FRONT_BOGIE = _PARAMS.half_bogie_distance


def _lead_in(speed_kmh: float) -> float:
    return START_OFFSET + _FRONT_BOGIE + speed_kmh / 3.6 * T_LEAD


def _curve_case(speed_kmh, radius, cant, t_trans, t_arc, duration):
    V = speed_kmh / 3.6
    lead = _lead_in(speed_kmh)
    t_rest = duration - T_LEAD - 2 * t_trans - t_arc
    return tuple(
        curve_with_transitions(radius, cant, lead, V * t_trans, V * t_arc, V * t_rest + 2 * START_OFFSET + 50.0)
    )


def _straight_case(speed_kmh, duration):
    return (straight(START_OFFSET * 2 + speed_kmh / 3.6 * duration + 50.0),)


SCENARIOS: "OrderedDict[str, Scenario]" = OrderedDict(
    (sc.name, sc)
    for sc in (
        Scenario(
            "id1_straight_250", "identification",
            "Identification 1: straight track at 250 km/h with lateral irregularity",
            250.0, _straight_case(250.0, 10.0), True, 10.0, 0,
        ),
        Scenario(
            "id2_curve_R400_72", "identification",
            "Identification 2: clothoid -> R 400 m, cant 0.06 m -> clothoid at 72 km/h, irregular",
            72.0, _curve_case(72.0, 400.0, 0.06, 4.0, 6.0, 20.0), True, 20.0, 1,
        ),
        Scenario(
            "id3_switch_R190_43", "identification",
            "Identification 3: S-curve switch R 190 m / 6 m straight / R 190 m at 43 km/h, no irregularity",
            43.0, tuple(s_curve_switch(_lead_in(43.0), 120.0)), False, 12.0, 2,
        ),
        Scenario(
            "val1_straight_250", "validation",
            "Validation 1: straight track at 250 km/h, new irregularity realisation",
            250.0, _straight_case(250.0, 10.0), True, 10.0, 0,
        ),
        Scenario(
            "val2_curve_R6000_306", "validation",
            "Validation 2: clothoid -> R 6000 m, cant 0.09 m -> clothoid at 306 km/h, irregular",
            306.0, _curve_case(306.0, 6000.0, 0.09, 4.0, 6.0, 19.0), True, 19.0, 1,
        ),
        Scenario(
            "val3_curve_R500_86", "validation",
            "Validation 3: clothoid -> R 500 m, cant 0.084 m -> clothoid at 86 km/h, irregular",
            86.0, _curve_case(86.0, 500.0, 0.084, 6.0, 5.0, 21.0), True, 21.0, 2,
        ),
    )
)


@dataclass(frozen=True)
class Response:
    """Simulated vehicle response on the output grid ``t`` [s]: ``strokes`` [m],
    ``stroke_velocities`` [m/s] and ``forces`` [N] of the four yaw dampers (columns in
    :data:`campaign.vehicle.DAMPER_NAMES` order), full ``states`` and the model."""

    t: np.ndarray
    strokes: np.ndarray
    stroke_velocities: np.ndarray
    forces: np.ndarray
    states: np.ndarray
    model: VehicleModel


def simulate(
    scenario: Scenario,
    seed: int = 0,
    fs: float = 2000.0,
    t_end: float | None = None,
    params: VehicleParams | None = None,
) -> Response:
    """Run ``scenario`` with master ``seed``, output rate ``fs`` [Hz], optionally stopping
    at ``t_end`` [s] (default: ``scenario.duration_s``) with vehicle ``params``."""
    if not isinstance(scenario, Scenario):
        raise ValueError(f"scenario must be a Scenario, got {type(scenario).__name__}")
    if not (math.isfinite(fs) and fs > 0.0):
        raise ValueError(f"fs must be > 0 Hz, got {fs}")
    T = scenario.duration_s if t_end is None else float(t_end)
    if not (math.isfinite(T) and T > 0.0):
        raise ValueError(f"t_end must be > 0 s, got {t_end}")
    n_out = int(round(T * fs)) + 1
    sub = max(1, math.ceil(1.0 / (fs * DT_MAX) - 1e-9))
    t_fine = np.arange((n_out - 1) * sub + 1) / (fs * sub)
    V = scenario.speed
    model = VehicleModel(params, V)
    track = scenario.track()
    irr = None
    if scenario.irregular:
        length = START_OFFSET + model.p.half_bogie_distance + model.p.semi_wheelbase + V * T + 10.0
        irr = synthesize(
            length,
            scenario.seed_sequence(seed),
            A=A_LATERAL[scenario.irregularity_level],
            taper=2.0 * START_OFFSET + 0.5 * V,
        )
    U = model.inputs(track, irr, START_OFFSET, t_fine)
    X = model.simulate(t_fine, U, model.initial_state(track, START_OFFSET))[::sub]
    strokes, velocities = model.damper_strokes(X)
    return Response(t_fine[::sub], strokes, velocities, X[:, -4:].copy(), X, model)


def damper_stroke(scenario: Scenario, seed: int = 0, fs: float = 2000.0, t_end: float | None = None):
    """Front-right yaw damper stroke of ``scenario``.

    Returns (t [s], stroke [m], stroke_velocity [m/s]) sampled at ``fs`` [Hz] from 0 to
    ``t_end`` [s] (default the scenario duration); stroke positive in extension. ``seed`` is
    the master seed of the irregularity realisations."""
    r = simulate(scenario, seed=seed, fs=fs, t_end=t_end)
    return r.t, r.strokes[:, 0].copy(), r.stroke_velocities[:, 0].copy()
