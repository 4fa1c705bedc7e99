"""Where independent tasks run: a local process pool or a Dask cluster (``--scheduler``,
``--vehicle-scheduler``), results as they finish.

Used by the fleet's rows (``tuner.fleet.batch``), the job's vehicle scenarios (``tuner.job``) and the
vehicle's parameter draws (``tuner.vehicle.propagation``); at the top of the package, beside
``tuner.worker_processes`` (how the pools start), so that each of them imports it downward.
"""
from __future__ import annotations

import os
import re
import time

from tuner.worker_processes import WORKER_ENV, exit_with_parent, pool_context, worker_environment

__all__ = ["FleetExecutor", "parse_scheduler", "WORKER_ENV"]


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


def _in_worker(fn, arg):
    """Run fn(arg) in a worker process of this module's executors (every FMU a task opens is freed by
    the task, or at the worker's exit by ``tuner.identification.runner``)."""
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
            from concurrent.futures import ProcessPoolExecutor

            self._pool = ProcessPoolExecutor(max_workers=self.arg, mp_context=pool_context(),
                                             initializer=exit_with_parent)
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

            with worker_environment():
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


