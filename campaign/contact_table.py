"""Tabulated wheel-rail contact geometry of one wheel, interpolated over the wheelset's lateral
displacement by natural cubic splines.

The table format is the one of the DTU group's RSGEO files (for instance the S1002 wheel on a UIC60
rail at 1:40 inclination, ``input/RSGEO/1o40/RSGEO.dat`` of their simulator): a line starting with
``#``, a header line naming the columns, then one whitespace-separated row per lateral displacement
(ascending, SI units), ended by a blank line, the end of the file or the next ``#`` line (only the
first table of a file is read). The columns, in this order:

==========  ============================================================================  =====
name        meaning                                                                       unit
==========  ============================================================================  =====
lat         lateral displacement of the wheelset towards this wheel (the row's abscissa)   m
N           normal force at the tabulated (static) penetration                             N
angle       contact angle between the wheel axle and the contact plane                     rad
a, b        semi-axes of the contact ellipse (longitudinal, lateral)                       m
aw          lateral distance of the contact point from the wheelset centre                 m
rw          rolling radius at the contact point                                            m
c11..c23    Kalker's creep coefficients                                                    -
rz          vertical position of the contact point on the rail                             m
qN          penetration (normal approach) at which ``N`` is tabulated                      m
ry          lateral contact position on the rail (filled by the user of the table)         m
==========  ============================================================================  =====

One table serves both wheels of a symmetric wheelset: the left wheel (at +y) is read at the
wheelset's lateral displacement ``y``, the right wheel at ``-y``. Between the rows the value is the
natural cubic spline through all rows (zero second derivative at both ends), the interpolation that
GSL calls ``cspline``; outside the tabulated range there is no value (:class:`ContactTableError`,
as a derailment).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

__all__ = ["COLUMNS", "ContactTable", "ContactTableError", "read_contact_table"]

COLUMNS = ("lat", "N", "angle", "a", "b", "aw", "rw", "c11", "c22", "c23", "rz", "qN", "ry")
"""Column names in file order (see the module docstring for meaning and units)."""


class ContactTableError(ValueError):
    """A contact table that cannot be read, or a displacement outside its range."""


@dataclass(frozen=True)
class ContactTable:
    """The rows of a contact table and their natural cubic spline coefficients.

    ``lat`` [m] ascending abscissae (n rows); ``values`` (n, 12) the other columns in the order of
    :data:`COLUMNS` [1:]; ``coefficients`` (4, n-1, 12): on the interval ``lat[i] <= y < lat[i+1]``
    the value is ``sum_k coefficients[k, i] (y - lat[i])**(3-k)``; ``source`` the file read.
    """

    lat: np.ndarray
    values: np.ndarray
    coefficients: np.ndarray
    source: str

    @property
    def max_displacement(self) -> float:
        """Largest |y| [m] inside the table on both sides (the derailment limit)."""
        return float(min(-self.lat[0], self.lat[-1]))

    def column(self, name: str) -> int:
        """Index of column ``name`` in :attr:`values` (and in the last axis of :meth:`evaluate`)."""
        if name not in COLUMNS[1:]:
            raise KeyError(f"no contact-table column {name!r}; the columns are {', '.join(COLUMNS[1:])}")
        return COLUMNS.index(name) - 1

    def evaluate(self, y) -> np.ndarray:
        """All 12 interpolated columns at lateral displacements ``y`` [m] (any shape): an array of
        shape ``y.shape + (12,)`` in the order of :data:`COLUMNS` [1:], SI units."""
        y = np.asarray(y, dtype=float)
        if np.any(y < self.lat[0]) or np.any(y > self.lat[-1]) or not np.all(np.isfinite(y)):
            raise ContactTableError(
                f"lateral displacement {np.max(np.abs(y)):.6g} m outside the contact table "
                f"[{self.lat[0]:.6g}, {self.lat[-1]:.6g}] m of {self.source} (derailment)")
        i = np.clip(np.searchsorted(self.lat, y, side="right") - 1, 0, self.lat.size - 2)
        h = (y - self.lat[i])[..., None]
        c = self.coefficients
        return ((c[0, i] * h + c[1, i]) * h + c[2, i]) * h + c[3, i]


def read_contact_table(path) -> ContactTable:
    """Read the first table of an RSGEO-format file ``path`` (format in the module docstring).

    Raises :class:`ContactTableError` naming the file and line for a missing ``#`` line, a row with
    the wrong number of columns or a non-number, fewer than 4 rows, or abscissae not ascending."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="latin-1").splitlines()
    except OSError as exc:
        raise ContactTableError(f"cannot read contact table {path}: {exc}") from exc
    start = next((k for k, line in enumerate(lines) if line.startswith("#")), None)
    if start is None or start + 1 >= len(lines):
        raise ContactTableError(f"{path}: no line starting with '#' followed by a header line")
    n_cols = len(lines[start + 1].split())
    if n_cols != len(COLUMNS):
        raise ContactTableError(f"{path}:{start + 2}: header has {n_cols} columns, expected "
                                f"{len(COLUMNS)} ({' '.join(COLUMNS)})")
    rows = _rows(path, lines, start + 2)
    data = np.array(rows)
    lat = data[:, 0]
    if np.any(np.diff(lat) <= 0.0):
        k = int(np.argmax(np.diff(lat) <= 0.0))
        raise ContactTableError(f"{path}: lateral displacement not ascending at data row {k + 2} "
                                f"({lat[k]!r} then {lat[k + 1]!r})")
    spline = CubicSpline(lat, data[:, 1:], bc_type="natural", axis=0)
    return ContactTable(lat=lat, values=data[:, 1:], coefficients=np.asarray(spline.c), source=str(path))


def _rows(path: Path, lines: list, first: int) -> list:
    """The numeric rows from line index ``first`` up to a blank line, a '#' line or the end."""
    rows = []
    for k in range(first, len(lines)):
        fields = lines[k].split()
        if not fields or lines[k].startswith("#"):
            break
        if len(fields) != len(COLUMNS):
            raise ContactTableError(f"{path}:{k + 1}: {len(fields)} columns, expected {len(COLUMNS)}")
        try:
            rows.append([float(f) for f in fields])
        except ValueError as exc:
            raise ContactTableError(f"{path}:{k + 1}: not a number ({exc})") from exc
    if len(rows) < 4:
        raise ContactTableError(f"{path}: {len(rows)} data rows, at least 4 needed for a cubic spline")
    return rows
