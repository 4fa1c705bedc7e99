"""Fleet batch identification: ``python -m tuner batch MANIFEST`` (also ``python -m tuner.cli.batch``).

One manifest row per damper test session; every row is identified by ``tuner.identification.fit.fit`` (and
diagnosed by ``tuner.diagnosis.diagnose.diagnose`` with ``--diagnose``) into its own folder
``<out>/<id>/``, then a fleet summary is written (``tuner.results.fleet_summary``: summary.csv,
summary.html, the damping characteristics of each type overlaid with outliers marked).

Manifest
--------
CSV (a header row; ``#`` comment lines and blank lines ignored) or TOML. Columns / keys:

* ``damper_id`` (required): the damper; letters, digits, ``-``, ``_``, ``.``;
* ``type`` (required): the damper type (outliers are judged within a type);
* ``session`` (optional): e.g. ``acceptance`` or ``2026-03``: a damper tested twice gets two rows;
  the row's id (and folder) is ``<damper_id>`` or ``<damper_id>-<session>``;
* ``identification``, ``validation``: test files, paths relative to the manifest's folder, several
  separated by ``;`` (TOML: a list or such a string); or ``dataset``: a dataset folder with a
  ``manifest.json`` (its roles are used);
* column mapping and units, passed to ``tuner.data.reading.load_files``: ``time_col``, ``stroke_col``,
  ``force_col``, ``temperature_col``, ``time_unit``, ``stroke_unit``, ``force_unit``,
  ``temperature_unit`` (and any other loader option of ``tuner.data.reading`` ending in ``_col``,
  ``_unit`` or ``_sign``);
* per-row settings: ``seed``, ``models`` (``lumped+maxwell``; ``+``, ``;`` or spaces between),
  ``population``, ``iterations``, ``polish``, ``fit_rate`` [Hz], ``warmup`` [s], ``engine``,
  ``parametrization``, ``init``, ``force_limit`` [N], ``diagnose`` (true/false);
* ``notes``: free text, ignored.

An empty cell takes the default: TOML ``[defaults]`` table, then the command-line option, then
``tuner.identification.fit.FitSettings``. TOML layout::

    [defaults]
    population = 10
    [[damper]]
    damper_id = "YD-0001"
    type = "A"
    identification = ["yd0001/id1.csv", "yd0001/id2.csv"]
    validation = "yd0001/val1.csv"

A malformed manifest (unknown column, missing damper_id, bad number, duplicated id) stops before
anything runs, naming the row and column (exit status 2). A row whose data cannot be used (a
missing file, a column not found) fails alone: its error is recorded and the other rows go on.

Executors (``--scheduler``)
---------------------------
* ``pool`` (default) / ``pool:N``: a local process pool (``concurrent.futures``, spawned processes),
  N = ``os.cpu_count()`` by default;
* ``local:N``: a ``dask.distributed.LocalCluster`` of N worker processes, one thread each;
* ``tcp://HOST:PORT`` (any Dask scheduler address): a running Dask cluster. The workers must have this
  project installed and see the manifest's files and ``--out`` at the same paths (a shared file
  system).

The unit of work is one whole row. Inside a row the fit evaluates its candidates in the row's own
process (``--row-workers 0``, the default), so the fleet level is the parallel one and nothing is
shipped per evaluation. (``--row-workers N`` gives each row a pool of N processes; Dask's workers
are daemon processes, which may not start children, so ``local:N`` then starts them as
non-daemons; on a remote cluster set ``distributed.worker.daemon: false``.) The BLAS libraries run
one thread per worker (``OMP_NUM_THREADS`` etc. = 1, Dask's default for its workers, set here for
the pool too), so a row gives the same numbers on any executor. Results stream back as they
finish, with a progress bar (plain lines when not on a terminal).

Resumable
---------
A row's folder receives ``row.json`` when it starts and ``done.json`` last (atomically: temporary
file and ``os.replace``) when it has finished; the fleet summary is built from ``done.json``. A
rerun of the same command skips every row with a ``done.json`` whose key (hash of the row's files,
columns and effective settings) matches; a row that changed is redone (the old folder moved aside to
``<id>.old[-N]``). A row without ``done.json`` (interrupted, or failed: ``failed.json`` holds the
error and traceback) is cleared and run again. Each row's seed comes from the manifest (``seed``)
or the command line (``--seed``, default 0), never from the scheduling order: the same manifest
gives the same numbers on one worker or many. ``<out>/batch.log`` records every row run (start,
end, status).

Exit status: 0 every row done, 1 some rows failed (see the summary), 2 bad manifest or options,
130 interrupted (rerun the same command to continue).
"""
from __future__ import annotations

