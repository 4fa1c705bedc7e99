"""Date-time stamps in a rig file's time column, read to seconds from the first stamp.

Stamps written as a date and a clock time, as data loggers write them:
``05/25/2022 05:50:06.526 PM`` (a 12-hour clock with AM/PM), ``25.05.2022 17:50:06.526`` (24-hour),
``2022-05-25T17:50:06`` (year first). The date's separator is ``/``, ``.`` or ``-``, the year has
four digits (first or last), seconds may be left out or have any number of decimals (point or
comma). Every stamp of a column must have the layout of the first. A time zone is not read (ISO
stamps with one are left to pandas by :mod:`tuner.data.reading`).

Day-month order of year-last dates: ``mdy`` (month/day/year, US) or ``dmy`` (day/month/year).
Given (``--date-order``), it is checked against every stamp; otherwise it is read from the data: a
first field above 12 on some row means dmy, a second field above 12 mdy. When every day and month
field is 12 or less, and the two orders give different times (the date changes within the file),
the file is refused with the fix (``--date-order``); when they give the same times (one date
throughout), the order does not matter and none is assumed.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from damper_dataset.format import DataError

__all__ = ["DATE_ORDERS", "check_date_order", "is_stamp", "stamp_seconds"]

#: the day-month orders of ``--date-order`` and what they mean (``ymd``: year-first dates, always)
DATE_ORDERS = {"mdy": "month/day/year", "dmy": "day/month/year", "ymd": "year-month-day"}
_STAMP = (r"^(?P<a>\d{1,4})(?P<sep>[/.-])(?P<b>\d{1,2})(?P=sep)(?P<c>\d{1,4})[ T]+(?P<h>\d{1,2}):(?P<mi>\d{2})"
          r"(?::(?P<s>\d{2}(?:[.,]\d+)?))?\s*(?P<ampm>[AaPp]\.?[Mm]\.?)?$")


def check_date_order(order, source: str) -> None:
    """DataError naming ``--date-order`` unless ``order`` is None, ``'mdy'`` or ``'dmy'``."""
    if order is not None and order not in ("mdy", "dmy"):
        raise DataError(f"{source}: --date-order (date_order) must be mdy (month/day/year) or dmy "
                        f"(day/month/year), got {order!r}")


def _parts(values: pd.Series) -> pd.DataFrame:
    """The fields of each stamp (NaN where a value is no stamp, or its year is not 4 digits first or last)."""
    m = values.astype(str).str.strip().str.extract(_STAMP)
    la, lc = m["a"].str.len(), m["c"].str.len()
    m["year_first"] = (la == 4) & (lc <= 2)
    m.loc[~m["year_first"] & ~((lc == 4) & (la <= 2)), "a"] = np.nan
    return m


def is_stamp(value) -> bool:
    """True when ``value`` is a date-time stamp this module reads."""
    return bool(_parts(pd.Series([value]))["a"].notna().iloc[0])


def _where(lines, i: int) -> str:
    """'data row i+1 (line k)' for messages."""
    return f"data row {i + 1}" + (f" (line {lines[i]})" if lines is not None and i < len(lines) else "")


def _day_month_order(first: np.ndarray, second: np.ndarray, order, say, lines) -> tuple[str | None, str]:
    """(order read or checked, why) for year-last dates whose first and second fields are ``first`` and
    ``second``; None when every field is <= 12 (the caller decides whether that matters). ``say``:
    the start of every message (file and column)."""
    big1, big2 = np.flatnonzero(first > 12), np.flatnonzero(second > 12)
    if order == "mdy" and big1.size:
        i = big1[0]
        raise DataError(f"{say}: --date-order mdy, but the month field is {first[i]} at {_where(lines, i)}; "
                        f"the stamps are day/month/year: use --date-order dmy")
    if order == "dmy" and big2.size:
        i = big2[0]
        raise DataError(f"{say}: --date-order dmy, but the month field is {second[i]} at {_where(lines, i)}; "
                        f"the stamps are month/day/year: use --date-order mdy")
    if order is not None:
        return order, f"--date-order {order}"
    if big1.size and big2.size:
        raise DataError(f"{say}: the dates fit neither month/day/year nor day/month/year: a first field "
                        f"{first[big1[0]]} at {_where(lines, big1[0])} and a second field {second[big2[0]]} "
                        f"at {_where(lines, big2[0])} are both above 12")
    if big1.size:
        return "dmy", f"a first field above 12: {first[big1[0]]} at {_where(lines, big1[0])}"
    if big2.size:
        return "mdy", f"a second field above 12: {second[big2[0]]} at {_where(lines, big2[0])}"
    return None, ""


def _clock_ns(m: pd.DataFrame, say: str, lines) -> tuple[np.ndarray, str]:
    """(nanoseconds since midnight of each stamp, 'the clock' text). 12-hour stamps: hour 1-12 with
    AM/PM (12 AM is midnight, 12 PM noon); 24-hour stamps: hour 0-23."""
    h, mi = m["h"].astype(int).to_numpy(), m["mi"].astype(int).to_numpy()
    s = m["s"].fillna("0").str.replace(",", ".", regex=False).astype(float).to_numpy()
    ampm = m["ampm"].fillna("").str.upper().str[:1].to_numpy()
    twelve = ampm != ""
    if twelve.any() and not twelve.all():
        i = int(np.argmax(twelve != twelve[0]))
        raise DataError(f"{say}: stamps with and without AM/PM: {m['h'].iloc[i]}:{m['mi'].iloc[i]} at "
                        f"{_where(lines, i)} after {'12' if twelve[0] else '24'}-hour stamps")
    bad = ((h < 1) | (h > 12)) if twelve[0] else (h > 23)
    bad |= (mi > 59) | (s >= 60)
    if bad.any():
        i = int(np.argmax(bad))
        raise DataError(f"{say}: no such clock time {h[i]}:{mi[i]:02d}:{s[i]:g}"
                        f"{' ' + ampm[i] + 'M' if twelve[0] else ''} at {_where(lines, i)}")
    if twelve[0]:
        h = h % 12 + 12 * (ampm == "P")
    ns = (h * 3600 + mi * 60).astype(np.int64) * 10**9 + np.round(s * 1e9).astype(np.int64)
    return ns, "12-hour clock (AM/PM)" if twelve[0] else "24-hour clock"


def _stamp_ns(year, month, day, clock_ns, say: str, lines) -> np.ndarray:
    """Nanoseconds since 1970 of each date and clock time; DataError naming a date that does not exist."""
    dates = pd.to_datetime(pd.DataFrame({"year": year, "month": month, "day": day}), errors="coerce")
    bad = dates.isna().to_numpy()
    if bad.any():
        i = int(np.argmax(bad))
        raise DataError(f"{say}: no such date: year {year[i]}, month {month[i]}, day {day[i]} at {_where(lines, i)}")
    return dates.to_numpy(dtype="datetime64[ns]").astype(np.int64) + clock_ns


def stamp_seconds(values: pd.Series, order, source: str, column: str, lines=None) -> tuple[np.ndarray, dict]:
    """Seconds [s] from the first stamp of ``values`` (strings, see the module docstring), and what was
    read: ``{'date_order': 'mdy'|'dmy'|'ymd'|None, 'stamps': text}``. ``order``: ``'mdy'``, ``'dmy'`` or
    None (read from the data); ``lines``: the file line of each value, for messages. Raises DataError
    naming the file, column, row and line, and ``--date-order`` when the order is ambiguous."""
    say = f"{source}: time column {column!r}"
    m = _parts(values)
    bad = m["a"].isna().to_numpy() | (m["year_first"].to_numpy() != m["year_first"].iloc[0])
    if bad.any():
        i = int(np.argmax(bad))
        raise DataError(f"{say} is neither numbers nor timestamps: {values.iloc[i]!r} at {_where(lines, i)} "
                        f"(the rows before are date-time stamps like {values.iloc[0]!r})")
    a, b, c = (m[k].astype(int).to_numpy() for k in "abc")
    clock, clock_text = _clock_ns(m, say, lines)
    if m["year_first"].iloc[0]:
        return _seconds(_stamp_ns(a, b, c, clock, say, lines)), {
            "date_order": "ymd", "stamps": f"{DATE_ORDERS['ymd']} (year first), {clock_text}"}
    found, why = _day_month_order(a, b, order, say, lines)
    if found is not None:
        month, day = (a, b) if found == "mdy" else (b, a)
        return _seconds(_stamp_ns(c, month, day, clock, say, lines)), {
            "date_order": found, "stamps": f"{DATE_ORDERS[found]} ({why}), {clock_text}"}
    mdy, dmy = _stamp_ns(c, a, b, clock, say, lines), _stamp_ns(c, b, a, clock, say, lines)
    if not np.array_equal(mdy - mdy[0], dmy - dmy[0]):
        raise DataError(f"{say}: the dates read both as month/day/year and as day/month/year (no day or month "
                        f"field above 12, e.g. {values.iloc[0]!r} at {_where(lines, 0)}) and the two give "
                        f"different times: give the order with --date-order mdy or --date-order dmy "
                        f"(--columns key date_order)")
    return _seconds(mdy), {"date_order": None, "stamps": "day-month order not needed (every day and month field "
                                                         f"<= 12, and both orders give the same times), {clock_text}"}


def _seconds(ns: np.ndarray) -> np.ndarray:
    """Seconds [s] from the first of the nanosecond stamps ``ns``."""
    return (ns - ns[0]) * 1e-9
