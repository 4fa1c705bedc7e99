"""A rig file's columns as written, whatever its format (``RawTable``), and the unit names it declares.

Every format's reader (``tuner.data.delimited``, ``tuner.data.mts793``, ``tuner.data.matlab_file``,
``tuner.data.parquet_file``) returns a ``RawTable``; ``tuner.data.rigfile.read_raw`` picks the reader.
What the columns mean (time, stroke, force ...), unit conversion, signs and checks are in
:mod:`tuner.data.reading`.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import pandas as pd

from damper_dataset.format import DataError

__all__ = ["DataError", "RawTable", "normalise_unit", "split_unit"]

_UNIT_ALIASES = {
    "s": "s", "sec": "s", "second": "s", "seconds": "s", "ms": "ms", "msec": "ms",
    "m": "m", "cm": "cm", "mm": "mm", "um": "um", "µm": "um", "μm": "um", "micron": "um",
    "n": "N", "dan": "daN", "kn": "kN",
    "m/s": "m/s", "mm/s": "mm/s", "cm/s": "cm/s", "ms-1": "m/s", "mms-1": "mm/s",
    "degc": "degC", "°c": "degC", "c": "degC", "deg c": "degC", "celsius": "degC", "k": "K",
    # US customary units (tuner.data.units holds their exact factors)
    "in": "in", "inch": "in", "inches": "in", "ft": "ft", "feet": "ft", "foot": "ft",
    "lbf": "lbf", "lb": "lbf", "lbs": "lbf", "kip": "kip", "kips": "kip", "klbf": "kip",
    "in/s": "in/s", "in/sec": "in/s", "ips": "in/s", "ft/s": "ft/s", "ft/sec": "ft/s",
    "lbf*s/in": "lbf*s/in", "lbf-s/in": "lbf*s/in", "lbf.s/in": "lbf*s/in", "lb-s/in": "lbf*s/in",
    "lbf s/in": "lbf*s/in",
}


def normalise_unit(text: str) -> str:
    """Canonical spelling of a unit string (``'KN'`` -> ``'kN'``, ``'°C'`` -> ``'degC'``);
    unknown units are returned stripped and unchanged."""
    u = text.strip().strip("[]()").strip()
    return _UNIT_ALIASES.get(u.lower(), u)


_HEADER_UNIT = re.compile(r"^(?P<name>.*?)\s*(?:\[(?P<b>[^\]]*)\]|\((?P<p>[^)]*)\)|\s+in\s+(?P<i>\S+))\s*$")


def split_unit(header: str) -> tuple[str, str | None]:
    """``'force [kN]'`` -> ``('force', 'kN')``; a header without a unit -> ``(header, None)``."""
    m = _HEADER_UNIT.match(header.strip())
    if not m or not m.group("name"):
        return header.strip(), None
    unit = m.group("b") or m.group("p") or m.group("i")
    return m.group("name").strip(), normalise_unit(unit) if unit and unit.strip() else None


@dataclass
class RawTable:
    """A file's columns as written. ``frame``: raw columns (header text stripped); ``lines``: the
    file line of each data row (None for Parquet and MATLAB); ``units``: column -> unit declared in the file
    (header or units row); ``names``: column -> name without the unit; ``delimiter``: as detected
    (None for Parquet and MATLAB); ``decimal``: decimal mark; ``header_line``: the file line of the column
    names (None: no header, Parquet or MATLAB); ``preamble``: the ``key: value`` pairs of the metadata lines
    before the header, as written; ``kind``: the format read (``'delimited text'``, ``'MTS 793 export'``,
    ``'MATLAB v5'``, ``'MATLAB v7.3'``, ``'Parquet'``); ``defaults``: role -> the column the format itself
    names so (an MTS export's ``Load`` is the force), used when the option is left at its default;
    ``info``: what else the format holds (an MTS export's blocks, a MATLAB file's variables); ``pieces``:
    the first row of each continuous piece when the file's time base breaks (an MTS export missing a
    block), else None; ``found``: the file's contents as a missing column's message lists them (None:
    the columns)."""

    frame: pd.DataFrame
    lines: list[int] | None
    units: dict
    names: dict
    delimiter: str | None
    decimal: str = "."
    header_line: int | None = None
    preamble: dict = field(default_factory=dict)
    kind: str = "delimited text"
    defaults: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)
    pieces: list | None = None
    found: str | None = None

    def find(self, spec, what: str, source: str) -> str:
        """The column ``spec`` names: a 1-based position (``3`` or ``'3'``), the exact header, or
        the header's name without its unit (case-insensitive). Raises ValueError naming the
        columns found."""
        cols = list(self.frame.columns)
        if isinstance(spec, int) or (isinstance(spec, str) and spec.strip().isdigit() and spec not in cols):
            k = int(spec)
            if not 1 <= k <= len(cols):
                raise DataError(f"{source}: {what} column position {k} is out of range: the file has "
                             f"{len(cols)} columns {cols}")
            return cols[k - 1]
        if spec in cols:
            return spec
        matlab = re.fullmatch(r"\s*(.+?)\s*\(\s*:\s*,\s*(\d+)\s*\)\s*", str(spec))  # MATLAB's data(:,2)
        if matlab and f"{matlab.group(1)}:{matlab.group(2)}" in cols:
            return f"{matlab.group(1)}:{matlab.group(2)}"
        low = str(spec).strip().lower()
        hits = [c for c in cols if self.names[c].lower() == low or c.lower() == low]
        if len(hits) == 1:
            return hits[0]
        if len(hits) > 1:
            raise DataError(f"{source}: {what} column {spec!r} is ambiguous: {hits}; give the full header")
        opt = {"time": "--time-col", "stroke": "--stroke-col", "force": "--force-col", "velocity": "--velocity-col",
               "temperature": "--temperature-col", "test id": "--test-col"}.get(what, "the column options")
        where = "" if not self.header_line or self.header_line == 1 else \
            (f" (the column names taken from line {self.header_line}; if they are on another line, give it "
             f"with --header-line N)")
        listed = self.found or f"columns found: {cols}"
        raise DataError(f"{source}: missing column {spec!r} ({what}); {listed}{where}; "
                        f"name the {what} column with {opt} (a header or a 1-based position)")

