"""Fleet batch identification (tuner.fleet, command line tuner.cli.batch): manifest checks, local pool vs Dask LocalCluster,
outlier flag, failed row, kill and restart."""
from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

from tuner.cli.batch import add_parser, cmd_batch, main  # noqa: E402
from tuner.fleet.batch import BatchOptions, run_batch  # noqa: E402
from tuner.fleet.manifest import ManifestError, read_fleet_manifest  # noqa: E402
from tuner.results.fleet_summary import find_outliers  # noqa: E402

#: small Firefly budget: the batch machinery is tested here, not the identification
#: a small fit of the paper's two models: these tests are about the fleet, not the model forms
SMALL = ["--population", "6", "--iterations", "4", "--polish", "3", "--models", "lumped+maxwell"]
SMALL_SETTINGS = {"population": 6, "iterations": 4, "polish_jacobians": 3, "models": ("lumped", "maxwell")}
#: (row id, type, rig damper, dataset seed, hidden effects): two types, one damper with friction; type B has one
#: damper (too few to judge: a second one only cost time)
DAMPERS = [("A1", "A", "lumped", 1, {}), ("A2", "A", "lumped", 2, {}), ("A3", "A", "lumped", 3, {"friction": 250.0}),
           ("B1", "B", "twin-tube", 2, {})]
IDS = [d[0] for d in DAMPERS]


#: the campaign's scenarios a row uses (the other two are not generated)
IDENTIFICATION = ["id1_straight_250", "id2_curve_R400_72", "id3_switch_R190_43"]
VALIDATION = ["val1_straight_250"]


def _files(name: str, role: str) -> str:
    return ";".join(f"data/{name}/{p}.csv" for p in (IDENTIFICATION if role == "id" else VALIDATION))


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    from campaign.generate import CampaignPlan, generate_dataset

    base = tmp_path_factory.mktemp("fleet")
    for name, _, damper, seed, effects in DAMPERS:
        generate_dataset(base / "data" / name, seed=seed, damper=damper, effects=effects,
                         plan=CampaignPlan(scenarios=IDENTIFICATION + VALIDATION, t_end=5.0), overview=False,
                         log=lambda m: None)
    lines = ["# fleet of the batch test: two types, A3 with hidden friction, X9 with a missing file",
             "damper_id,type,identification,validation,seed"]
    lines += [f"{name},{typ},{_files(name, 'id')},{_files(name, 'val')},7" for name, typ, *_ in DAMPERS]
    lines.append("X9,B,data/missing/id1.csv,,7")
    manifest = base / "fleet.csv"
    manifest.write_text("\n".join(lines) + "\n")
    return manifest


def _params(out: Path, rid: str) -> dict:
    return json.loads((out / rid / "parameters.json").read_text())


def _check_fleet(res: dict, out: Path) -> None:
    st = {r["id"]: r for r in res["rows"]}
    assert [st[i]["status"] for i in IDS] == ["done"] * len(IDS)
    bad = st["X9"]
    assert bad["status"] == "failed"
    assert "fleet.csv row 5" in bad["error"] and "'identification'" in bad["error"] and "not found" in bad["error"]
    # the odd damper (hidden friction) lies outside its type's spread; its siblings do not; type B
    # (one damper) is not judged
    assert res["outliers"]["A3"]["outlier"] and res["outliers"]["A3"]["ratio"] > 1.5
    assert not res["outliers"]["A1"]["outlier"] and not res["outliers"]["A2"]["outlier"]
    assert res["outliers"]["B1"]["ratio"] is None
    csv_text = (out / "summary.csv").read_text()
    rows = csv_text.strip().splitlines()
    assert len(rows) == 1 + len(IDS) + 1
    assert rows[0].startswith("row,id,damper_id,session,type,status,error")
    assert "validation.val1_straight_250.lumped.ame_n" in rows[0] and "lumped.Fc_01 [N]" in rows[0]
    html = (out / "summary.html").read_text()
    assert "1.4826" in html and "A3" in html and "fc_A.png" in html
    assert (out / "figures" / "fc_A.png").stat().st_size > 1000 and (out / "figures" / "fc_B.png").exists()
    # the rows' reports were written without their figures (--no-row-figures): each slot says so
    assert "Figure not drawn" in (out / IDS[0] / "report.html").read_text() and not (out / IDS[0] / "figures").exists()
    for i in IDS:
        rec = json.loads((out / i / "done.json").read_text())
        assert rec["seed"] == 7 and rec["validation"]["val1_straight_250"]["lumped"]["ame"] > 0


