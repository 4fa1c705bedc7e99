"""The delimited-text reader: delimiters, comment lines, a logger's preamble, units in the header or a units row.

This module only turns a file into a table of raw columns with the units the file declares; what
the columns mean (time, stroke, force ...), unit conversion, signs and checks are in
:mod:`tuner.data.reading`.

Accepted files
--------------
* Text: ``.csv``, ``.tsv``, ``.txt``, ``.dat`` (each also ``.gz``), UTF-8. The delimiter is
  detected among ``,`` ``;`` tab ``|`` and runs of blanks. With ``;`` or tab as delimiter a
  decimal comma (``1,25``) is accepted. Lines starting with ``#`` or ``%`` are comments.
  The header is the first other line from which the rows have a stable number of fields: its
  own, or one fewer on rows that leave out a trailing text column (a logger's ``Events``, written
  on a few rows only). Lines before it are a preamble (a data logger's ``Sampling Rate:  1000``
  ...): its ``key: value`` pairs are kept as metadata. ``--header-line N`` (the file's 1-based
  line number) names the header when the detection fails. A trailing text column takes the rest
  of a row whose text holds the delimiter (two events ``DAQ Pause, DAQ Stop`` in a comma-separated
  ``Events`` column); any other row with another number of fields (a field more among the numeric
  columns) is refused naming its line, the header's line and that option. Units may be given in the
  header (``force [kN]``, ``force (kN)``, ``force in kN``) or in a units row right under it
  (every cell non-numeric, e.g. ``s, mm, kN`` or ``[s], [mm], [kN]``). A first line of numbers
  only is data, not a
  header (a rig writing no header): the columns are named ``column 1``, ``column 2``, ... and
  found by position; their units come from the options. Only column numbers ``0 1 2 ...`` or
  ``1 2 3 ...`` (what pandas writes for an unnamed table) are taken as a header.
* Parquet (``.parquet``, ``.pq``), units in the column names as above.

Excel workbooks are not read: save the sheet as CSV.
"""
from __future__ import annotations

import csv
import gzip
import re
from pathlib import Path

import pandas as pd

from damper_dataset.format import DataError
from tuner.data.raw_table import RawTable, normalise_unit, split_unit

__all__ = ["TEXT_SUFFIXES", "read_text", "text_lines", "is_number", "text_frame"]

TEXT_SUFFIXES = (".csv", ".tsv", ".txt", ".dat")
_DELIMITERS = [",", ";", "\t", "|"]
_PROBE_LINES = 200  # lines looked at to find the header and the delimiter
_ODD_ROWS = 0.1     # the share of those lines that may have another number of fields (damaged rows)


def is_number(cell: str, decimal: str) -> bool:
    c = cell.strip()
    if decimal == ",":
        c = c.replace(",", ".")
    try:
        float(c)
        return True
    except ValueError:
        return False


def _is_header_less(cells: list[str], decimal: str) -> bool:
    """True when a first line is a data row: every non-empty cell a number (at least two), and not
    just the column numbers 0..n-1 or 1..n that pandas writes as the header of an unnamed table."""
    full = [c.strip() for c in cells if c.strip()]
    if len(full) < 2 or not all(is_number(c, decimal) for c in full):
        return False
    return full not in ([str(k) for k in range(len(full))], [str(k + 1) for k in range(len(full))])


def _detect_delimiter(header: str, sample: list[str]) -> str | None:
    """The delimiter giving the same number (> 1) of fields on the header and the sample rows;
    None for runs of blanks."""
    for d in _DELIMITERS:
        n = len(next(csv.reader([header], delimiter=d)))
        if n > 1 and all(len(next(csv.reader([s], delimiter=d))) == n for s in sample):
            return d
    n = len(header.split())
    if n > 1 and all(len(s.split()) == n for s in sample):
        return None
    return ","


def _splitter(delim: str | None):
    """A function splitting one line into its fields (``delim`` None: runs of blanks)."""
    return (lambda s: next(csv.reader([s], delimiter=delim), [])) if delim else str.split


def _delimiter_name(delim: str | None) -> str:
    """'comma', 'semicolon', 'tab', 'bar' or 'blank' (runs of blanks: None), for messages."""
    return {",": "comma", ";": "semicolon", "\t": "tab", "|": "bar"}.get(delim, "blank")


def _numbers(cells: list[str]) -> int:
    """How many of ``cells`` are numbers (decimal point or comma)."""
    return sum(is_number(c, ",") for c in cells if c.strip())


