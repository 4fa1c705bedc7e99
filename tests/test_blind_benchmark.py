"""The blind benchmark's bookkeeping (benchmarks/blind_class.py): a run that raises is kept as a failed row and
the others go on; every row is written as one strict-JSON line as it ends, so that the same command resumes a
stopped benchmark and more seeds add to it; the table counts a fault the verdict said the base absorbs apart
from a fault named. The diagnoses themselves are replaced by a serial stand-in (their behaviour is tested in
tests/test_diagnose.py and measured by the benchmark)."""
import json

import pytest

import benchmarks.blind_class as bc


class SerialExecutor:
    """The executor's interface (``tuner.executors.FleetExecutor``), in this process."""

    description = "serial stand-in"

    def __init__(self, scheduler):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def run(self, fn, tasks):
        for i, task in enumerate(tasks):
            try:
                yield i, fn(task), None
            except Exception as exc:  # noqa: BLE001 - the executor reports it, as the real one does
                yield i, None, exc


def _fake_run(calls):
    def run_case(case):
        calls.append(case["seed"])
        if case["seed"] == bc.case_seed("valve_lag+preload", 1):
            raise RuntimeError("the reader refused the data")
        named = ["valve_lag"] if case["case"] == "valve_lag+preload" else ["free_play", "friction"]
        return {**case, "causes": named, "named": named[0], "base": "lumped", "fitted": {}, "truth": {},
                "confounded": {"preload": 0.97} if case["case"] == "valve_lag+preload" else {}, "elapsed_s": 1.0}
    return run_case


def test_a_failed_run_is_kept_the_rows_are_strict_json_and_a_second_call_resumes(tmp_path, monkeypatch, capsys):
    calls = []
    monkeypatch.setattr(bc, "FleetExecutor", SerialExecutor)
    monkeypatch.setattr(bc, "run_case", _fake_run(calls))
    argv = ["--cases", "free_play+friction,valve_lag+preload", "--seeds", "2", "--out", str(tmp_path)]
    assert bc.main(argv) == 0
    assert len(calls) == 4
    lines = (tmp_path / "rows.jsonl").read_text().splitlines()
    rows = [json.loads(line, parse_constant=lambda c: pytest.fail(f"non-strict JSON constant {c}")) for line in lines]
    assert len(rows) == 4 and sum("error" in r for r in rows) == 1
    table = capsys.readouterr().out.splitlines()
    vp = [line for line in table if line.startswith("valve_lag+preload")][-1].split()  # the table, after the rows
    # runs 2, all named 0, some 1, on its base 0, named or said absorbed 1, unexplained 0, false 0, failed 1
    assert vp[1:9] == ["2", "0", "1", "0", "1", "0", "0", "1"]
    calls.clear()
    assert bc.main([*argv[:4], "--seeds", "3", "--out", str(tmp_path)]) == 0  # one more seed: only it runs
    assert calls == [bc.case_seed("free_play+friction", 2), bc.case_seed("valve_lag+preload", 2)]
    assert len((tmp_path / "rows.jsonl").read_text().splitlines()) == 6


def test_a_damaged_rows_file_is_named_with_its_line(tmp_path):
    (tmp_path / "rows.jsonl").write_text('{"case": "x"}\n{"case": \n')
    with pytest.raises(SystemExit, match=r"rows.jsonl, line 2"):
        bc.done_rows(tmp_path / "rows.jsonl")


def test_said_is_what_the_verdict_says():
    """A fault counts as said when the verdict lists it as not told apart: its detection limit untold (absorbed,
    no plausible magnitude detectable) or, under an unexplained residual, a candidate explaining the same residual
    as the base; absorbed alone, with a plausible magnitude detectable, is not said."""
    limit = {"reachable": True, "within_plausible": False, "absorbed_share": 0.98, "limit": 2340.0}
    res = {"detection_limits": {"preload": limit, "friction": {**limit, "within_plausible": True},
                                "free_play": {**limit, "absorbed_share": 0.5, "reachable": False}},
           "unexplained": {"indistinguishable": [{"effect": "time_delay", "absorbed_share": 0.99}]}}
    assert bc.confounded(res) == {"preload": 0.98, "time_delay": 0.99}
    assert bc.confounded({"detection_limits": None, "unexplained": None}) == {}
