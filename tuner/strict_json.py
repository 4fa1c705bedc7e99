"""Strict JSON for every file the tuner writes: what ``jq``, JavaScript and any JSON library read.

JSON has no infinity and no NaN (Python's ``json`` writes ``Infinity`` and ``NaN`` unless told not to,
which strict parsers refuse). Here such a value is written as ``null`` and listed, with what it was,
in the document's top-level ``"non_finite_values"`` object: its path (keys and list indices joined by
``/``) -> ``"inf"``, ``"-inf"`` or ``"nan"``. The meaning of each field (an unbounded interval, a model
that could not be simulated) is documented where the field is made. ``loads`` reads such a document
back with the values restored, so a checkpoint written this way resumes exactly.

numpy scalars and arrays, tuples and paths are written as numbers, lists and strings; any other
object is refused (TypeError): nothing is silently turned into text.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

__all__ = ["dumps", "loads", "write", "NON_FINITE_KEY"]

#: the top-level key that lists the values JSON cannot hold
NON_FINITE_KEY = "non_finite_values"


def _plain(value, path: str, found: dict):
    """``value`` with numpy types, tuples and paths made JSON types and every non-finite float made None
    (recorded in ``found`` under its path)."""
    if isinstance(value, dict):
        return {str(k): _plain(v, f"{path}/{k}" if path else str(k), found) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_plain(v, f"{path}/{i}" if path else str(i), found) for i, v in enumerate(list(value))]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value)
        if math.isfinite(v):
            return v
        found[path] = "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")
        return None
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"strict_json: {path or 'the document'} is a {type(value).__name__}, not a JSON value")


def dumps(document, **kwargs) -> str:
    """Strict JSON text of ``document`` (a dict, or a list whose values are all finite); keyword arguments as
    ``json.dumps`` (indent, sort_keys)."""
    found: dict = {}
    plain = _plain(document, "", found)
    if found:
        if not isinstance(plain, dict):
            raise ValueError(f"strict_json: non-finite values at {', '.join(found)} in a top-level list: "
                             "wrap it in an object to record them")
        if NON_FINITE_KEY in plain:
            raise ValueError(f"strict_json: the document already has a key {NON_FINITE_KEY!r}")
        plain[NON_FINITE_KEY] = found
    return json.dumps(plain, allow_nan=False, **kwargs)


def _refuse(constant: str):
    raise ValueError(f"not strict JSON: {constant}")


def loads(text: str):
    """The document of strict JSON ``text`` (``Infinity``/``NaN`` refused), with the values listed under
    ``non_finite_values`` put back at their paths (and that key removed)."""
    document = json.loads(text, parse_constant=_refuse)
    if not isinstance(document, dict) or NON_FINITE_KEY not in document:
        return document
    for path, what in document.pop(NON_FINITE_KEY).items():
        *parents, last = path.split("/")
        node = document
        for p in parents:
            node = node[int(p)] if isinstance(node, list) else node[p]
        value = {"inf": math.inf, "-inf": -math.inf, "nan": math.nan}[what]
        if isinstance(node, list):
            node[int(last)] = value
        else:
            node[last] = value
    return document


def write(path, document, **kwargs) -> Path:
    """Write ``document`` as strict JSON to ``path`` (atomically: a temporary file, then renamed)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(dumps(document, **kwargs))
    tmp.replace(path)
    return path
