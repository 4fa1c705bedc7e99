"""The MATLAB ``.mat`` reader: version 5 (``scipy.io``) and version 7.3 (HDF5, ``h5py``).

A lab's MATLAB file holds its channels as variables; each numeric one becomes one or more columns, named
as the column options (``--time-col`` ...) and a ``--columns`` file name them:

* a vector (column ``N x 1`` or row ``1 x N``): its name, ``x``;
* a matrix's columns by 1-based index: ``data:2`` (MATLAB's ``data(:,2)`` is taken too); a matrix with
  fewer rows than columns (channels in rows, ``3 x N``) is read by its rows, under the same names;
* a struct's fields by a dot, at any depth: ``rig.stroke``, ``rig.raw:2``.

The table's length is the one most of these columns share (the longest on a tie); numeric scalars are
kept as metadata (``fs = 1000`` is no column), and text, cell arrays, struct arrays, arrays of three or
more dimensions and columns of another length are listed but left out. Units are not declared in a
.mat file: give them by option (``--stroke-unit mm``) or in the ``--columns`` file. A column that is not
found is refused listing the variables found with their MATLAB sizes and the columns they give.
"""
from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.io

from damper_dataset.format import DataError
from tuner.data.raw_table import RawTable

__all__ = ["MAT_SUFFIXES", "read_mat"]

MAT_SUFFIXES = (".mat",)
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_NUMERIC_CLASSES = ("double", "single", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64")


def _version(path: Path, source: str) -> str:
    """'7.3' for an HDF5-based .mat file (the HDF5 signature at byte 0 or 512), else '5'."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(520)
    except OSError as exc:
        raise DataError(f"{source}: cannot read file: {exc}") from exc
    if not head:
        raise DataError(f"{source}: file is empty")
    return "7.3" if head.startswith(_HDF5_SIGNATURE) or head[512:520] == _HDF5_SIGNATURE else "5"


def _load_v5(path: Path, source: str) -> dict:
    """The variables of a version 5 (or 4, 6, 7) .mat file: arrays and structs as nested dicts."""
    try:
        data = scipy.io.loadmat(path, simplify_cells=True)
    except Exception as exc:  # scipy raises ValueError, TypeError, MatReadError ... on a damaged file
        raise DataError(f"{source}: cannot read the MATLAB file: {exc}") from exc
    return {k: v for k, v in data.items() if not k.startswith("__")}


def _h5_value(obj, h5py):
    """A v7.3 variable (``h5py``: the module): a numeric array in MATLAB's orientation (HDF5 stores it
    transposed), a struct as a dict, anything else (text, cells, references) as a short description."""
    cls = obj.attrs.get("MATLAB_class", b"")
    cls = cls.decode() if isinstance(cls, bytes) else str(cls)
    if isinstance(obj, h5py.Group):
        if cls not in ("struct", ""):
            return f"<{cls}>"
        return {k: _h5_value(v, h5py) for k, v in obj.items()}
    if cls not in _NUMERIC_CLASSES and not (cls == "" and obj.dtype.kind in "fiu"):
        return f"<{cls or obj.dtype}>"
    if obj.attrs.get("MATLAB_empty", 0):
        return np.zeros(0)
    return np.asarray(obj[()]).T


def _load_v73(path: Path, source: str) -> dict:
    """The variables of a version 7.3 (HDF5) .mat file, as :func:`_load_v5` gives them."""
    try:  # imported here: an environment installed before h5py became a dependency still reads the rest
        import h5py
    except ImportError as exc:
        raise DataError(f"{source}: a MATLAB v7.3 (HDF5) file needs h5py, a dependency of the project: "
                        f"pip install h5py (or reinstall the project)") from exc
    try:
        with h5py.File(path, "r") as f:
            return {k: _h5_value(v, h5py) for k, v in f.items() if not k.startswith("#")}
    except OSError as exc:
        raise DataError(f"{source}: cannot read the MATLAB v7.3 (HDF5) file: {exc}") from exc


def _size(value) -> str:
    """MATLAB's size text of a value, ``10000x3``."""
    if isinstance(value, np.ndarray):
        shape = value.shape if value.ndim >= 2 else (value.size, 1)
        return "x".join(str(k) for k in shape)
    return type(value).__name__


def _columns(name: str, value, cols: dict, listed: list, scalars: dict) -> None:
    """Add the columns of variable ``name`` to ``cols`` (name -> 1-D float array), what it is to ``listed``
    (one text per variable) and a numeric scalar to ``scalars``."""
    if isinstance(value, dict):
        for k, v in value.items():
            _columns(f"{name}.{k}", v, cols, listed, scalars)
        return
    arr = np.asarray(value) if isinstance(value, (np.ndarray, int, float, np.number)) else None
    if arr is None or arr.dtype.kind not in "fiub" or arr.ndim > 2:
        listed.append(f"{name} ({_size(value)}, left out: not a numeric vector or matrix)")
        return
    arr = arr.astype(float)
    if arr.size == 1:
        scalars[name] = float(arr.reshape(-1)[0])
        listed.append(f"{name} (1x1 = {scalars[name]:g})")
        return
    if arr.ndim == 1 or 1 in arr.shape:
        cols[name] = arr.reshape(-1)
        listed.append(f"{name} ({_size(value)})")
        return
    turned = arr.shape[0] < arr.shape[1]
    arr = arr.T if turned else arr
    for j in range(arr.shape[1]):
        cols[f"{name}:{j + 1}"] = arr[:, j]
    listed.append(f"{name} ({_size(value)}: columns {name}:1 .. {name}:{arr.shape[1]}"
                  + (", channels in rows" if turned else "") + ")")


def read_mat(path: Path, source: str) -> RawTable:
    """A .mat file's numeric channels as columns (module docstring); DataError naming the file."""
    version = _version(path, source)
    variables = _load_v73(path, source) if version == "7.3" else _load_v5(path, source)
    cols, listed, scalars = {}, [], {}
    for name, value in variables.items():
        _columns(name, value, cols, listed, scalars)
    found = f"variables found: {', '.join(listed) or 'none'}"
    if not cols:
        raise DataError(f"{source}: MATLAB file without numeric vectors or matrices; {found}")
    counts = Counter(len(v) for v in cols.values())
    n = max(counts, key=lambda k: (counts[k], k))
    other = [c for c, v in cols.items() if len(v) != n]
    frame = pd.DataFrame({c: v for c, v in cols.items() if len(v) == n})
    note = f"left out, another length than {n}: {other}" if other else None
    info = {"version": version, "variables": listed, "scalars": scalars, "note": note}
    names = {c: c for c in frame.columns}
    return RawTable(frame, None, {}, names, None, kind=f"MATLAB v{version}", info=info,
                    found=found + (f" ({note})" if note else "") + "; a matrix's column as NAME:K, a struct's "
                                                                        "field as NAME.FIELD")
