"""A nominal force-velocity characteristic with its tolerance band, as a supplier's sheet gives it, and which
points lie inside it.

The file: a CSV with a header row naming a velocity column and a force column (``velocity``, ``velocity_m_s``,
``velocity [mm/s]``, ``v``; ``force``, ``force_n``, ``force [kN]``, ``F``), in m/s, cm/s or mm/s and N, daN or kN as
the header says (a unit in brackets or after an underscore; SI without), and optionally a ``tolerance`` column in %
per row. Signed as everywhere in the tool: compression as a negative velocity with a negative force. Each
direction's points are a piecewise-linear characteristic; the band is the nominal force +- the tolerance (in % of
the nominal force, interpolated between rows like it). A point (velocity v, force F) is inside when
|F - F_nominal(v)| <= tolerance(v) x |F_nominal(v)|; a point beyond the nominal's velocities in its direction is not
judged (``inside`` None).
"""
from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["NominalCharacteristic", "read_nominal"]

_VELOCITY_UNITS = {"m/s": 1.0, "m_s": 1.0, "cm/s": 1e-2, "cm_s": 1e-2, "mm/s": 1e-3, "mm_s": 1e-3}
_FORCE_UNITS = {"n": 1.0, "dan": 10.0, "kn": 1e3}


@dataclass(frozen=True)
class NominalCharacteristic:
    """The nominal characteristic of ``source``: ``velocity_m_s`` [m/s] (increasing, signed), ``force_n`` [N] and
    ``tolerance_pct`` [%] per point."""

    source: str
    velocity_m_s: np.ndarray
    force_n: np.ndarray
    tolerance_pct: np.ndarray

    def judge(self, velocity_m_s: float, force_n: float) -> dict:
        """Where the point (``velocity_m_s`` [m/s], ``force_n`` [N]) lies against the band (module docstring):
        {"velocity_m_s", "force_n", "nominal_force_n", "tolerance_pct", "deviation_pct", "inside"}."""
        side = self.velocity_m_s > 0 if velocity_m_s > 0 else self.velocity_m_s < 0
        v, f, tol = self.velocity_m_s[side], self.force_n[side], self.tolerance_pct[side]
        slack = 1e-9 * abs(velocity_m_s)  # a velocity of 0.30000000000000004 m/s is the nominal's 0.3
        if v.size == 0 or not (v[0] - slack <= velocity_m_s <= v[-1] + slack):
            return {"velocity_m_s": velocity_m_s, "force_n": force_n, "nominal_force_n": None, "tolerance_pct": None,
                    "deviation_pct": None, "inside": None}
        nominal, t = float(np.interp(velocity_m_s, v, f)), float(np.interp(velocity_m_s, v, tol))
        deviation = 100 * (force_n - nominal) / abs(nominal) if nominal != 0 else math.inf
        return {"velocity_m_s": velocity_m_s, "force_n": force_n, "nominal_force_n": nominal, "tolerance_pct": t,
                "deviation_pct": deviation, "inside": bool(abs(deviation) <= t)}

    def to_dict(self) -> dict:
        return {"file": self.source, "points": [
            {"velocity_m_s": float(v), "force_n": float(f), "tolerance_pct": float(t)}
            for v, f, t in zip(self.velocity_m_s, self.force_n, self.tolerance_pct)]}


def _column(header: list[str], names: tuple, units: dict, path: Path, what: str) -> tuple[int, float]:
    """(index, factor to SI) of the column of ``header`` named one of ``names`` (with its unit)."""
    for i, raw in enumerate(header):
        h = raw.strip().lower()
        m = re.fullmatch(r"([a-z]+)\s*(?:\[\s*([^\]]+?)\s*\]|\(\s*([^)]+?)\s*\)|_([a-z_/]+))?", h)
        if not m or m.group(1) not in names:
            continue
        unit = next((u for u in m.groups()[1:] if u), None)
        if unit is None:
            return i, 1.0
        if unit not in units:
            raise ValueError(f"{path}: line 1, column {i + 1} ({raw.strip()!r}): unknown {what} unit {unit!r}; "
                             f"give one of {', '.join(sorted(units))}")
        return i, units[unit]
    raise ValueError(f"{path}: line 1: no {what} column among {header}; name it e.g. "
                     f"'{names[0]} [{next(iter(units))}]'")


def _number(text: str, path: Path, line: int, col: int, what: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ValueError(f"{path}: line {line}, column {col + 1}: {what} {text!r} is not a number") from None
    if not math.isfinite(v):
        raise ValueError(f"{path}: line {line}, column {col + 1}: {what} {text!r} is not finite")
    return v


def read_nominal(path: Path, tolerance_pct: float | None = None) -> NominalCharacteristic:
    """The nominal characteristic of the CSV ``path`` (module docstring); ``tolerance_pct`` [%]: the band for every
    row (the file's ``tolerance`` column, when it has one, otherwise). ValueError naming the file, line and column
    and the likely fix for anything it cannot use."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"nominal characteristic {path} not found")
    rows = [r for r in csv.reader(path.read_text().splitlines()) if any(c.strip() for c in r)]
    if len(rows) < 3:
        raise ValueError(f"{path}: a header row and at least two rows of velocity and force are needed")
    iv, sv = _column(rows[0], ("velocity", "v"), _VELOCITY_UNITS, path, "velocity")
    jf, sf = _column(rows[0], ("force", "f"), _FORCE_UNITS, path, "force")
    tol_col = next((i for i, h in enumerate(rows[0]) if h.strip().lower().startswith("tolerance")), None)
    if tolerance_pct is None and tol_col is None:
        raise ValueError(f"{path}: no tolerance: give --nominal-tolerance PCT or a 'tolerance' column [%]")
    points = []
    for line, r in enumerate(rows[1:], start=2):
        v = _number(r[iv], path, line, iv, "velocity") * sv
        f = _number(r[jf], path, line, jf, "force") * sf
        t = float(tolerance_pct) if tolerance_pct is not None else _number(r[tol_col], path, line, tol_col, "tolerance")
        if v == 0 or f * v < 0 or not 0 <= t < 100:
            raise ValueError(f"{path}: line {line}: velocity {v:g} m/s, force {f:g} N, tolerance {t:g} %: a damper's "
                             "force has its velocity's sign (compression: both negative), the velocity is not 0 and "
                             "the tolerance is in [0, 100) %")
        points.append((v, f, t))
    points.sort()
    if any(a[0] == b[0] for a, b in zip(points, points[1:])):
        raise ValueError(f"{path}: two rows of one velocity")
    v, f, t = (np.array(c, dtype=float) for c in zip(*points))
    return NominalCharacteristic(str(path), v, f, t)