import argparse
import contextlib
import csv
import dataclasses
import hashlib
import json
import os
import re
import shutil
import socket
import sys
import time
import traceback
from pathlib import Path

from tqdm import tqdm

from damper_fmu.fmu import ensure_fmu
from damper_fmu.parameters import EFFECT_MODELS, MODEL_KINDS
from tuner import job
from tuner.cli.run import run_handler
from tuner.data.reading import DataError, load_dataset, load_files, load_tests
from tuner.identification.engine import ENGINES
from tuner.identification.fit import FitSettings
from tuner.results.fleet_summary import OUTLIER_K, OUTLIER_TOLERANCE, write_atomic, write_summary

__all__ = ["Row", "ManifestError", "read_fleet_manifest", "FleetExecutor", "parse_scheduler", "run_row", "run_batch",
           "add_parser", "cmd_batch", "main", "ROW_FORMAT", "SETTING_COLUMNS"]

ROW_FORMAT = "tuner-batch-row/1"
ID_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")
#: manifest column -> (FitSettings field, converter name)
SETTING_COLUMNS = {"seed": ("seed", "int"), "models": ("models", "models"), "population": ("population", "int"),
                   "iterations": ("iterations", "int"), "polish": ("polish_jacobians", "int"),
                   "fit_rate": ("fit_rate_hz", "float"), "warmup": ("warmup_s", "float"),
                   "engine": ("engine", "str"), "parametrization": ("parametrization", "str"),
                   "init": ("init", "str"), "force_limit": ("force_limit_n", "float")}
BASE_COLUMNS = ("damper_id", "type", "session", "identification", "validation", "dataset", "diagnose", "notes")
MODELS = MODEL_KINDS
#: environment of every worker process: one BLAS thread (the fleet level is the parallel one, and
#: the same thread count everywhere keeps the numbers identical on every executor)
WORKER_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S%z")


# --------------------------------------------------------------------------- manifest

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
    """Column/unit options the data reader of this version accepts (tuner.data.reading, public names)."""
    import inspect

    names = set(inspect.signature(load_tests).parameters)
    names = {n for n in names if n.endswith(("_col", "_unit", "_sign"))}
    return names | {"time_col", "stroke_col", "force_col", "temperature_col", "time_unit", "stroke_unit",
                    "force_unit", "temperature_unit"}


def _convert(value, kind: str, where: str, column: str):
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


def _check_setting(name: str, value, where: str, column: str):
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
            columns[k] = _convert(vals[k], kind, where, k)
    settings = {}
    for col, (name, kind) in SETTING_COLUMNS.items():
        if col in vals:
            settings[name] = _check_setting(name, _convert(vals[col], kind, where, col), where, col)
    diagnose = _convert(vals["diagnose"], "bool", where, "diagnose") if "diagnose" in vals else None
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
        import tomllib

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


# --------------------------------------------------------------------------- one row

def _task(row: Row, out: Path, base_settings: dict, diagnose: bool, row_workers: int) -> dict:
    """The picklable description of one row's work (sent to a worker)."""
    s = {**base_settings, **row.settings, "workers": int(row_workers)}
    s["models"] = list(s.get("models", FitSettings().models))
    do_diag = row.diagnose if row.diagnose is not None else diagnose
    spec = {"id": row.id, "damper_id": row.damper_id, "session": row.session, "type": row.type,
            "identification": row.identification, "validation": row.validation, "dataset": row.dataset,
            "columns": row.columns, "settings": {k: v for k, v in s.items() if k != "workers"},
            "diagnose": bool(do_diag)}
    key = hashlib.sha256(json.dumps(spec, sort_keys=True, default=str).encode()).hexdigest()[:16]
    return {**spec, "key": key, "row": row.number, "where": row.where, "folder": str(Path(out) / row.id),
            "workers": int(row_workers)}


