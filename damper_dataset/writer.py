"""Write a rig dataset in the ``damper-rig-dataset/1`` format (``damper_dataset.format``).

Files are CSV with fixed number formatting, so that the same input always gives
the same bytes and files stay small: time with 3 more decimals than the sample
period needs (6 at 1 kHz), stroke [m] at 1e-9 m (9 decimals, ~8 significant
digits for strokes of cm), force [N] at 0.1 N, temperature [degC] at 0.01 degC,
other channels with 10 significant digits; one leading ``#`` comment line
names the columns and units. The manifest is JSON with sorted keys and 2-space
indentation; each test entry also records ``n_samples``. Nothing time- or
host-dependent is written.
"""
from __future__ import annotations

import json
import math
import os
import re
import shutil
import tempfile
import uuid
from pathlib import Path

import numpy as np
import pandas as pd

from damper_dataset.format import (FORMAT_ID, MANIFEST_NAME, MANIFEST_TEST_KEYS, REQUIRED_COLUMNS, ROLES,
                                   check_signals)

UNITS = {"time": "s", "stroke": "m", "force": "N"}
KNOWN_CHANNEL_UNITS = {"temperature": "degC"}
_DECIMALS = {"stroke": 9, "force": 1, "temperature": 2}
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
CREATED_BY = "damper_dataset.writer.write_dataset (damper-rig-dataset/1 writer)"


def _fmt_fixed(x: np.ndarray, decimals: int) -> list[str]:
    x = np.round(np.asarray(x, dtype=float), decimals) + 0.0  # + 0.0 turns -0.0 into 0.0
    f = f"%.{decimals}f"
    return [f % v for v in x.tolist()]


def _fmt_general(x: np.ndarray) -> list[str]:
    x = np.asarray(x, dtype=float) + 0.0
    return ["%.10g" % v for v in x.tolist()]


def _json_default(o):
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON-serialisable in dataset metadata: {type(o).__name__}")


def _csv_text(name: str, frame: pd.DataFrame, units: dict, rate: float) -> str:
    extras = [c for c in frame.columns if c not in REQUIRED_COLUMNS]
    cols = [*REQUIRED_COLUMNS, *extras]
    t_dec = max(0, math.ceil(math.log10(rate))) + 3
    formatted = []
    for c in cols:
        v = frame[c].to_numpy(dtype=float)
        if c == "time":
            formatted.append(_fmt_fixed(v, t_dec))
        elif c in _DECIMALS:
            formatted.append(_fmt_fixed(v, _DECIMALS[c]))
        else:
            formatted.append(_fmt_general(v))
    head = ", ".join(f"{c} [{units[c]}]" for c in cols)
    lines = [f"# {FORMAT_ID} test {name}: {head}", ",".join(cols)]
    lines += [",".join(row) for row in zip(*formatted)]
    return "\n".join(lines) + "\n"


