"""Effect sizes relative to the damper tested: the typical ranges of the catalogue, scaled.

The catalogue's typical magnitudes (``damper_fmu.effect_catalogue``, ``Effect.typical``: friction 50-300 N, an
inertia of 20-200 kg, a free play of 0.1-1 mm ...) are those of a railway yaw damper: peak forces of
about ``REFERENCE.peak_force_n`` on strokes of about ``REFERENCE.stroke_range_m``. On a damper 30 times
smaller the same rule would refuse every cause (a 2.35 kg inertia that removed 24 % of a 600 N damper's
held-out error was refused as "below 10 kg"). So the ranges scale with the damper the data show:

* forces (friction, preload, pre-yield hysteresis) and the equivalent mass (its force m x'' is a share
  of the damper's force) with the measured peak force: x peak_force / REFERENCE.peak_force_n;
* lengths (free play, the hysteresis displacement) with the stroke range, never above the catalogue's:
  x min(1, stroke_range / REFERENCE.stroke_range_m) (a clearance does not grow with a longer stroke);
* times (valve lag, channel delay), the thermal coefficient and the bypass ratio are not sizes of the
  damper: unchanged.

Which parameter scales how is part of its effect's record (``Effect.scaling``: ``SCALES_WITH_FORCE``,
``SCALES_WITH_STROKE``).

The typical range is what dampers usually have, not a hard limit: a magnitude is plausible within
``MEANINGFUL_FRACTION`` of the low end and ``1 / MEANINGFUL_FRACTION`` of the high end of its scaled range
(``plausible_range``). Below it, it is no physical cause (``meaningful_floor``: a refit compensating something
else); an interval wholly above it patches another error (a form gap). Within the margin above the top it is a
large but real fault (a 231 N friction on a damper whose range ends at 232 N, fitted at 245 N beside a free play,
was refused without it). The report shows the plausible range beside the fitted value.
"""
from __future__ import annotations

from dataclasses import dataclass

from damper_fmu.effect_catalogue import SCALES_WITH_FORCE, SCALES_WITH_STROKE, effect_of

from tuner.identification.damper_scale import REFERENCE_SCALE

__all__ = ["DamperSize", "REFERENCE", "MEANINGFUL_FRACTION", "size_factor", "typical_range", "plausible_range",
           "meaningful_floor"]

#: a magnitude below this fraction of the low end of its (scaled) typical range is no physical cause (a 0.2
#: ms valve lag where valves lag 1-10 ms is the refit compensating something else); one above the high end
#: divided by it is no value of the effect either (``plausible_range``)
MEANINGFUL_FRACTION = 0.5


@dataclass(frozen=True)
class DamperSize:
    """The size of a damper as its tests show it: peak |force| [N] and stroke range [m]."""

    peak_force_n: float
    stroke_range_m: float


#: the railway yaw damper the catalogue's typical magnitudes describe (the paper's, and the bundled
#: campaign's: peaks of 15-25 kN, quasi-static curve strokes of tens of mm): the one the models' bounds and fixed
#: constants are set for too (``tuner.identification.damper_scale.REFERENCE_SCALE``)
REFERENCE = DamperSize(peak_force_n=REFERENCE_SCALE.peak_force_n, stroke_range_m=REFERENCE_SCALE.stroke_range_m)


def size_factor(name: str, size: DamperSize | None) -> float:
    """The factor on the catalogue's typical range of parameter ``name`` for a damper of ``size`` (module
    docstring); 1 for the reference damper, for no size given, and for parameters that are no size."""
    if size is None:
        return 1.0
    scaling = effect_of(name).scaling.get(name)
    if scaling == SCALES_WITH_FORCE:
        return size.peak_force_n / REFERENCE.peak_force_n
    if scaling == SCALES_WITH_STROKE:
        return min(1.0, size.stroke_range_m / REFERENCE.stroke_range_m)
    return 1.0


def typical_range(name: str, size: DamperSize | None = None) -> tuple[float, float]:
    """Typical |value| (SI) of effect parameter ``name`` on a damper of ``size`` (the catalogue's range
    scaled, ``size_factor``)."""
    lo, hi = effect_of(name).typical[name]
    k = size_factor(name, size)
    return lo * k, hi * k


def plausible_range(name: str, size: DamperSize | None = None) -> tuple[float, float]:
    """The |values| (SI) of effect parameter ``name`` that are physical values of its effect on a damper of
    ``size``: its typical range widened by ``MEANINGFUL_FRACTION`` below and by its inverse above."""
    lo, hi = typical_range(name, size)
    return MEANINGFUL_FRACTION * lo, hi / MEANINGFUL_FRACTION


def meaningful_floor(name: str, size: DamperSize | None = None) -> float:
    """The smallest |value| (SI) of ``name`` that is a physical cause on a damper of ``size``."""
    return plausible_range(name, size)[0]
