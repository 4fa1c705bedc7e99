"""Fleet batch identification (``python -m tuner batch MANIFEST``, command line in ``tuner.cli.batch``).

- ``manifest``: the rows of a manifest (CSV or TOML), read and checked;
- ``batch``: one row, the whole batch, and its resumption.

Where the rows run (a local process pool or Dask) is ``tuner.executors``, shared with the job's vehicle runs.

One manifest row per damper test session; every row runs the tuner's job (``tuner.job.run``: fit, and
with ``--diagnose`` the diagnosis) into its own folder
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
* column mapping and units, passed to ``tuner.data.reading.load_files`` as a ``ReadOptions``
  (``tuner.data.read_options``): ``time_col``, ``stroke_col``, ``force_col``, ``temperature_col``,
  ``time_unit``, ``stroke_unit``, ``force_unit``, ``temperature_unit`` (and any other of its options
  ending in ``_col``, ``_unit`` or ``_sign``);
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
