"""Raw rig files as rigs write them: the one place that picks a file's reader.

Each format has its reader, which turns a file into a table of raw columns with the units the file
declares (``tuner.data.raw_table.RawTable``); what the columns mean (time, stroke, force ...), unit
conversion, signs and checks are in :mod:`tuner.data.reading`.

Accepted files (``RawTable.kind`` names the format read), recognised by their content where it says
so, else by their ending:

* an MTS 793 data-acquisition export (first line ``MTS793|...``, any ending, also ``.gz``):
  :mod:`tuner.data.mts793`;
* a MATLAB file ``.mat``, version 5 or 7.3 (HDF5): :mod:`tuner.data.matlab_file`;
* delimited text ``.csv``, ``.tsv``, ``.txt``, ``.dat`` (each also ``.gz``): :mod:`tuner.data.delimited`;
* Parquet ``.parquet``, ``.pq``: :mod:`tuner.data.parquet_file`.

Excel workbooks are not read: save the sheet as CSV.
"""
from __future__ import annotations

from pathlib import Path

from damper_dataset.format import DataError
from tuner.data.delimited import TEXT_SUFFIXES, read_text
from tuner.data.matlab_file import MAT_SUFFIXES, read_mat
from tuner.data.mts793 import is_mts793, read_mts793
from tuner.data.parquet_file import PARQUET_SUFFIXES, read_parquet
from tuner.data.raw_table import RawTable, normalise_unit, split_unit

__all__ = ["DataError", "RawTable", "read_raw", "normalise_unit", "split_unit", "TEXT_SUFFIXES"]


def read_raw(path, source: str | None = None, header_line: int | None = None) -> RawTable:
    """Read one rig file with its format's reader (module docstring); DataError naming the file on any
    problem. ``header_line``: the 1-based file line of the column names (delimited text; None: detected)."""
    path = Path(path)
    source = source or str(path)
    if not path.exists():
        raise DataError(f"{source}: file not found")
    if not path.is_file():
        raise DataError(f"{source}: not a file")
    name = path.name.lower()
    if name.endswith(PARQUET_SUFFIXES):
        return read_parquet(path, source)
    if name.endswith(MAT_SUFFIXES):
        return read_mat(path, source)
    text = name.endswith(TEXT_SUFFIXES) or name.endswith(tuple(s + ".gz" for s in TEXT_SUFFIXES))
    if is_mts793(path):
        return read_mts793(path, source)
    if text:
        return read_text(path, source, header_line)
    if name.endswith((".xlsx", ".xls", ".ods")):
        raise DataError(f"{source}: unsupported file type (spreadsheet): save the sheet as CSV")
    raise DataError(f"{source}: unsupported file type; use .csv/.tsv/.txt/.dat (optionally .gz), .parquet, .mat "
                    f"or an MTS 793 export")
