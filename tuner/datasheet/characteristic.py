"""The simulated datasheet of one damper FMU: its force-velocity and dynamic characteristics from settled sines.

* Force-velocity characteristic (the practice of EN 13802 acceptance tests): one sine of stroke amplitude
  ``fv_amplitude_m`` per peak velocity v (frequency v / (2 pi A)); the force at the peak extension velocity
  (+v) and at the peak compression velocity (-v) of the settled loop.
* Dynamic characteristic: one sine per frequency and amplitude; first-harmonic K', K'', |K*|, loss angle,
  equivalent Maxwell k and c, the force's harmonic distortion (``tuner.datasheet.loop``).
* The series stiffness a multibody code takes beside the force-velocity table (a table dashpot in series with
  a spring): the median equivalent Maxwell k of the dynamic points where the elasticity carries the larger
  part of the force (loss angle below 45 deg; all points when none is), where k is best determined.

Every point is simulated (``source`` 'simulated' in the datasheet); settled or not is recorded per point.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tuner.datasheet.loop import LoopQuantities
from tuner.datasheet.sine_runs import SineDriver, SineSettings

__all__ = ["DatasheetSettings", "ForceVelocityPoint", "DynamicPoint", "FmuCharacteristic", "fmu_characteristic",
           "series_stiffness", "DEFAULT_PEAK_VELOCITIES", "DEFAULT_FREQUENCIES", "DEFAULT_AMPLITUDES"]

#: peak velocities [m/s] of the force-velocity characteristic (10 per direction, 0.005-0.3 m/s)
DEFAULT_PEAK_VELOCITIES = (0.005, 0.01, 0.02, 0.03, 0.05, 0.075, 0.1, 0.15, 0.2, 0.3)
#: frequencies [Hz] of the dynamic characteristic
DEFAULT_FREQUENCIES = (0.5, 1.0, 2.0, 3.0, 5.0, 7.0, 10.0, 15.0, 20.0)
#: stroke amplitudes [m] of the dynamic characteristic (a yaw damper hunts at 0.5-2 mm)
DEFAULT_AMPLITUDES = (0.5e-3, 1e-3, 2e-3, 5e-3)
#: stroke amplitude [m] of the force-velocity sines
DEFAULT_FV_AMPLITUDE = 25e-3
#: loss angle [deg] below which a dynamic point's equivalent k counts for the series stiffness
SPRING_DOMINATED_DEG = 45.0


@dataclass(frozen=True)
class DatasheetSettings:
    """What the datasheet runs: ``peak_velocities_m_s`` (> 0; each gives an extension and a compression point),
    ``fv_amplitude_m`` [m], ``frequencies_hz`` [Hz], ``amplitudes_m`` [m], and the sine runs' ``sine``."""

    peak_velocities_m_s: tuple = DEFAULT_PEAK_VELOCITIES
    fv_amplitude_m: float = DEFAULT_FV_AMPLITUDE
    frequencies_hz: tuple = DEFAULT_FREQUENCIES
    amplitudes_m: tuple = DEFAULT_AMPLITUDES
    sine: SineSettings = field(default_factory=SineSettings)

    def check(self) -> None:
        """ValueError naming the setting (and its command-line option) that cannot be used."""
        for name, option, values in (("peak velocities", "--velocities", self.peak_velocities_m_s),
                                     ("frequencies", "--frequencies", self.frequencies_hz),
                                     ("amplitudes", "--amplitudes", self.amplitudes_m)):
            if not values or not all(math.isfinite(v) and v > 0 for v in values):
                raise ValueError(f"datasheet: {name} ({option}) must be positive numbers, got {list(values)}")
        if not (math.isfinite(self.fv_amplitude_m) and 0 < self.fv_amplitude_m <= 0.5):
            raise ValueError(f"datasheet: the force-velocity stroke amplitude (--fv-amplitude) must be in (0, 500] mm, "
                             f"got {self.fv_amplitude_m * 1e3:g} mm")
        self.sine.check()

    def to_dict(self) -> dict:
        """The settings as the datasheet records them (SI units in the keys)."""
        s = self.sine
        return {"peak_velocities_m_s": list(self.peak_velocities_m_s), "fv_amplitude_m": self.fv_amplitude_m,
                "frequencies_hz": list(self.frequencies_hz), "amplitudes_m": list(self.amplitudes_m),
                "max_step_s": s.max_step_s, "min_samples_per_period": s.min_samples, "periods": s.periods,
                "max_periods": s.max_periods, "settle_tolerance": s.settle_tolerance}


