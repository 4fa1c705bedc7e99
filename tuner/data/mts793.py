"""The MTS 793 data-acquisition export reader (the controller of many servo-hydraulic damper rigs).

Such an export, as the controller writes it (tab-separated, CRLF line ends)::

    MTS793|MPT|ENU|1|2|.|/|:|1|0|0|A
    <blank>
    Data Acquisition<TAB>...<TAB>Time:<TAB>1.0196941<TAB>Sec<TAB>10/4/2021 7:48:04 AM
    Stroke<TAB>Load<TAB>Time
    in<TAB>lbf<TAB>Sec
    0.0012<TAB>-3.4<TAB>0.0009765625
    ...                                 (typically 1024 rows)
    <blank>
    Data Acquisition<TAB>...<TAB>Time:<TAB>2.0196941<TAB>Sec<TAB>10/4/2021 7:48:05 AM
    Stroke<TAB>Load<TAB>Time
    ...

The first line names the export; its sixth ``|`` field is the decimal mark (``.`` or ``,``). Each block
opens with its own line (the first field ``Data Acquisition``, or any line holding ``Time:`` and a
number), then the channel names, then a units row (every cell text), then the rows; the time column runs
on across blocks. Blank lines and lines starting with ``#`` or ``%`` are skipped. A file without block
lines (the channel names right under the first line) is one block.

The rows of every block are read in order. Across blocks the channel names must repeat (else DataError
naming the line) and the time base is checked (the time column when the file has one, named ``Time`` or
in a time unit; else the blocks' own ``Time:`` stamps): a block whose rows go back over an earlier one's
(written twice) is left out, and a jump forward (a block missing) splits the file into continuous pieces,
each with a warning naming the blocks by number and line; a block other than the last with another row
count than the others is a warning too. The block stamps (number, file line, ``Time:`` value and unit,
date-time stamp, rows) are kept in ``RawTable.info['blocks']``.
"""
from __future__ import annotations

import gzip
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from damper_dataset.format import DataError
from tuner.data.delimited import is_number, text_frame, text_lines
from tuner.data.raw_table import RawTable, normalise_unit, split_unit

__all__ = ["MTS_MARK", "is_mts793", "read_mts793"]

#: how the first line of an MTS 793 export starts
MTS_MARK = "MTS793"
#: what the export's channels are called, per role of ours (lower case), when the option is left at its default
_ROLE_NAMES = {"time": ("time", "running time"), "stroke": ("stroke", "displacement", "axial displacement"),
               "force": ("load", "force", "axial load", "axial force")}


@dataclass
class _Block:
    """One data-acquisition block: its opening line's file line, ``Time:`` value and unit and date-time
    stamp (None without an opening line), its channel names (and their file line) and units (None: no
    units row), and its rows (fields) with their file lines."""

    line: int | None
    time: float | None
    time_unit: str | None
    stamp: str | None
    names: list
    names_line: int
    units: list | None
    rows: list
    row_lines: list


def is_mts793(path: Path) -> bool:
    """True when the file's first non-empty line starts with ``MTS793`` (also gzip-compressed)."""
    opener = gzip.open if path.name.lower().endswith(".gz") else open
    try:
        with opener(path, "rt", encoding="utf-8-sig", errors="replace") as fh:
            for _, line in zip(range(20), fh):
                if line.strip():
                    return line.strip().startswith(MTS_MARK)
    except (OSError, EOFError):
        return False
    return False


def _block_line(s: str, decimal: str) -> tuple[float | None, str | None, str | None] | None:
    """(``Time:`` value, its unit, the date-time stamp) of a block's opening line; None for another line.
    ``decimal``: the export's decimal mark."""
    cells = [c.strip() for c in s.split("\t")]
    k = cells.index("Time:") if "Time:" in cells else None
    has_time = k is not None and k + 1 < len(cells) and is_number(cells[k + 1], decimal)
    if not (cells[0].startswith("Data Acquisition") or has_time):
        return None
    if not has_time:
        return None, None, None
    rest = cells[k + 2:]
    value = float(cells[k + 1].replace(",", ".") if decimal == "," else cells[k + 1])
    return value, (rest[0] if rest else None), (" ".join(c for c in rest[1:] if c) or None)


