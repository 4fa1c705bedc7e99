"""The fleet manifest (CSV or TOML; format in ``tuner.fleet``): one ``Row`` per damper test session,
checked before anything runs (``ManifestError`` names the row and column)."""
from __future__ import annotations

import csv
import dataclasses
import re
import tomllib
from pathlib import Path

from damper_fmu.parameters import MODEL_KINDS
from tuner.data.read_options import READ_OPTIONS
from tuner.identification.engine import ENGINES

__all__ = ["Row", "ManifestError", "read_fleet_manifest", "convert_cell", "check_setting", "SETTING_COLUMNS",
           "BASE_COLUMNS"]

ID_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")
#: manifest column -> (FitSettings field, converter name)
SETTING_COLUMNS = {"seed": ("seed", "int"), "models": ("models", "models"), "population": ("population", "int"),
                   "iterations": ("iterations", "int"), "polish": ("polish_jacobians", "int"),
                   "fit_rate": ("fit_rate_hz", "float"), "warmup": ("warmup_s", "float"),
                   "engine": ("engine", "str"), "parametrization": ("parametrization", "str"),
                   "init": ("init", "str"), "force_limit": ("force_limit_n", "float")}
BASE_COLUMNS = ("damper_id", "type", "session", "identification", "validation", "dataset", "diagnose", "notes")
MODELS = MODEL_KINDS

@dataclasses.dataclass
class Row:
    """One manifest row, checked. Paths absolute; ``where`` names the row for messages."""

    number: int
    where: str
    damper_id: str
    type: str
    session: str = ""
    identification: list = dataclasses.field(default_factory=list)
    validation: list = dataclasses.field(default_factory=list)
    dataset: str = ""
    columns: dict = dataclasses.field(default_factory=dict)
    settings: dict = dataclasses.field(default_factory=dict)
    diagnose: bool | None = None

    @property
    def id(self) -> str:
        return f"{self.damper_id}-{self.session}" if self.session else self.damper_id


def _loader_options() -> set:
    """Column/unit/sign options the data reader of this version accepts (``ReadOptions`` fields)."""
    names = {n for n in READ_OPTIONS if n.endswith(("_col", "_unit", "_sign"))}
    return names | {"time_col", "stroke_col", "force_col", "temperature_col", "time_unit", "stroke_unit",
                    "force_unit", "temperature_unit"}


def convert_cell(value, kind: str, where: str, column: str):
    text = value.strip() if isinstance(value, str) else value
    try:
        if kind == "int":
            if isinstance(text, bool) or (isinstance(text, float) and not text.is_integer()):
                raise ValueError
            return int(text)
        if kind == "float":
            if isinstance(text, bool):
                raise ValueError
            x = float(text)
            if x != x or x in (float("inf"), float("-inf")):
                raise ValueError
            return x
        if kind == "bool":
            if isinstance(text, bool):
                return text
            t = str(text).lower()
            if t in ("1", "true", "yes", "y", "on"):
                return True
            if t in ("0", "false", "no", "n", "off"):
                return False
            raise ValueError
        if kind == "models":
            items = text if isinstance(text, list) else re.split(r"[+;,\s]+", str(text))
            models = tuple(m.strip() for m in items if m.strip())
            bad = [m for m in models if m not in MODELS]
            if bad or not models:
                raise ManifestError(f"{where}, column 'models': unknown model(s) {bad or models!r}; "
                                    f"choose from {', '.join(MODELS)} (separated by '+')")
            return models
        return str(text)
    except ManifestError:
        raise
    except (TypeError, ValueError):
        what = {"int": "an integer", "float": "a finite number", "bool": "true or false"}.get(kind, kind)
        raise ManifestError(f"{where}, column {column!r}: {value!r} is not {what}") from None


class ManifestError(ValueError):
    """A manifest problem, naming the row and column (a ValueError: the command exits with status 2)."""


def _split_files(value, where: str, column: str, base: Path) -> list:
    if value is None or value == "":
        return []
    items = value if isinstance(value, list) else str(value).split(";")
    if not all(isinstance(i, str) for i in items):
        raise ManifestError(f"{where}, column {column!r}: expected file paths, got {value!r}")
    return [str((base / i.strip()).resolve()) if not Path(i.strip()).is_absolute() else i.strip()
            for i in items if i.strip()]


def check_setting(name: str, value, where: str, column: str):
    if name in ("population",) and value < 2:
        raise ManifestError(f"{where}, column {column!r}: population must be >= 2, got {value}")
    if name in ("iterations",) and value < 1:
        raise ManifestError(f"{where}, column {column!r}: iterations must be >= 1, got {value}")
    if name in ("polish_jacobians", "seed") and value < 0:
        raise ManifestError(f"{where}, column {column!r}: must be >= 0, got {value}")
    if name in ("fit_rate_hz", "force_limit_n") and value <= 0:
        raise ManifestError(f"{where}, column {column!r}: must be positive, got {value}")
    if name == "warmup_s" and value < 0:
        raise ManifestError(f"{where}, column {column!r}: must be >= 0 s, got {value}")
    if name == "engine" and value not in ENGINES:
        raise ManifestError(f"{where}, column {column!r}: unknown engine {value!r}; choose from {', '.join(ENGINES)}")
    if name == "parametrization" and value not in ("improved", "paper"):
        raise ManifestError(f"{where}, column {column!r}: {value!r}; choose improved or paper")
    if name == "init" and value not in ("seeded", "random"):
        raise ManifestError(f"{where}, column {column!r}: {value!r}; choose seeded or random")
    return value