def _heads_table(h: int, counts: list[int], rows: list[str], split) -> bool:
    """True when row ``h`` of ``rows`` can be the header of the rows after it (row 0 may also be the
    first sample of a table without a header). It has n >= 2 fields; the next row and at least
    ``1 - _ODD_ROWS`` of the later ones have n, or n - 1 (a trailing text column such as a logger's
    'Events' left out on most rows; the odd rows are read or refused later by :func:`_table_rows`). The
    next row may also be longer: a data row (a number among its first n - 1 fields) with text where that
    column starts (two events written with the delimiter). It is not a data row (below row 0, a header
    has fewer numbers than the rows under it), nor a metadata line over a header of one field fewer (a
    next row of n - 1 fields without a number)."""
    n, rest = counts[h], counts[h + 1:]
    if n < 2 or not rest or rest[0] < n - 1:
        return False
    first = split(rows[h + 1])
    if rest[0] > n and (is_number(first[n - 1], ",") or not _numbers(first[:n - 1])):
        return False
    if sum(c != n and c != n - 1 for c in rest) > _ODD_ROWS * len(rest):
        return False
    below = [_numbers(split(r)) for r in rows[h + 1:h + 4]]
    if rest[0] == n - 1 and below[0] == 0:
        return False
    return h == 0 or _numbers(split(rows[h])) < max(below)


def _find_table(kept: list[str], at: int | None) -> tuple[int, str | None]:
    """(index in ``kept`` of the header line, delimiter). The header is the first line from which the
    first ``_PROBE_LINES`` lines have a stable field count (:func:`_heads_table`); the lines before it
    are a preamble (metadata); when no line qualifies, the first line. Delimiters are tried in the
    order ``, ; tab | blanks``; the one whose table starts first wins. ``at``: the header's index when
    given (``--header-line``): only the delimiter is detected."""
    lo = at or 0
    rows = kept[lo:lo + _PROBE_LINES]
    found = []
    for k, delim in enumerate(_DELIMITERS + [None]):
        split = _splitter(delim)
        counts = [len(split(s)) for s in rows]
        starts = range(len(rows) - 1) if at is None else range(min(1, len(rows) - 1))
        h = next((h for h in starts if _heads_table(h, counts, rows, split)), None)
        if h is not None:
            found.append((lo + h, k, delim))
    if found:
        h, _, delim = min(found)
        return h, delim
    return lo, _detect_delimiter(kept[lo], kept[lo + 1:lo + 6])


def _header_index(header_line, lines: list[int], n_lines: int, source: str) -> int:
    """The index among the kept (non-comment, non-empty) lines of file line ``header_line`` (1-based,
    ``--header-line``). DataError naming the option for a bad value."""
    if isinstance(header_line, bool) or not isinstance(header_line, int) or header_line < 1:
        raise DataError(f"{source}: --header-line (header_line) must be a line number from 1, got {header_line!r}")
    if header_line > n_lines:
        raise DataError(f"{source}: --header-line {header_line} is beyond the file's last line ({n_lines})")
    if header_line not in lines:
        raise DataError(f"{source}: --header-line {header_line}: that line is empty or a comment ('#' or '%'), "
                        f"not a header; give the line number of the column names")
    return lines.index(header_line)


def _preamble(rows: list[str], delim: str | None) -> dict:
    """The ``key: value`` (also ``key = value``, or two fields ``key<delimiter>value``) pairs of the
    metadata lines before the header, both as written (stripped); other lines are left out."""
    out = {}
    for s in rows:
        key, sep, value = s.partition(":")
        if not sep:
            key, sep, value = s.partition("=")
        fields = _splitter(delim)(s) if delim else []
        if not sep and len(fields) == 2:
            (key, value), sep = fields, delim
        if sep and key.strip():
            out[key.strip()] = value.strip()
    return out


def _number_in_last(rows: list[list[str]], lines: list[int], n: int, decimal: str) -> tuple[int, str] | None:
    """(file line, cell) of the first row of exactly ``n`` fields with a number in its last column; None
    when there is none: that column may then be a trailing text column (a logger's 'Events')."""
    return next(((k, r[-1].strip()) for r, k in zip(rows, lines)
                 if len(r) == n and r[-1].strip() and is_number(r[-1], decimal)), None)