def _load_row_data(task: dict):
    where = task["where"]
    if task["dataset"]:
        if not Path(task["dataset"]).is_dir():
            raise DataError(f"{where}, column 'dataset': folder {task['dataset']} not found (paths are relative to "
                            f"the manifest's folder)")
        tests = load_dataset(task["dataset"])
        ident = [t for t in tests if t.role == "identification"]
        valid = [t for t in tests if t.role == "validation"]
    else:
        for col in ("identification", "validation"):
            for f in task[col]:
                if not Path(f).is_file():
                    raise DataError(f"{where}, column {col!r}: file {f} not found (paths are relative to the "
                                    f"manifest's folder; several files are separated by ';')")
        try:
            ident = load_files(task["identification"], "identification", **task["columns"])
            valid = load_files(task["validation"], "validation", **task["columns"]) if task["validation"] else []
        except DataError as err:
            raise DataError(f"{where}: {err} (column mapping and units: the manifest's *_col / *_unit columns)") from err
    if not ident:
        raise DataError(f"{where}: the data holds no identification test")
    names = [t.name for t in ident + valid]
    if len(set(names)) != len(names):
        raise DataError(f"{where}: test names must be unique within a row, got {names} (file names without "
                        f"extension)")
    return ident, valid


def _record(task: dict, folder: Path, started: str, elapsed: float, log_lines: int) -> dict:
    """done.json content: what the fleet summary needs, read from the fit's output files."""
    params = json.loads((folder / "parameters.json").read_text())
    metrics = json.loads((folder / "metrics.json").read_text())
    rmse, noise = {}, None
    for m in params:
        h = folder / f"history_{m}.json"
        if h.exists():
            hist = json.loads(h.read_text())
            rmse[m] = hist.get("identification_rmse_n")
            noise = hist.get("noise_floor_n", noise)
    validation = {}
    for name, t in metrics.get("tests", {}).items():
        if t.get("role") == "validation":
            validation[name] = {m: {"ame": r["ame"], "mse": r["mse"], "rmse": r["rmse"]}
                                for m, r in t["models"].items()}
    diag = None
    dj = folder / "diagnosis.json"
    if task["diagnose"] and dj.exists():
        d = json.loads(dj.read_text())
        diag = {"cause": d.get("cause"), "causes": d.get("causes", []), "verdict": d.get("verdict", "")}
    return {"format": ROW_FORMAT, "key": task["key"], "id": task["id"], "damper_id": task["damper_id"],
            "session": task["session"], "type": task["type"], "row": task["row"], "status": "done",
            "seed": task["settings"].get("seed"), "settings": task["settings"], "diagnose": task["diagnose"],
            "started_at": started, "finished_at": _now(), "elapsed_s": elapsed, "host": socket.gethostname(),
            "pid": os.getpid(), "parameters": {m: p["values"] for m, p in params.items()},
            "units": {m: p["units"] for m, p in params.items()},
            "identified": {m: sorted(p["bounds"]) for m, p in params.items()},
            "identification_rmse_n": rmse, "noise_floor_n": noise, "validation": validation,
            "diagnosis": diag, "files": {"identification": task["identification"],
                                         "validation": task["validation"], "dataset": task["dataset"]}}


def run_row(task: dict) -> dict:
    """Identify one row into ``task['folder']``; return its record (status 'done' or 'failed').

    Runs in a worker. Every exception of the row is caught and recorded (``failed.json``: type,
    message, traceback): a failed row does not stop the others. ``done.json`` is written last.
    """
    folder = Path(task["folder"])
    started, t0 = _now(), time.perf_counter()
    folder.mkdir(parents=True, exist_ok=True)
    write_atomic(folder / "row.json", json.dumps({k: v for k, v in task.items()}, indent=1, default=str))
    logf = open(folder / "log.txt", "a", encoding="utf-8")
    n_lines = 0

    def log(msg: str) -> None:
        nonlocal n_lines
        n_lines += 1
        logf.write(f"{msg}\n")
        logf.flush()

    try:
        log(f"{_now()} row {task['id']} ({task['where']}) on {socket.gethostname()} pid {os.getpid()}")
        ident, valid = _load_row_data(task)
        for t in ident + valid:
            for w in t.metadata.get("warnings", []):
                log(f"warning: {w}")
        s = dict(task["settings"])
        s["models"] = tuple(s["models"])
        settings = FitSettings(**s, workers=task["workers"])
        provenance = {"files": {t.name: str(t.source) for t in ident + valid},
                      "command": f"python -m tuner batch ({task['where']})", "batch_row": task["id"]}
        if task["diagnose"]:
            if not valid:
                raise DataError(f"{task['where']}: diagnose needs validation files (its decision is the held-out "
                                    f"gain); fill 'validation' or set diagnose = false")
            if not job.wants_diagnosis(settings, valid):
                raise ValueError(f"{task['where']}: the diagnosis needs one of {', '.join(EFFECT_MODELS)} "
                                 f"in 'models'")
        job.run(ident, valid, folder, settings, diagnose_after=task["diagnose"], provenance=provenance, log=log)
        rec = _record(task, folder, started, time.perf_counter() - t0, n_lines)
        write_atomic(folder / "done.json", json.dumps(rec, indent=1, sort_keys=True))
        (folder / "failed.json").unlink(missing_ok=True)
        log(f"{_now()} done in {rec['elapsed_s']:.1f} s")
        return rec
    except Exception as err:  # noqa: BLE001 -- recorded with its traceback, the row is 'failed'
        rec = _failure(task, err, traceback.format_exc(), started, time.perf_counter() - t0)
        log(f"{_now()} FAILED: {rec['error']}\n{rec['traceback']}")
        return rec
    finally:
        logf.close()