def _validate(tests, channel_units) -> tuple[list, dict]:
    """Check the test list; return ([(manifest entry, frame, rate [Hz])], units)."""
    if not tests:
        raise ValueError("write_dataset: no tests given")
    units = dict(UNITS)
    seen, out = set(), []
    for k, t in enumerate(tests):
        if not isinstance(t, dict):
            raise ValueError(f"write_dataset: tests[{k}] must be a dict")
        miss = [key for key in ("name", "role", "scenario", "frame") if key not in t]
        if miss:
            raise ValueError(f"write_dataset: tests[{k}] lacks {miss}")
        name = t["name"]
        if not isinstance(name, str) or not _NAME_RE.match(name):
            raise ValueError(f"write_dataset: test name {name!r} must be a non-empty file-safe "
                             f"string (letters, digits, '_', '-', '.')")
        if name in seen:
            raise ValueError(f"write_dataset: duplicated test name {name!r}")
        seen.add(name)
        if t["role"] not in ROLES:
            raise ValueError(f"write_dataset: test {name!r}: unknown role {t['role']!r}; "
                             f"expected one of {ROLES}")
        frame = t["frame"]
        if not isinstance(frame, pd.DataFrame):
            raise ValueError(f"write_dataset: test {name!r}: frame must be a pandas DataFrame")
        miss = [c for c in REQUIRED_COLUMNS if c not in frame.columns]
        if miss:
            raise ValueError(f"write_dataset: test {name!r}: frame lacks column(s) {miss}; "
                             f"columns: {list(frame.columns)}")
        reserved = [key for key in t if key in MANIFEST_TEST_KEYS and key not in
                    ("name", "role", "scenario")]
        if reserved:
            raise ValueError(f"write_dataset: test {name!r}: keys {reserved} are set by the "
                             f"writer")
        for c in frame.columns:
            if c in REQUIRED_COLUMNS:
                continue
            if not isinstance(c, str) or not _NAME_RE.match(c):
                raise ValueError(f"write_dataset: test {name!r}: bad channel name {c!r}")
            unit = channel_units.get(c, KNOWN_CHANNEL_UNITS.get(c))
            if unit is None:
                raise ValueError(f"write_dataset: test {name!r}: unit of channel {c!r} "
                                 f"unknown; pass channel_units={{{c!r}: ...}}")
            if units.setdefault(c, unit) != unit:
                raise ValueError(f"write_dataset: channel {c!r} has two units")
        try:
            arr = {c: frame[c].to_numpy(dtype=float) for c in frame.columns}
        except (TypeError, ValueError) as exc:
            raise ValueError(f"write_dataset: test {name!r}: non-numeric column: {exc}") from exc
        rate = check_signals(f"write_dataset: test {name!r}", arr["time"], arr["stroke"],
                             arr["force"], {c: v for c, v in arr.items()
                                            if c not in REQUIRED_COLUMNS})
        entry = {k2: v for k2, v in t.items() if k2 != "frame"}
        entry.update(file=f"{name}.csv", scenario=str(t["scenario"]),
                     sample_rate_hz=float(f"{rate:.9g}"), n_samples=len(frame))
        out.append((entry, frame, rate))
    return out, units


def write_dataset(out_dir, tests: list[dict], description: str, generator: dict,
                  overwrite: bool = False, *, channel_units: dict | None = None,
                  created_by: str = CREATED_BY) -> Path:
    """Write ``tests`` and ``manifest.json`` into ``out_dir``; return its Path.

    Each test is a dict with ``name`` (file-safe), ``role`` ("identification" or
    "validation"), ``scenario`` (str), ``frame`` (DataFrame with ``time`` [s],
    ``stroke`` [m], ``force`` [N] and optional channels such as ``temperature``
    [degC]; other channels need ``channel_units``) and any extra JSON-able
    metadata (e.g. ``speed_kmh``) copied into the manifest entry. ``generator``
    is a free JSON-able dict. An existing non-empty ``out_dir`` is only replaced
    when ``overwrite`` is True, and then atomically: the dataset is written to a
    temporary sibling folder and swapped in at the end. Raises ValueError on bad
    input, FileExistsError when refusing to overwrite.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"{out} exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise FileExistsError(f"{out} exists and is not empty; pass overwrite=True to replace it")
    if not isinstance(generator, dict):
        raise ValueError("write_dataset: generator must be a dict")
    items, units = _validate(tests, dict(channel_units or {}))
    manifest = {"format": FORMAT_ID, "description": str(description),
                "created_by": str(created_by), "generator": generator, "units": units,
                "tests": [entry for entry, _, _ in items]}
    manifest_text = json.dumps(manifest, sort_keys=True, indent=2, ensure_ascii=False,
                               allow_nan=False, default=_json_default) + "\n"

    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    try:
        os.chmod(tmp, 0o755)
        for entry, frame, rate in items:
            (tmp / entry["file"]).write_bytes(
                _csv_text(entry["name"], frame, units, rate).encode("utf-8"))
        (tmp / MANIFEST_NAME).write_bytes(manifest_text.encode("utf-8"))
        if not out.exists():
            os.replace(tmp, out)
        elif not any(out.iterdir()):
            out.rmdir()
            os.replace(tmp, out)
        else:
            old = out.parent / f".{out.name}.old-{uuid.uuid4().hex}"
            os.replace(out, old)
            try:
                os.replace(tmp, out)
            except OSError:
                os.replace(old, out)
                raise
            shutil.rmtree(old)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out
