"""Calibration of a data logger's raw channels: a scale and an offset per channel, and a force tare.

A logger writes the transducers' outputs as they come (volts, mostly). The engineering value of a
stroke, force or velocity channel is ``K x raw + B`` in the unit of that channel's unit option
(``--stroke-unit`` ..., SI by default): ``K`` the transducer's sensitivity, ``B`` an offset in that
unit. A displacement transducer of 10 mm/V: ``--stroke-scale 10 --stroke-unit mm``; a load cell
amplifier of 980.665 N/V: ``--force-scale 980.665 --force-unit N``. A load cell logged without an
amplifier, known by its rated output S [mV/V] at its rated load F with an excitation E [V], has
``K = F / (S / 1000 x E)``. The direction is not a calibration matter: ``K`` must be positive, and
``--stroke-sign``/``--force-sign`` say which way is extension and tension. Unit conversion to SI and
the signs are applied after the calibration, by :mod:`tuner.data.reading`.

The tare (``--force-zero S``) removes the load cell's offset: the mean force over the first S seconds
of a test, where the damper must be at rest (its stroke may move by no more than
``FORCE_ZERO_MAX_MOTION`` of the test's stroke range: a damper that moves makes a force).
"""
from __future__ import annotations

import math

import numpy as np

from damper_dataset.format import DataError

__all__ = ["CALIBRATED", "FORCE_ZERO_MAX_MOTION", "calibration", "apply", "force_zero"]

#: the channels a scale and an offset may be given for
CALIBRATED = ("stroke", "force", "velocity")
#: the largest stroke motion during the --force-zero window, as a share of the test's stroke range
FORCE_ZERO_MAX_MOTION = 0.05


def _number(value, option: str, source: str, positive: bool) -> float:
    """``value`` as a finite float (and > 0 when ``positive``); DataError naming the option otherwise."""
    ok = not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)
    if not ok or (positive and value <= 0):
        what = "a positive finite number" if positive else "a finite number"
        tail = " (the direction is given by the sign option, e.g. --force-sign -1)" if positive and ok else ""
        raise DataError(f"{source}: {option} must be {what}, got {value!r}{tail}")
    return float(value)


def calibration(options: dict, source: str) -> dict:
    """The checked calibration of each channel of ``CALIBRATED``. ``options``: ``'stroke_scale'``,
    ``'stroke_offset'``, ``'force_scale'`` ... -> a number or None. Returns channel -> ``{'scale': K or
    None, 'offset': B or None}`` for the channels with either given. DataError naming the option (as on
    the command line and as the ``--columns`` key) for a value that is not a number, or a scale <= 0."""
    out = {}
    for what in CALIBRATED:
        got = {}
        for part in ("scale", "offset"):
            value = options.get(f"{what}_{part}")
            if value is not None:
                got[part] = _number(value, f"--{what}-{part} ({what}_{part})", source, positive=part == "scale")
        if got:
            out[what] = {"scale": got.get("scale"), "offset": got.get("offset")}
    return out


def apply(raw: np.ndarray, cal: dict) -> np.ndarray:
    """``scale x raw + offset`` (a missing scale is 1, a missing offset 0)."""
    return (1.0 if cal["scale"] is None else cal["scale"]) * raw + (cal["offset"] or 0.0)


def force_zero(label: str, time: np.ndarray, force: np.ndarray, stroke: np.ndarray, seconds) -> tuple:
    """Remove the force offset measured over the first ``seconds`` [s] of a test (a tare).

    time [s, from 0], force [N, + tension], stroke [m]. Returns (force minus its mean over
    ``time <= seconds`` [N], ``{'seconds', 'samples', 'removed_n', 'stroke_motion_m'}``). DataError naming
    ``--force-zero`` when ``seconds`` is not a positive number, is not shorter than the test, or the stroke
    moves by more than ``FORCE_ZERO_MAX_MOTION`` of its range meanwhile (the force is then not the zero)."""
    seconds = _number(seconds, "--force-zero (force_zero)", label, positive=True)
    duration = float(time[-1] - time[0])
    if seconds >= duration:
        raise DataError(f"{label}: --force-zero {seconds:g} s is not shorter than the test ({duration:.4g} s); "
                        f"give the length of the quiet lead-in before the stroke starts")
    window = time - time[0] <= seconds
    motion, total = float(np.ptp(stroke[window])), float(np.ptp(stroke))
    if motion > FORCE_ZERO_MAX_MOTION * total:
        raise DataError(f"{label}: the stroke moves {motion * 1e3:.4g} mm during the first {seconds:g} s "
                        f"({100 * motion / total:.3g} % of its range {total * 1e3:.4g} mm, more than "
                        f"{100 * FORCE_ZERO_MAX_MOTION:g} %): the force there is not the load cell's zero. Give a "
                        f"shorter --force-zero, within the lead-in where the damper is at rest")
    offset = float(np.mean(force[window]))
    return force - offset, {"seconds": seconds, "samples": int(window.sum()), "removed_n": offset,
                            "stroke_motion_m": motion}