def _failure(task: dict, err: BaseException, tb: str, started: str, elapsed: float) -> dict:
    msg = f"{type(err).__name__}: {err}"
    rec = {"format": ROW_FORMAT, "key": task["key"], "id": task["id"], "damper_id": task["damper_id"],
           "session": task["session"], "type": task["type"], "row": task["row"], "status": "failed",
           "error": msg, "traceback": tb, "started_at": started, "finished_at": _now(), "elapsed_s": elapsed,
           "host": socket.gethostname(), "pid": os.getpid()}
    try:
        write_atomic(Path(task["folder"]) / "failed.json", json.dumps(rec, indent=1))
    except OSError:
        pass  # the record still goes back to the batch and into its log and summary
    return rec


# --------------------------------------------------------------------------- executors

def parse_scheduler(spec: str | None) -> tuple[str, object]:
    """('pool', N) | ('local', N) | ('address', 'tcp://...') from a --scheduler value."""
    if spec is None or spec == "pool":
        return "pool", os.cpu_count() or 1
    m = re.fullmatch(r"(pool|local):(.*)", spec)
    if m:
        try:
            n = int(m.group(2))
        except ValueError:
            n = 0
        if n < 1:
            raise ValueError(f"--scheduler {spec}: the number of workers must be a positive integer, e.g. {m.group(1)}:2")
        return m.group(1), n
    if spec == "local":
        return "local", os.cpu_count() or 1
    if "://" in spec or re.fullmatch(r"[\w.-]+:\d+", spec):
        return "address", spec
    raise ValueError(f"--scheduler {spec!r}: expected pool, pool:N, local:N or a Dask scheduler address such as "
                     f"tcp://10.0.0.5:8786")


@contextlib.contextmanager
def _worker_environment():
    """WORKER_ENV in os.environ while worker processes are spawned (they inherit it)."""
    old = {k: os.environ.get(k) for k in WORKER_ENV}
    os.environ.update(WORKER_ENV)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


_GUARD = {"installed": False}


def _leave_without_teardown() -> None:
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)


def _in_worker(fn, arg):
    """Run fn(arg) in a worker process of this module's executors. The first call registers an
    exit that skips interpreter teardown: native FMU libraries have been seen to corrupt the heap
    when collected during finalisation (see tuner/__main__.py); every FMU is freed explicitly."""
    if not _GUARD["installed"]:
        import atexit

        atexit.register(_leave_without_teardown)
        _GUARD["installed"] = True
    return fn(arg)