def _fields(s: str, n: int, k: int, names: list, source: str) -> list:
    """A data row's ``n`` tab-separated fields (empty trailing fields dropped); DataError naming line ``k``."""
    cells = s.split("\t")
    while len(cells) > n and not cells[-1].strip():
        cells.pop()
    if len(cells) != n:
        raise DataError(f"{source}: line {k} has {len(cells)} field(s) but the block's channel names {names} are "
                        f"{n} (tab-separated MTS 793 export): the line is damaged; cut it out or repair it")
    return cells


def _blocks(kept: list, lines: list, decimal: str, source: str) -> list[_Block]:
    """The data-acquisition blocks of the lines after the export's first line (module docstring)."""
    out, i = [], 0
    while i < len(kept):
        opened = _block_line(kept[i], decimal)
        head = i + (opened is not None)
        if head >= len(kept):
            break
        names = [c.strip() for c in kept[head].split("\t")]
        while names and not names[-1]:
            names.pop()
        if len(names) < 2 or any(is_number(c, decimal) for c in names):
            raise DataError(f"{source}: line {lines[head]}: expected the channel names of an MTS 793 block "
                            f"(e.g. 'Stroke<TAB>Load<TAB>Time'), got {kept[head][:60]!r}")
        units = None
        start = head + 1
        if start < len(kept) and _block_line(kept[start], decimal) is None \
                and not any(is_number(c, decimal) for c in kept[start].split("\t") if c.strip()):
            units, start = [c.strip() for c in kept[start].split("\t")], start + 1
        end = start
        while end < len(kept) and _block_line(kept[end], decimal) is None:
            end += 1
        if out and names != out[0].names:
            raise DataError(f"{source}: line {lines[head]}: the block's channel names {names} differ from the first "
                            f"block's {out[0].names} (line {out[0].names_line}); the export mixes "
                            f"channel sets: export one set per file")
        rows = [_fields(kept[j], len(names), lines[j], names, source) for j in range(start, end)]
        t, tu, stamp = opened if opened is not None else (None, None, None)
        out.append(_Block(lines[i] if opened is not None else None, t, tu, stamp, names, lines[head], units, rows,
                          lines[start:end]))
        i = end
    return out


def _say(k: int, b: _Block) -> str:
    """'block 3 (line 2061, 10/4/2021 7:48:06 AM)' for messages."""
    where = [f"line {b.line}"] if b.line is not None else [f"rows from line {b.row_lines[0]}"] if b.row_lines else []
    return f"block {k + 1}" + (f" ({', '.join(where + ([b.stamp] if b.stamp else []))})" if where else "")


def _time_column(names: list, units: list | None) -> int | None:
    """The index of the time column: named ``Time``, else in a time unit; None without one."""
    low = [split_unit(n)[0].lower() for n in names]
    if "time" in low:
        return low.index("time")
    for i, u in enumerate(units or []):
        if normalise_unit(u) in ("s", "ms"):
            return i
    return None


@dataclass
class _Positions:
    """Where each block lies on the time base: its start and the start the next block should have [the time
    column's or the stamps' unit], how far back a block may start before it goes back over the one before
    (``back_tol``) and how far forward before one is missing (``forward_tol``), and what they come from."""

    starts: list
    ends: list
    back_tol: float
    forward_tol: float
    what: str


def _positions(blocks: list[_Block], tcol: int | None, decimal: str) -> _Positions | None:
    """The blocks' positions from the time column (tolerances: half a sample step), else from the blocks'
    ``Time:`` stamps (whether a stamp marks a block's start or end: the next stamp is due one median
    increment later, a block is missing beyond 1.5 increments and written twice when its stamp does not
    increase); None when neither is there."""
    if tcol is not None:
        conv = (lambda c: float(c.replace(",", "."))) if decimal == "," else float
        times = [np.array([conv(r[tcol]) for r in b.rows]) if b.rows else np.zeros(0) for b in blocks]
        steps = np.concatenate([np.diff(t) for t in times if len(t) > 1] or [np.zeros(0)])
        if steps.size and np.median(steps) > 0:
            dt = float(np.median(steps))
            spans = [(t[0], t[-1] + dt) if len(t) else (np.nan, np.nan) for t in times]
            return _Positions([a for a, _ in spans], [e for _, e in spans], 0.5 * dt, 0.5 * dt, "the time column")
    stamps = [b.time for b in blocks]
    if len(blocks) < 2 or any(s is None for s in stamps):
        return None
    inc = float(np.median(np.diff(stamps)))
    if not inc > 0:
        return None
    # back: a stamp that does not increase (by more than a billionth of an increment: rounding)
    return _Positions(stamps, [s + inc for s in stamps], inc * (1 - 1e-9), 0.5 * inc, "the blocks' Time: stamps")