def _table_rows(body: list[str], body_lines: list[int], header: list[str], split, delim, decimal: str, head: str,
                source: str) -> list[list[str]]:
    """Each row's fields, as many as the ``header``'s n. A row may leave out a trailing text column (n - 1
    fields: an empty cell there) or hold the delimiter in that column's text (``..., 0.0021, DAQ Pause,
    DAQ Stop``): when the last column holds no number on the rows of n fields (:func:`_number_in_last`)
    and a longer row has text where that column starts, the column takes the rest of the row, joined
    back with the delimiter. Any other row (a field more among the numeric columns, fields missing)
    raises DataError naming its line, ``head`` (the header's line) and ``--header-line``."""
    n = len(header)
    rows = [split(s) for s in body]
    numeric_last = _number_in_last(rows, body_lines, n, decimal)
    for i, (r, k) in enumerate(zip(rows, body_lines)):
        m = len(r)
        if m == n:
            continue
        if m == n - 1:
            r.append("")
            continue
        starts = r[n - 1].strip() if m > n else ""
        if m > n and starts and not is_number(starts, decimal) and numeric_last is None:
            rows[i] = r[:n - 1] + [(delim or " ").join(r[n - 1:])]
            continue
        if m > n and starts and is_number(starts, decimal):
            why = (f"its field {n} ({starts!r}) is a number where the last column {header[-1]!r} starts: a field "
                   f"more among the numeric columns")
        elif m > n and starts and numeric_last is not None:
            why = (f"the last column {header[-1]!r} holds a number (line {numeric_last[0]}: {numeric_last[1]!r}), "
                   f"so it is no text column whose text may hold the delimiter")
        else:
            why = ("not a row of that table (a row may only leave out a trailing text column such as 'Events', "
                   "or hold the delimiter in that column's text)")
        raise DataError(
            f"{source}: line {k} has {m} field(s) but {head} has {n} ({_delimiter_name(delim)}-separated): "
            f"{why}. If the column names are on another line (metadata lines before them), give its line "
            f"number with --header-line N; otherwise line {k} is damaged")
    return rows


def text_lines(path: Path, source: str) -> tuple[list[str], list[int], int]:
    """(the non-empty lines that are not comments, their 1-based line numbers, the file's line count)."""
    opener = gzip.open if path.name.lower().endswith(".gz") else open
    try:
        with opener(path, "rt", encoding="utf-8-sig", newline="") as fh:
            raw = fh.read().splitlines()
    except (OSError, UnicodeDecodeError, EOFError) as exc:
        raise DataError(f"{source}: cannot read file: {exc}") from exc
    kept, lines = [], []
    for k, line in enumerate(raw, start=1):
        s = line.strip()
        if s and not s.startswith(("#", "%")):
            kept.append(line)
            lines.append(k)
    return kept, lines, len(raw)


def text_frame(rows: list[list[str]], header: list[str], decimal: str) -> pd.DataFrame:
    """The rows (:func:`_table_rows`) as a table of stripped strings (a decimal comma turned into a
    point); a row without its trailing field has an empty cell there."""
    df = pd.DataFrame(rows, columns=header, dtype=str)
    df = df.apply(lambda s: s.str.strip())
    if decimal == ",":
        df = df.apply(lambda s: s.str.replace(",", ".", regex=False))
    return df


def read_text(path: Path, source: str, header_line=None) -> RawTable:
    """A text file's table (module docstring): comments left out, the header found after any preamble
    (or at ``header_line``), the delimiter and decimal mark detected, a units row read, every row's
    field count checked."""
    kept, lines, n_lines = text_lines(path, source)
    at = None if header_line is None else _header_index(header_line, lines, n_lines, source)
    if not kept:
        raise DataError(f"{source}: file is empty (no header line and no data)")
    if len(kept) == (at or 0) + 1:
        raise DataError(f"{source}: file is empty: header {kept[-1]!r} but no data rows")
    h, delim = _find_table(kept, at)
    split = _splitter(delim)
    header = [c.strip() for c in split(kept[h])]
    decimal = "."
    probe = [c.strip() for row in kept[h + 1:h + 4] for c in split(row)]
    if delim in (";", "\t", None) and any(re.fullmatch(r"[-+]?\d+,\d+(?:[eE][-+]?\d+)?", c) for c in probe):
        decimal = ","
    units_row, start, head = None, h + 1, f"the header (line {lines[h]})"
    if at is None and _is_header_less(header, decimal):  # no header: the first line is the first sample
        header = [f"column {k + 1}" for k in range(len(header))]
        start, head = h, f"the first row (line {lines[h]})"
    elif len(kept) > h + 2 and not any(is_number(c, decimal) for c in split(kept[h + 1]) if c.strip()) \
            and any(is_number(c, decimal) for c in split(kept[h + 2])):
        units_row, start = [c.strip() for c in split(kept[h + 1])], h + 2
    body, body_lines = kept[start:], lines[start:]
    if not body:
        raise DataError(f"{source}: file is empty: header {header} but no data rows")
    twice = sorted({c for c in header if header.count(c) > 1})
    if twice:
        raise DataError(f"{source}: {head} names column(s) {twice} more than once: name each column once, or, if "
                        f"the column names are on another line, give its line number with --header-line N")
    df = text_frame(_table_rows(body, body_lines, header, split, delim, decimal, head, source), header, decimal)
    units, names = {}, {}
    for i, col in enumerate(header):
        names[col], units[col] = split_unit(col)
        if units_row is not None and i < len(units_row) and units_row[i]:
            units[col] = normalise_unit(units_row[i])
    return RawTable(df, body_lines, units, names, delim, decimal, header_line=lines[h] if start > h else None,
                    preamble=_preamble(kept[:h], delim))