class FleetExecutor:
    """Independent tasks on a local process pool or a Dask cluster; results as they finish.

    ``with FleetExecutor("local:2") as ex: for index, result, error in ex.run(fn, tasks): ...``;
    ``fn`` must be importable by the workers (a module-level function). ``error`` is the exception
    when the task could not run to its end (e.g. its worker process died), else None.
    """

    def __init__(self, scheduler: str | None = None):
        self.kind, self.arg = parse_scheduler(scheduler)
        self.n_workers = self.arg if self.kind != "address" else None
        self._pool = self._client = self._cluster = None

    @property
    def description(self) -> str:
        if self.kind == "pool":
            return f"local process pool of {self.arg} processes"
        if self.kind == "local":
            return f"Dask LocalCluster of {self.arg} worker processes"
        return f"Dask cluster at {self.arg}"

    def __enter__(self):
        if self.kind == "pool":
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor

            self._pool = ProcessPoolExecutor(max_workers=self.arg, mp_context=mp.get_context("spawn"))
        else:
            import logging

            import dask
            from distributed import Client, LocalCluster

            if self.kind == "local":
                with dask.config.set({"distributed.worker.daemon": False}):
                    self._cluster = LocalCluster(n_workers=self.arg, threads_per_worker=1, processes=True,
                                                 dashboard_address=None, silence_logs=logging.ERROR)
                self._client = Client(self._cluster)
            else:
                try:
                    self._client = Client(self.arg, timeout="20s")
                except (OSError, TimeoutError) as err:
                    raise ValueError(f"--scheduler {self.arg}: cannot reach the Dask scheduler ({err}); start it "
                                     f"with 'dask scheduler' and workers with 'dask worker {self.arg}'") from None
                self.n_workers = len(self._client.scheduler_info().get("workers", {})) or None
        return self

    def __exit__(self, *exc):
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
        if self._client is not None:
            self._client.close()
        if self._cluster is not None:
            self._cluster.close()
        self._pool = self._client = self._cluster = None

    def run(self, fn, tasks: list):
        """Yield (index, result, error) for every task, in the order they finish."""
        if not tasks:
            return
        if self._pool is not None:
            from concurrent.futures import as_completed

            with _worker_environment():
                futures = {self._pool.submit(_in_worker, fn, t): i for i, t in enumerate(tasks)}
            for fut in as_completed(futures):
                try:
                    yield futures[fut], fut.result(), None
                except Exception as err:  # noqa: BLE001 -- e.g. BrokenProcessPool: reported per task
                    yield futures[fut], None, err
        else:
            from distributed import as_completed

            futures = {}
            for i, t in enumerate(tasks):
                f = self._client.submit(_in_worker, fn, t, pure=False, key=f"{getattr(fn, '__name__', 'task')}-{i}-"
                                        f"{os.getpid()}-{time.time_ns()}")
                futures[f] = i
            for fut in as_completed(list(futures)):
                try:
                    yield futures[fut], fut.result(), None
                except Exception as err:  # noqa: BLE001 -- e.g. KilledWorker: reported per task
                    yield futures[fut], None, err


# --------------------------------------------------------------------------- the batch

def _batch_log(out: Path, msg: str) -> None:
    with open(out / "batch.log", "a", encoding="utf-8") as f:
        f.write(f"{_now()} {msg}\n")


def _done_record(folder: Path) -> dict | None:
    p = folder / "done.json"
    if not p.exists():
        return None
    try:
        return json.loads(p.read_text())
    except (json.JSONDecodeError, OSError):
        return None  # unreadable: the row is redone


def _prepare_folder(task: dict, out: Path, log) -> str:
    """'skip' (finished with the same key), or 'run' after clearing what an earlier attempt left."""
    folder = Path(task["folder"])
    if not folder.exists():
        return "run"
    rec = _done_record(folder)
    if rec is not None and rec.get("key") == task["key"]:
        return "skip"
    if rec is not None:  # finished with another row spec or settings: keep it, aside
        k, aside = 1, folder.with_name(f"{folder.name}.old")
        while aside.exists():
            k += 1
            aside = folder.with_name(f"{folder.name}.old-{k}")
        folder.rename(aside)
        log(f"{task['id']}: the manifest row or the settings changed since it finished; earlier results moved "
            f"to {aside}")
        return "run"
    if any(folder.iterdir()) and not (folder / "row.json").exists():
        raise FileExistsError(f"{task['where']}: {folder} exists and is not a batch row folder (no row.json); "
                              f"move it away or choose another --out")
    shutil.rmtree(folder)  # an interrupted or failed attempt of this batch: start the row afresh
    return "run"


