"""The batch: one row (``run_row``: the tuner's job into the row's folder, its record), the whole batch
(``run_batch``: resume, executors, the fleet summary)."""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import socket
import sys
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

from tqdm import tqdm

from damper_fmu.fmu import ensure_fmu
from damper_fmu.parameters import EFFECT_MODELS
from tuner import job
from tuner.data.read_options import ReadOptions
from tuner.data.reading import DataError, load_dataset, load_files
from tuner.executors import FleetExecutor
from tuner.fleet.manifest import Row, check_setting, read_fleet_manifest
from tuner.identification.fit import FitSettings
from tuner.results.fleet_summary import OUTLIER_K, OUTLIER_TOLERANCE, write_atomic, write_summary
from tuner import strict_json

__all__ = ["run_row", "run_batch", "BatchOptions", "ROW_FORMAT"]

ROW_FORMAT = "tuner-batch-row/1"


@dataclass(frozen=True)
class BatchOptions:
    """How ``run_batch`` runs a manifest (the command line's options of ``python -m tuner batch``). ``scheduler``:
    where the rows run (``tuner.executors.parse_scheduler``'s spec; None: the default pool); ``settings``:
    FitSettings fields used where the manifest leaves them open; ``diagnose``: each row's job diagnoses after its
    fit; ``row_workers``: worker processes of each row's own fit (0: in the row's process); ``outlier_k``,
    ``outlier_tolerance``: the fleet summary's outlier rule (``tuner.results.fleet_summary``); ``progress``: the
    progress bar (None: when stderr is a terminal); ``figures``: False writes each row's report without its figures
    (``tuner.results.report.make_report``: about 7 s less a row)."""

    scheduler: str | None = None
    settings: dict | None = None
    diagnose: bool = False
    row_workers: int = 0
    outlier_k: float = OUTLIER_K
    outlier_tolerance: float = OUTLIER_TOLERANCE
    progress: bool | None = None
    figures: bool = True


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S%z")


def _task(row: Row, out: Path, base_settings: dict, diagnose: bool, row_workers: int, figures: bool) -> dict:
    """The picklable description of one row's work (sent to a worker); ``key`` identifies the row's results
    (not ``figures``: a report's figures are drawn again by ``python -m tuner report``)."""
    s = {**base_settings, **row.settings, "workers": int(row_workers)}
    s["models"] = list(s.get("models", FitSettings().models))
    do_diag = row.diagnose if row.diagnose is not None else diagnose
    spec = {"id": row.id, "damper_id": row.damper_id, "session": row.session, "type": row.type,
            "identification": row.identification, "validation": row.validation, "dataset": row.dataset,
            "columns": row.columns, "settings": {k: v for k, v in s.items() if k != "workers"},
            "diagnose": bool(do_diag)}
    key = hashlib.sha256(json.dumps(spec, sort_keys=True, default=str).encode()).hexdigest()[:16]
    return {**spec, "key": key, "row": row.number, "where": row.where, "folder": str(Path(out) / row.id),
            "workers": int(row_workers), "figures": bool(figures)}


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
            read = ReadOptions.of(**task["columns"])
            ident = load_files(task["identification"], "identification", read)
            valid = load_files(task["validation"], "validation", read) if task["validation"] else []
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
    params = strict_json.loads((folder / "parameters.json").read_text())
    metrics = strict_json.loads((folder / "metrics.json").read_text())
    rmse, noise = {}, None
    for m in params:
        h = folder / f"history_{m}.json"
        if h.exists():
            hist = strict_json.loads(h.read_text())
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
        d = strict_json.loads(dj.read_text())
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
    write_atomic(folder / "row.json", strict_json.dumps({k: v for k, v in task.items()}, indent=1))
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
        settings = FitSettings.from_dict({**task["settings"], "workers": task["workers"]})
        provenance = {"files": {t.name: str(t.source) for t in ident + valid},
                      "command": f"python -m tuner batch ({task['where']})", "batch_row": task["id"]}
        if task["diagnose"]:
            if not valid:
                raise DataError(f"{task['where']}: diagnose needs validation files (its decision is the held-out "
                                    f"gain); fill 'validation' or set diagnose = false")
            if not job.wants_diagnosis(settings, valid):
                raise ValueError(f"{task['where']}: the diagnosis needs one of {', '.join(EFFECT_MODELS)} "
                                 f"in 'models'")
        job.run(ident, valid, folder, settings, log=log,
                options=job.JobOptions(diagnose_after=task["diagnose"], provenance=provenance, figures=task["figures"]))
        rec = _record(task, folder, started, time.perf_counter() - t0, n_lines)
        write_atomic(folder / "done.json", strict_json.dumps(rec, indent=1, sort_keys=True))
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
        write_atomic(Path(task["folder"]) / "failed.json", strict_json.dumps(rec, indent=1))
    except OSError:
        pass  # the record still goes back to the batch and into its log and summary
    return rec


def _batch_log(out: Path, msg: str) -> None:
    with open(out / "batch.log", "a", encoding="utf-8") as f:
        f.write(f"{_now()} {msg}\n")


def _done_record(folder: Path) -> dict | None:
    p = folder / "done.json"
    if not p.exists():
        return None
    try:
        return strict_json.loads(p.read_text())
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


def _batch_settings(settings: dict | None, row_workers: int) -> dict:
    """The fit settings of the rows where the manifest leaves them open: the defaults with ``settings`` over them
    (ValueError naming an unknown or bad setting, or a negative ``row_workers``)."""
    base = FitSettings().to_dict()
    base.pop("workers")
    base.pop("extra")
    for k, v in (settings or {}).items():
        if k not in base:
            raise ValueError(f"unknown fit setting {k!r}")
        base[k] = v
    for name in ("population", "iterations", "polish_jacobians", "seed", "fit_rate_hz", "warmup_s", "engine"):
        check_setting(name, base[name], "command line", name)
    if row_workers < 0:
        raise ValueError("--row-workers must be >= 0")
    return base


def run_batch(manifest, out, *, options: BatchOptions = BatchOptions(), log=print) -> dict:
    """Run (or resume) the batch of ``manifest`` into ``out`` as ``options`` say (``BatchOptions``); write the
    fleet summary. Returns {"rows": [per
    manifest row: id, type, status ('done', 'failed', 'pending'), error, ran (bool: run now),
    record], "ran": [ids run now], "summary": paths, "outliers": {id: info}, "elapsed_s"}.
    """
    rows = read_fleet_manifest(manifest)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    base = _batch_settings(options.settings, options.row_workers)
    tasks = [_task(r, out, base, options.diagnose, options.row_workers, options.figures) for r in rows]
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
    ex = FleetExecutor(options.scheduler)
    log(f"batch: {len(tasks)} rows, {n_skip} finished earlier, {len(todo)} to run on a {ex.description}; "
        f"results in {out}")
    if todo and ex.kind != "address":  # build the FMUs once here, not concurrently in every worker
        for m in sorted({m for t in todo for m in t["settings"]["models"]}):
            ensure_fmu(m)
    ran = []
    try:
        if todo:
            bar = tqdm(total=len(todo), unit="row", desc="fleet", file=sys.stderr,
                       disable=(not sys.stderr.isatty()) if options.progress is None else not options.progress)
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
        summary = write_summary(out, rows_out, k=options.outlier_k, tolerance=options.outlier_tolerance,
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