@dataclass(frozen=True)
class ForceVelocityPoint:
    """The force ``force_n`` [N] at peak velocity ``velocity_m_s`` [m/s] (signed: > 0 extension), of a sine of
    ``frequency_hz`` [Hz] and ``amplitude_m`` [m]; ``settled`` as ``SettledLoop``."""

    direction: str
    velocity_m_s: float
    force_n: float
    frequency_hz: float
    amplitude_m: float
    settled: bool

    def to_dict(self) -> dict:
        return {**{k: getattr(self, k) for k in self.__dataclass_fields__}, "source": "simulated"}


@dataclass(frozen=True)
class DynamicPoint:
    """One dynamic point: its loop's ``quantities`` at the nominal ``frequency_hz`` and ``amplitude_m``."""

    frequency_hz: float
    amplitude_m: float
    quantities: LoopQuantities
    settled: bool

    def to_dict(self) -> dict:
        q = self.quantities.to_dict()
        keep = ("storage_n_m", "loss_n_m", "dynamic_stiffness_n_m", "loss_angle_deg", "maxwell_k_n_m",
                "maxwell_c_n_s_m", "distortion")
        return {"frequency_hz": self.frequency_hz, "amplitude_m": self.amplitude_m, **{k: q[k] for k in keep},
                "settled": self.settled, "source": "simulated"}


@dataclass
class FmuCharacteristic:
    """The simulated datasheet of the FMU at ``fmu``: ``force_velocity`` (compression then extension, by
    velocity), ``dynamic`` (by amplitude, then frequency), ``series_stiffness_n_m`` [N/m], ``seconds`` [s] wall."""

    fmu: Path
    force_velocity: list
    dynamic: list
    series_stiffness_n_m: float
    seconds: float

    def to_dict(self) -> dict:
        return {"fmu": str(self.fmu), "series_stiffness_n_m": self.series_stiffness_n_m,
                "series_stiffness_basis": f"median equivalent Maxwell k of the dynamic points with a loss angle "
                                          f"below {SPRING_DOMINATED_DEG:g} deg (of all when none is)",
                "force_velocity": [p.to_dict() for p in self.force_velocity],
                "dynamic": [p.to_dict() for p in self.dynamic], "seconds": self.seconds}


def series_stiffness(points: list) -> float:
    """The series stiffness [N/m] of the module docstring from ``DynamicPoint``s (inf when none has a finite k)."""
    spring = [p.quantities.maxwell_k_n_m for p in points if p.quantities.loss_angle_deg < SPRING_DOMINATED_DEG]
    ks = [k for k in (spring or [p.quantities.maxwell_k_n_m for p in points]) if math.isfinite(k)]
    return float(np.median(ks)) if ks else math.inf


def fmu_characteristic(fmu: Path, settings: DatasheetSettings = DatasheetSettings(), driver: SineDriver | None = None,
                       log=print) -> FmuCharacteristic:
    """The simulated datasheet of the damper FMU ``fmu`` (module docstring), on ``driver`` when given (its FMU
    instance reused) or on one opened and closed here."""
    settings.check()
    t0 = time.perf_counter()
    own = driver is None
    driver = SineDriver(fmu, settings.sine) if own else driver
    try:
        fv = []
        for v in sorted(settings.peak_velocities_m_s):
            a = settings.fv_amplitude_m
            loop = driver.settled(v / (2 * np.pi * a), a)
            q = loop.quantities
            fv += [ForceVelocityPoint("extension", q.peak_velocity_m_s, q.force_extension_n, q.frequency_hz, a,
                                      loop.settled),
                   ForceVelocityPoint("compression", -q.peak_velocity_m_s, q.force_compression_n, q.frequency_hz, a,
                                      loop.settled)]
        dyn = [DynamicPoint(f, a, (loop := driver.settled(f, a)).quantities, loop.settled)
               for a in sorted(settings.amplitudes_m) for f in sorted(settings.frequencies_hz)]
    finally:
        if own:
            driver.close()
    fv.sort(key=lambda p: p.velocity_m_s)
    unsettled = sum(not p.settled for p in fv) // 2 + sum(not p.settled for p in dyn)
    if unsettled:
        log(f"datasheet: {Path(fmu).name}: {unsettled} sine run(s) not settled within "
            f"{settings.sine.max_periods} periods (marked 'settled': false)")
    return FmuCharacteristic(Path(fmu), fv, dyn, series_stiffness(dyn), time.perf_counter() - t0)