def run_batch(manifest, out, *, scheduler: str | None = None, settings: dict | None = None,
              diagnose: bool = False, row_workers: int = 0, outlier_k: float = OUTLIER_K,
              outlier_tolerance: float = OUTLIER_TOLERANCE, progress: bool | None = None, log=print) -> dict:
    """Run (or resume) the batch of ``manifest`` into ``out``; write the fleet summary.

    settings: FitSettings fields used where the manifest leaves them open. Returns {"rows": [per
    manifest row: id, type, status ('done', 'failed', 'pending'), error, ran (bool: run now),
    record], "ran": [ids run now], "summary": paths, "outliers": {id: info}, "elapsed_s"}.
    """
    rows = read_fleet_manifest(manifest)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    base = FitSettings().to_dict()
    base.pop("workers")
    base.pop("extra")
    for k, v in (settings or {}).items():
        if k not in base:
            raise ValueError(f"unknown fit setting {k!r}")
        base[k] = v
    for name in ("population", "iterations", "polish_jacobians", "seed", "fit_rate_hz", "warmup_s", "engine"):
        _check_setting(name, base[name], "command line", name)
    if row_workers < 0:
        raise ValueError("--row-workers must be >= 0")
    tasks = [_task(r, out, base, diagnose, row_workers) for r in rows]
    state = {t["id"]: {"row": t["row"], "id": t["id"], "damper_id": t["damper_id"], "session": t["session"],
                       "type": t["type"], "seed": t["settings"].get("seed"), "status": "pending", "error": "",
                       "ran": False, "record": None} for t in tasks}
    todo = []
    for t in tasks:
        if _prepare_folder(t, out, log) == "skip":
            state[t["id"]].update(status="done", record=_done_record(Path(t["folder"])))
        else:
            todo.append(t)
    n_skip = len(tasks) - len(todo)
    t0 = time.perf_counter()
    ex = FleetExecutor(scheduler)
    log(f"batch: {len(tasks)} rows, {n_skip} finished earlier, {len(todo)} to run on a {ex.description}; "
        f"results in {out}")
    if todo and ex.kind != "address":  # build the FMUs once here, not concurrently in every worker
        for m in sorted({m for t in todo for m in t["settings"]["models"]}):
            ensure_fmu(m)
    ran = []
    try:
        if todo:
            bar = tqdm(total=len(todo), unit="row", desc="fleet", file=sys.stderr,
                       disable=(not sys.stderr.isatty()) if progress is None else not progress)
            with ex:
                for t in todo:
                    _batch_log(out, f"start {t['id']} ({t['where']})")
                for i, rec, err in ex.run(run_row, todo):
                    t = todo[i]
                    if err is not None:  # the worker died: the task never returned its own record
                        rec = _failure(t, err, "".join(traceback.format_exception(err)), "", float("nan"))
                        rec["error"] = f"worker lost ({type(err).__name__}: {err}); rerun the batch to retry this row"
                    st = state[t["id"]]
                    st.update(status=rec["status"], error=rec.get("error", ""), ran=True,
                              record=rec if rec["status"] == "done" else None)
                    ran.append(t["id"])
                    _batch_log(out, f"{rec['status']} {t['id']} in {rec.get('elapsed_s', float('nan')):.1f} s"
                               + (f": {rec['error']}" if rec["status"] == "failed" else ""))
                    bar.update(1)
                    line = (f"[{len(ran)}/{len(todo)}] {t['id']}: {rec['status']} "
                            f"({rec.get('elapsed_s', float('nan')):.0f} s)")
                    if rec["status"] == "failed":
                        line += f": {rec['error']}"
                    (log if bar.disable else bar.write)(line)
            bar.close()
    finally:
        rows_out = [state[t["id"]] for t in tasks]
        summary = write_summary(out, rows_out, k=outlier_k, tolerance=outlier_tolerance,
                                title=f"Fleet summary: {Path(manifest).name}")
    for r in rows_out:
        o = summary["outliers"].get(r["id"])
        r["outlier"] = bool(o and o["outlier"])
    n_fail = sum(r["status"] == "failed" for r in rows_out)
    odd = [r["id"] for r in rows_out if r["outlier"]]
    log(f"batch: {sum(r['status'] == 'done' for r in rows_out)} done, {n_fail} failed in "
        f"{time.perf_counter() - t0:.0f} s; outliers: {', '.join(odd) if odd else 'none'}")
    log(f"summary: {summary['html']}")
    return {"rows": rows_out, "ran": ran, "summary": summary, "outliers": summary["outliers"],
            "elapsed_s": time.perf_counter() - t0}


# --------------------------------------------------------------------------- command line

