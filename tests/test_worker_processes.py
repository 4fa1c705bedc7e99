"""Worker pools (tuner.worker_processes): a run killed from outside leaves no worker behind."""
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as f:  # a zombie is gone for our purpose
        return f.read().split(")")[-1].split()[0] != "Z"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_the_workers_of_a_killed_run_end_with_it(tmp_path):
    script = tmp_path / "run.py"
    script.write_text(textwrap.dedent("""
        import os, sys, time
        from tuner.executors import FleetExecutor

        def pid(_):
            time.sleep(0.2)
            return os.getpid()

        if __name__ == "__main__":
            with FleetExecutor("pool:2") as ex:
                pids = {r for _, r, _ in ex.run(pid, [0, 1, 2, 3])}
                print(" ".join(map(str, sorted(pids))), flush=True)
                time.sleep(120)
    """))
    proc = subprocess.Popen([sys.executable, str(script)], cwd=ROOT, stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        workers = [int(p) for p in proc.stdout.readline().split()]
        assert workers and all(_alive(p) for p in workers)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    deadline = time.monotonic() + 30.0
    while any(_alive(p) for p in workers) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not [p for p in workers if _alive(p)], "workers outlived the killed run"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_the_workers_of_a_killed_fit_remove_their_extracted_fmus(tmp_path):
    """An engine's workers on the FMU engine each extract the FMU into the temporary folder; killed with the run
    that opened them, they delete those folders before they end (before, each one stayed: a run stopped by a CI
    timeout or kill -9 left two per engine)."""
    # a short folder of its own: the forkserver's socket lives in TMPDIR, and a Unix socket path is limited to 107
    # bytes (under pytest's basetemp the path outgrew it once its run counter reached three digits)
    temp = Path(tempfile.mkdtemp(prefix="wk_", dir="/tmp"))
    try:
        _killed_fit_cleans_up(tmp_path, temp)
    finally:
        shutil.rmtree(temp, ignore_errors=True)


def _killed_fit_cleans_up(tmp_path: Path, temp: Path) -> None:
    script = tmp_path / "fit.py"
    script.write_text(textwrap.dedent("""
        import os, time
        from pathlib import Path
        from damper_fmu import defaults
        from tuner.data.reading import load_dataset
        from tuner.identification.engine import Engine
        from tuner.identification.fit import FitSettings, ensure_fmu
        from tuner.identification.problem import Problem

        if __name__ == "__main__":
            tests = load_dataset(Path("data/default"))[:1]
            problem = Problem.build(tests, [], FitSettings().data)
            with Engine("maxwell", problem.sig_id, engine="fmu", workers=2, fmu_path=ensure_fmu("maxwell")) as eng:
                eng.fitness_batch([defaults("maxwell")] * 4)
                print(" ".join(str(p) for p in eng._pool._processes), flush=True)
                time.sleep(120)
    """))
    proc = subprocess.Popen([sys.executable, str(script)], cwd=ROOT, stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT), "TMPDIR": str(temp)})
    try:
        workers = [int(p) for p in proc.stdout.readline().split()]
        assert workers and all(_alive(p) for p in workers)
        started = time.monotonic() + 30.0  # a worker extracts its FMU as it starts
        while len(list(temp.glob("damper_runner_*"))) < len(workers) and time.monotonic() < started:
            time.sleep(0.2)
        assert len(list(temp.glob("damper_runner_*"))) == len(workers)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    deadline = time.monotonic() + 30.0
    while (any(_alive(p) for p in workers) or list(temp.glob("damper_runner_*"))) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not [p for p in workers if _alive(p)], "workers outlived the killed run"
    assert not list(temp.glob("damper_runner_*")), "the killed run's workers left their extracted FMUs"
