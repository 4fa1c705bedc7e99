"""The Parquet reader: a table as pandas writes it, units in the column names (``force [kN]``)."""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from damper_dataset.format import DataError
from tuner.data.raw_table import RawTable, split_unit

__all__ = ["PARQUET_SUFFIXES", "read_parquet"]

PARQUET_SUFFIXES = (".parquet", ".pq")


def read_parquet(path: Path, source: str) -> RawTable:
    """A Parquet file's columns (names stripped, units split off the names); DataError naming the file."""
    if path.stat().st_size == 0:
        raise DataError(f"{source}: file is empty")
    try:
        df = pd.read_parquet(path)
    except Exception as exc:  # pyarrow raises several exception types
        raise DataError(f"{source}: cannot read Parquet: {exc}") from exc
    if len(df) == 0:
        raise DataError(f"{source}: file is empty: columns {list(df.columns)} but no rows")
    df.columns = [str(c).strip() for c in df.columns]
    names, units = {}, {}
    for c in df.columns:
        names[c], units[c] = split_unit(c)
    return RawTable(df, None, units, names, None, kind="Parquet")