#: how to continue an interrupted batch (finished rows are never redone)
CONTINUE_HINT = "run the same command again to continue (finished rows are kept)"


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the ``batch`` sub-command on an argparse subparsers object (func=cmd_batch)."""
    p = subparsers.add_parser("batch", help="identify a fleet: one fit per manifest row, fleet summary",
                              description=__doc__.split("\n\n")[0])
    _add_arguments(p)
    p.set_defaults(func=cmd_batch)
    return p


def _add_arguments(p: argparse.ArgumentParser) -> None:
    d = FitSettings()
    p.add_argument("manifest", type=Path, help="fleet manifest (CSV or TOML), one row per damper test session")
    p.add_argument("--out", type=Path, default=None,
                   help="results folder (default results/<manifest name>); rerunning continues it")
    p.add_argument("--scheduler", default=None, metavar="SPEC",
                   help="pool (default: local process pool of os.cpu_count() processes), pool:N, local:N (Dask "
                        "LocalCluster of N workers) or a Dask scheduler address tcp://HOST:PORT")
    p.add_argument("--diagnose", action="store_true", help="run the diagnosis after each fit (rows may say "
                   "diagnose = true/false)")
    g = p.add_argument_group("fit settings where the manifest leaves them open")
    g.add_argument("--models", default=None, help=f"e.g. lumped,maxwell (default {','.join(d.models)})")
    g.add_argument("--population", type=int, default=None, help=f"fireflies (default {d.population})")
    g.add_argument("--iterations", type=int, default=None, help=f"max iterations (default {d.iterations})")
    g.add_argument("--polish", type=int, default=None, help=f"refinement cap in Jacobians (default {d.polish_jacobians})")
    g.add_argument("--seed", type=int, default=None, help=f"seed of every row without its own (default {d.seed})")
    g.add_argument("--engine", default=None, choices=["fmu", "native", "inprocess"])
    g.add_argument("--fit-rate", type=float, default=None, help=f"[Hz] (default {d.fit_rate_hz:g})")
    g.add_argument("--warmup", type=float, default=None, help=f"[s] (default {d.warmup_s:g})")
    g.add_argument("--row-workers", type=int, default=0,
                   help="evaluation processes inside each row (default 0: in the row's process)")
    g = p.add_argument_group("fleet summary")
    g.add_argument("--outlier-k", type=float, default=OUTLIER_K, help="k of the median +- k x 1.4826 MAD rule "
                   "(default %(default)s)")
    g.add_argument("--outlier-tolerance", type=float, default=OUTLIER_TOLERANCE,
                   help="smallest band as a fraction of |median| (default %(default)s)")


def cmd_batch(args) -> int:
    """Run the batch of ``args`` (the ``batch`` sub-command); 0 all done, 1 some rows failed."""
    settings = {}
    if args.models is not None:
        settings["models"] = _convert(args.models, "models", "--models", "models")
    for opt, name in (("population", "population"), ("iterations", "iterations"), ("polish", "polish_jacobians"),
                      ("seed", "seed"), ("engine", "engine"), ("fit_rate", "fit_rate_hz"), ("warmup", "warmup_s")):
        v = getattr(args, opt)
        if v is not None:
            settings[name] = v
    manifest = Path(args.manifest)
    out = args.out or Path(__file__).resolve().parents[2] / "results" / manifest.stem
    if args.outlier_k <= 0 or args.outlier_tolerance < 0:
        raise ValueError("--outlier-k must be > 0 and --outlier-tolerance >= 0")
    res = run_batch(manifest, out, scheduler=args.scheduler, settings=settings, diagnose=args.diagnose,
                    row_workers=args.row_workers, outlier_k=args.outlier_k, outlier_tolerance=args.outlier_tolerance)
    failed = [r for r in res["rows"] if r["status"] == "failed"]
    for r in failed:
        print(f"failed: {r['id']}: {r['error']}", file=sys.stderr)
    return 1 if failed else 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tuner batch", description=__doc__.split("\n\n")[0])
    _add_arguments(ap)
    args = ap.parse_args(sys.argv[1:] if argv is None else list(argv))
    return run_handler(cmd_batch, args, CONTINUE_HINT)


if __name__ == "__main__":
    # run the importable module's main, so that worker processes unpickle tuner.cli.batch.run_row
    from tuner.cli.batch import main as _main

    sys.exit(_main())