def _parse_entry(entry: dict, number: int, where: str, base: Path, loader: set) -> Row:
    known = set(BASE_COLUMNS) | set(SETTING_COLUMNS) | loader
    unknown = sorted(k for k in entry if k not in known)
    if unknown:
        raise ManifestError(f"{where}: unknown column(s) {unknown}; known columns: {', '.join(sorted(known))}")
    vals = {k: v for k, v in entry.items() if v is not None and not (isinstance(v, str) and not v.strip())}
    for key in ("damper_id", "type"):
        if key not in vals:
            raise ManifestError(f"{where}: column {key!r} is empty or missing; every row needs a damper_id and a type")
    did, typ = str(vals["damper_id"]).strip(), str(vals["type"]).strip()
    session = str(vals.get("session", "")).strip()
    for col, text in (("damper_id", did), ("session", session)):
        if text and not ID_RE.match(text):
            raise ManifestError(f"{where}, column {col!r}: {text!r} is not usable as a folder name; use letters, "
                                f"digits, '-', '_', '.' (starting with a letter or digit)")
    ident = _split_files(vals.get("identification"), where, "identification", base)
    valid = _split_files(vals.get("validation"), where, "validation", base)
    dataset = vals.get("dataset", "")
    if dataset:
        if ident or valid:
            raise ManifestError(f"{where}: give either 'dataset' or 'identification'/'validation' files, not both")
        dataset = str((base / str(dataset).strip()).resolve())
    elif not ident:
        raise ManifestError(f"{where}: no identification files: fill column 'identification' (paths relative "
                            f"to the manifest, separated by ';') or 'dataset'")
    columns = {}
    for k in loader:
        if k in vals:
            kind = "float" if k.endswith("_sign") else "str"
            columns[k] = convert_cell(vals[k], kind, where, k)
    settings = {}
    for col, (name, kind) in SETTING_COLUMNS.items():
        if col in vals:
            settings[name] = check_setting(name, convert_cell(vals[col], kind, where, col), where, col)
    diagnose = convert_cell(vals["diagnose"], "bool", where, "diagnose") if "diagnose" in vals else None
    return Row(number=number, where=where, damper_id=did, type=typ, session=session, identification=ident,
               validation=valid, dataset=dataset, columns=columns, settings=settings, diagnose=diagnose)


def read_fleet_manifest(path) -> list[Row]:
    """Read and check a fleet manifest (CSV or TOML, module docstring); return its rows.

    Raises ValueError (``ManifestError``) naming the row and column of the first problem. Files are
    not opened here: a missing file fails its row only, when the row runs.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"manifest {path} not found")
    base = path.resolve().parent
    loader = _loader_options()
    entries = []  # (number, where, dict)
    if path.suffix.lower() == ".toml":
        try:
            doc = tomllib.loads(path.read_text(encoding="utf-8"))
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
            raise ManifestError(f"{path}: invalid TOML: {err}") from None
        extra = sorted(k for k in doc if k not in ("defaults", "damper"))
        if extra:
            raise ManifestError(f"{path}: unknown top-level key(s) {extra}; expected [defaults] and [[damper]] tables")
        defaults = doc.get("defaults", {})
        if not isinstance(defaults, dict):
            raise ManifestError(f"{path}: [defaults] must be a table")
        bad = [k for k in ("damper_id", "session", "identification", "validation", "dataset") if k in defaults]
        if bad:
            raise ManifestError(f"{path}: [defaults] may not hold {bad} (they belong to each [[damper]])")
        dampers = doc.get("damper", [])
        if not isinstance(dampers, list) or not dampers:
            raise ManifestError(f"{path}: no [[damper]] tables: one per damper test session")
        for k, d in enumerate(dampers, start=1):
            entries.append((k, f"{path.name} [[damper]] #{k}", {**defaults, **d}))
    else:
        try:
            text = path.read_text(encoding="utf-8-sig")
        except UnicodeDecodeError as err:
            raise ManifestError(f"{path}: not UTF-8 text ({err}); save the manifest as UTF-8 CSV") from None
        lines = [(i, ln) for i, ln in enumerate(text.splitlines(), start=1)
                 if ln.strip() and not ln.lstrip().startswith("#")]
        if not lines:
            raise ManifestError(f"{path}: empty manifest: a header row and one row per damper test session")
        reader = csv.reader([ln for _, ln in lines])
        header = [h.strip() for h in next(reader)]
        if len(set(header)) != len(header):
            raise ManifestError(f"{path}: duplicated column in the header {header}")
        for (lineno, _), cells in zip(lines[1:], reader):
            where = f"{path.name} row {len(entries) + 1} (line {lineno})"
            if len(cells) > len(header):
                raise ManifestError(f"{where}: {len(cells)} cells for {len(header)} columns; quote cells that "
                                    f"contain commas, separate files with ';'")
            entries.append((len(entries) + 1, where, dict(zip(header, cells))))
        if not entries:
            raise ManifestError(f"{path}: the manifest has a header but no rows")
    rows = [_parse_entry(e, n, w, base, loader) for n, w, e in entries]
    seen = {}
    for r in rows:
        if r.id in seen:
            raise ManifestError(f"{r.where}: id {r.id!r} (damper_id + session) repeats {seen[r.id].where}; give "
                                f"each test session of a damper its own 'session'")
        seen[r.id] = r
    return rows


