"""How this package starts its worker processes: the identification engines' pools
(``tuner.identification.engine``), the local pools of the fleets and the vehicle draws
(``tuner.executors``) and the report's figures (``map_in_workers``).

'forkserver' where the platform has it (Linux, macOS): a server process imports the simulation modules
once (``PRELOAD``) and every pool's workers fork from it with them loaded. With 'spawn' each worker
imported numpy, scipy, fmpy and this package anew: a two-worker engine took 2.5 s to open and run its
first batch and 0.55 s to close, against 0.12 s and 0.02 s from the fork server (the first pool of a
process pays the server's start, 2 s), and the main job opens about ten. 'spawn' elsewhere (Windows).
Never 'fork' of the calling process itself: it may hold threads (BLAS, a progress display) and FMU
instances that a child must not inherit. As with 'spawn', a script that opens a pool needs an
``if __name__ == "__main__":`` guard.

Every worker ends when the process that opened its pool is gone (``exit_with_parent``): a run killed from
outside (``kill``, a CI timeout) leaves no workers behind. With the fork server a worker's parent process is the
server, which lives as long as any worker (each holds the server's liveness pipe), so the worker watches the
pool's owner instead: ``multiprocessing.parent_process()``'s sentinel, a pipe only the owner holds open.
Before it ends it runs what was registered with ``on_orphan_exit`` (the FMU runners delete their extracted
folders), with no other clean-up: the owner is gone and the main thread may be inside an FMU.

Every worker runs with ``WORKER_ENV`` (one BLAS thread: the pool is the parallel level, and the same
thread count everywhere keeps the numbers the same on every executor): the fork server is started
with it, and spawned processes (Windows, a Dask LocalCluster) inherit it from ``worker_environment``.
"""
from __future__ import annotations

import contextlib
import multiprocessing as mp
from concurrent.futures import ProcessPoolExecutor
import multiprocessing.connection
import os
import threading

__all__ = ["pool_context", "worker_environment", "exit_with_parent", "on_orphan_exit", "map_in_workers", "PRELOAD",
           "WORKER_ENV"]

#: the modules the fork server imports once: what a worker needs to simulate a damper or the vehicle
PRELOAD = ("tuner.identification.engine", "tuner.vehicle.propagation")
#: environment of every worker process (module docstring)
WORKER_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
#: what a worker whose owner has gone does before it exits (``on_orphan_exit``)
_ON_ORPHAN_EXIT: list = []
#: (function, context) of a ``map_in_workers`` worker
_MAPPED: list = []


@contextlib.contextmanager
def worker_environment():
    """WORKER_ENV in os.environ while worker processes (or the fork server) start: they inherit it."""
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


def pool_context():
    """The multiprocessing context of a worker pool (module docstring); the fork server running."""
    if "forkserver" not in mp.get_all_start_methods():
        return mp.get_context("spawn")
    from multiprocessing import forkserver

    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(list(PRELOAD))
    with worker_environment():
        forkserver.ensure_running()
    return ctx


def exit_with_parent() -> None:
    """In a worker process: a daemon thread that ends the process (exit status 0) once the process that opened the
    pool has ended, after what ``on_orphan_exit`` registered and no other clean-up (module docstring). Nothing
    outside a pool's worker."""
    parent = mp.parent_process()
    if parent is None or parent.sentinel is None:
        return
    threading.Thread(target=_end_with, args=(parent.sentinel,), daemon=True, name="exit-with-parent").start()


def on_orphan_exit(clean_up) -> None:
    """Have ``clean_up()`` run in this worker just before it ends because its owner has gone
    (``exit_with_parent``): files only (removing a folder this process extracted), no calls into a library
    another thread of the worker may be inside. Registering the same callable again does nothing."""
    if clean_up not in _ON_ORPHAN_EXIT:
        _ON_ORPHAN_EXIT.append(clean_up)


def _end_with(sentinel) -> None:
    mp.connection.wait([sentinel])
    for clean_up in list(_ON_ORPHAN_EXIT):
        try:
            clean_up()
        except OSError:  # the process ends anyway; a folder left behind is all that is lost
            pass
    os._exit(0)


def map_in_workers(fn, items: list, workers: int, context: tuple = ()) -> list:
    """``[fn(item, *context) for item in items]``, in ``min(workers, len(items))`` worker processes of this module
    when ``workers`` >= 2 (``context`` sent once to each, ``fn`` a module-level function), in this process
    otherwise. Independent CPU-bound items only (the report's figures)."""
    if workers < 2 or len(items) < 2:
        return [fn(item, *context) for item in items]
    with worker_environment(), ProcessPoolExecutor(max_workers=min(workers, len(items)), mp_context=pool_context(),
                                                   initializer=_start_mapped, initargs=(fn, context)) as pool:
        return list(pool.map(_call_mapped, items))


def _start_mapped(fn, context: tuple) -> None:
    exit_with_parent()  # a killed run leaves no workers behind
    _MAPPED[:] = [fn, context]


def _call_mapped(item):
    fn, context = _MAPPED
    return fn(item, *context)