@pytest.mark.slow  # 65-107 s in the suite on the 2-core machine (a one-row pool batch, a Dask batch killed,
#                   restarted)
def test_pool_dask_kill_and_restart(fleet, tmp_path):
    # 1. the local process pool: the reference, on the fleet's first row (the same row of a one-row manifest
    #    beside it; every row through the pool would only repeat what the Dask runs check)
    out_pool, lines = tmp_path / "pool", []
    one = fleet.with_name("first_row.csv")
    one.write_text("\n".join(fleet.read_text().splitlines()[:3]) + "\n")
    res = run_batch(one, out_pool, options=BatchOptions(scheduler="pool:2", settings=SMALL_SETTINGS,
                                                           progress=False, figures=False), log=lines.append)
    assert res["ran"] == [IDS[0]] and [r["status"] for r in res["rows"]] == ["done"]

    # 2. the same batch on a Dask LocalCluster of 2 workers, killed (process group, SIGKILL) once a
    #    row has finished
    out = tmp_path / "dask"
    proc = subprocess.Popen([sys.executable, "-m", "tuner.cli.batch", str(fleet), "--out", str(out), "--scheduler",
                             "local:2", "--no-row-figures", *SMALL], cwd=ROOT, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t0 = time.monotonic()
    try:
        while not any((out / i / "done.json").exists() for i in IDS):
            assert proc.poll() is None, "the batch ended before it could be killed"
            assert time.monotonic() - t0 < 120, "no row finished within 120 s"
            time.sleep(0.1)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    finished = {i: (out / i / "done.json").stat().st_mtime_ns for i in IDS if (out / i / "done.json").exists()}
    assert 1 <= len(finished) < len(IDS)

    # 3. restarted on Dask: only what had not finished runs; every row ends done, with exactly the
    #    pool's numbers
    res = run_batch(fleet, out, options=BatchOptions(scheduler="local:2", settings=SMALL_SETTINGS,
                                                           progress=False, figures=False), log=lines.append)
    _check_fleet(res, out)
    assert sorted(res["ran"]) == sorted(set(IDS + ["X9"]) - set(finished))
    for i, mtime in finished.items():
        assert (out / i / "done.json").stat().st_mtime_ns == mtime, f"{i} finished before the kill but was redone"
    assert _params(out, IDS[0]) == _params(out_pool, IDS[0]), "Dask and the local pool differ"
    log = (out / "batch.log").read_text()
    assert all(log.count(f"done {i} in") <= 1 for i in IDS), log  # no row finished twice

    # 4. a rerun with nothing to do runs nothing; the failed row is retried (and fails again)
    res = run_batch(fleet, out, options=BatchOptions(scheduler="pool:1", settings=SMALL_SETTINGS,
                                                           progress=False, figures=False), log=lines.append)
    assert res["ran"] == ["X9"]


def test_manifest_errors_name_row_and_column(tmp_path):
    m = tmp_path / "m.csv"
    cases = {
        "damper_id,type,identification,colour\nA1,A,a.csv,red\n": "unknown column(s) ['colour']",
        "damper_id,type,identification,population\nA1,A,a.csv,many\n": "row 1 (line 2), column 'population': 'many' is not an integer",
        "damper_id,type,identification\nA1,A,a.csv\nA1,A,b.csv\n": "id 'A1' (damper_id + session) repeats",
        "damper_id,type,identification\nA 1,A,a.csv\n": "column 'damper_id': 'A 1' is not usable as a folder name",
        "damper_id,type,identification\nA1,,a.csv\n": "column 'type' is empty or missing",
        "damper_id,type,validation\nA1,A,a.csv\n": "no identification files",
        "damper_id,type,identification,models\nA1,A,a.csv,lumped+spring\n": "unknown model(s)",
        "damper_id,type,identification,population\nA1,A,a.csv,1\n": "population must be >= 2",
    }
    for text, msg in cases.items():
        m.write_text(text)
        with pytest.raises(ManifestError, match=None) as err:
            read_fleet_manifest(m)
        assert msg in str(err.value) and "m.csv" in str(err.value), (msg, str(err.value))
    # exit status 2 with the message for a bad manifest
    m.write_text("damper_id,type,identification,colour\nA1,A,a.csv,red\n")
    assert main([str(m), "--out", str(tmp_path / "o")]) == 2


def test_toml_manifest_defaults_sessions_and_columns(tmp_path):
    m = tmp_path / "fleet.toml"
    m.write_text("""
[defaults]
population = 8
stroke_unit = "mm"
[[damper]]
damper_id = "YD-1"
type = "A"
session = "acceptance"
identification = ["d/id1.csv", "d/id2.csv"]
validation = "d/v1.csv;d/v2.csv"
seed = 3
[[damper]]
damper_id = "YD-1"
type = "A"
session = "2026-03"
dataset = "ds"
force_col = "F_kN"
force_unit = "kN"
models = "lumped"
diagnose = true
""")
    rows = read_fleet_manifest(m)
    assert [r.id for r in rows] == ["YD-1-acceptance", "YD-1-2026-03"]
    a, b = rows
    assert a.identification == [str(tmp_path / "d" / "id1.csv"), str(tmp_path / "d" / "id2.csv")]
    assert len(a.validation) == 2 and a.settings == {"population": 8, "seed": 3}
    assert a.columns == {"stroke_unit": "mm"} and a.diagnose is None
    assert b.dataset == str(tmp_path / "ds") and b.settings["models"] == ("lumped",) and b.diagnose is True
    assert b.columns == {"stroke_unit": "mm", "force_col": "F_kN", "force_unit": "kN"}


def test_parser_registration():
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="command")
    add_parser(sub)
    args = ap.parse_args(["batch", "fleet.csv", "--scheduler", "local:2", "--diagnose", "--population", "5"])
    assert args.func is cmd_batch and args.scheduler == "local:2" and args.diagnose and args.population == 5