def _check_blocks(blocks: list[_Block], decimal: str, source: str) -> tuple[list, list, list]:
    """(the blocks kept, the first kept block of each continuous piece, warnings): blocks written twice left
    out, a missing block starting a new piece, an odd row count named (module docstring)."""
    warn = []
    n_full = Counter(len(b.rows) for b in blocks[:-1]).most_common(1)[0][0] if len(blocks) > 1 else None
    for k, b in enumerate(blocks[:-1]):
        if len(b.rows) != n_full:
            warn.append(f"{source}: MTS 793 {_say(k, b)} has {len(b.rows)} rows where the other blocks have {n_full}")
    pos = _positions(blocks, _time_column(blocks[0].names, blocks[0].units), decimal)
    if pos is None:
        return blocks, [0], warn
    kept, pieces, last = [0], [0], 0
    for k in range(1, len(blocks)):
        gap = pos.starts[k] - pos.ends[last]
        if not np.isfinite(gap):  # a block without rows
            continue
        where = f"{pos.what}: due at {pos.ends[last]:.7g}, found at {pos.starts[k]:.7g}"
        if gap < -pos.back_tol:
            again = blocks[k].rows == blocks[last].rows
            warn.append(f"{source}: MTS 793 {_say(k, blocks[k])} " + (f"repeats {_say(last, blocks[last])}" if again
                        else f"goes back over the blocks before it ({where})") + ": left out")
            continue
        if gap > pos.forward_tol:
            missing = max(int(round(gap / max(pos.ends[last] - pos.starts[last], 1e-12))), 1)
            warn.append(f"{source}: MTS 793 export: {missing} block(s) missing between {_say(last, blocks[last])} "
                        f"and {_say(k, blocks[k])} ({where}): the file is read as separate pieces from there")
            pieces.append(len(kept))
        kept.append(k)
        last = k
    return [blocks[k] for k in kept], pieces, warn


def read_mts793(path: Path, source: str) -> RawTable:
    """An MTS 793 data-acquisition export's rows of every block, in order (module docstring). The warnings
    of the blocks' checks are in ``info['warnings']``; ``pieces`` marks where a missing block breaks the time
    base. DataError naming the file and line."""
    kept, lines, _ = text_lines(path, source)
    cells = kept[0].strip().split("|")
    decimal = "," if len(cells) > 5 and cells[5] == "," else "."
    blocks = _blocks(kept[1:], lines[1:], decimal, source)
    if not blocks or not any(b.rows for b in blocks):
        raise DataError(f"{source}: MTS 793 export without data rows (first line {kept[0].strip()!r})")
    used, piece_blocks, warn = _check_blocks(blocks, decimal, source)
    names, units_row = blocks[0].names, blocks[0].units
    rows = [r for b in used for r in b.rows]
    row_lines = [k for b in used for k in b.row_lines]
    starts = np.cumsum([0] + [len(b.rows) for b in used])
    frame = text_frame(rows, names, decimal)
    units, plain = {}, {}
    for i, col in enumerate(names):
        plain[col], units[col] = split_unit(col)
        if units_row is not None and i < len(units_row) and units_row[i]:
            units[col] = normalise_unit(units_row[i])
    defaults = {}
    for role, known in _ROLE_NAMES.items():
        hit = next((c for c in names if plain[c].lower() in known), None)
        if hit is not None:
            defaults[role] = hit
    info = {"export": kept[0].strip(), "rows_per_block": Counter(len(b.rows) for b in used).most_common(1)[0][0],
            "blocks": [{"block": blocks.index(b) + 1, "line": b.line, "time": b.time, "time_unit": b.time_unit,
                        "stamp": b.stamp, "rows": len(b.rows)} for b in used],
            "blocks_left_out": len(blocks) - len(used), "warnings": warn}
    pieces = [int(starts[k]) for k in piece_blocks] if len(piece_blocks) > 1 else None
    return RawTable(frame, row_lines, units, plain, "\t", decimal, header_line=blocks[0].names_line,
                    kind="MTS 793 export", defaults=defaults, info=info, pieces=pieces)