def test_outlier_rule():
    import numpy as np

    v = np.array([-0.1, -0.01, 0.01, 0.1])
    base = np.array([-20e3, -8e3, 8e3, 20e3])
    curves = {f"d{i}": (v, base * (1 + 0.002 * i)) for i in range(5)}
    curves["odd"] = (v, base + np.array([0.0, -900.0, 0.0, 0.0]))  # 11 % off at -10 mm/s
    res = find_outliers(curves)
    assert [i for i, d in res["dampers"].items() if d["outlier"]] == ["odd"]
    assert res["dampers"]["odd"]["worst_rate_m_s"] == -0.01
    assert not find_outliers({k: curves[k] for k in ("d0", "odd")})["judged"]  # two dampers: not judged


def test_a_rows_column_mapping_reaches_the_reader(tmp_path):
    """A row's *_col / *_unit / *_sign cells are the reader's options (``ReadOptions``) of its files: the
    bundled tests written in mm, kN under another name and with the force's sign flipped read back as the
    dataset does; a column the mapping does not name fails the row, naming it."""
    import numpy as np
    import pandas as pd

    from tuner.data.reading import DataError, load_dataset
    from tuner.fleet.batch import _load_row_data, _task

    truth = {t.name: t for t in load_dataset(ROOT / "data" / "default")}
    for name in ("id1_straight_250", "val1_straight_250"):
        t = truth[name]
        pd.DataFrame({"time": t.time, "stroke": 1e3 * t.stroke, "F_kN": -1e-3 * t.force}).to_csv(
            tmp_path / f"{name}.csv", index=False, float_format="%.12g")
    m = tmp_path / "fleet.csv"
    m.write_text("damper_id,type,identification,validation,stroke_unit,force_col,force_unit,force_sign\n"
                 "A1,A,id1_straight_250.csv,val1_straight_250.csv,mm,F_kN,kN,-1\n"
                 "A2,A,id1_straight_250.csv,,mm,Kraft,kN,-1\n")
    good, bad = read_fleet_manifest(m)
    ident, valid = _load_row_data(_task(good, tmp_path / "out", {}, False, 0, False))
    for got in (*ident, *valid):
        want = truth[got.name]
        assert got.role == want.role and got.metadata["read"]["signs"] == {"stroke": 1, "force": -1}
        np.testing.assert_allclose(got.stroke, want.stroke, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(got.force, want.force, rtol=1e-9, atol=1e-9)
    with pytest.raises(DataError, match="Kraft") as err:
        _load_row_data(_task(bad, tmp_path / "out", {}, False, 0, False))
    assert "fleet.csv row 2" in str(err.value) and "*_col" in str(err.value)
