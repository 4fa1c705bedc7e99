"""``python -m tuner vehicle --nonlinear`` (tuner.vehicle.limit_cycles): the study's plumbing on a stand-in whose
answers are known (fast), and the real run with the Maxwell FMU against the eigenvalues (``full``)."""
import json
import math

import numpy as np
import pytest

import tuner.vehicle.limit_cycles as limit_cycles
from campaign.bifurcation import BifurcationDiagram, ConicityPoint, LimitCycle
from damper_fmu.fmu import ensure_fmu
from tuner.__main__ import main


def _known_point(fmu, conicity, study):
    """Linear critical speed 100 sqrt(0.15 / lambda) m/s, fold 20 m/s below it, a branch of three cycles."""
    v_lin = 100.0 * math.sqrt(0.15 / conicity)
    cycles = [LimitCycle(v_lin + dv, 6e-3, True, True, 6.0) for dv in (10.0, 0.0, -19.0)]
    cycles.append(LimitCycle(v_lin - 21.0, 1e-5, False, True, 8.0))
    return ConicityPoint(conicity, BifurcationDiagram(cycles, v_lin - 19.0, (v_lin - 21.0, v_lin - 19.0), v_lin))


def test_nonlinear_command_writes_table_json_and_figures(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(limit_cycles, "fmu_conicity_point", _known_point)
    fmu = ensure_fmu("maxwell")
    out = tmp_path / "nl"
    code = main(["vehicle", "--fmus", str(fmu), str(fmu), "--out", str(out), "--quiet", "--nonlinear",
                 "--conicities", "0.15", "0.3", "--diagram-conicity", "0.3", "--workers", "1"])
    assert code == 0
    text = capsys.readouterr().out
    assert "DamperMaxwell: linear / nonlinear (fold) [km/h]" in text and "DamperMaxwell-2" in text
    data = json.loads((out / "hunting_nonlinear.json").read_text())
    rows = data["results"]["DamperMaxwell"]["conicities"]
    assert [r["conicity"] for r in rows] == [0.15, 0.3]
    for r in rows:
        v_lin = 360.0 * math.sqrt(0.15 / r["conicity"])
        assert r["linear_critical_speed_kmh"] == pytest.approx(v_lin)
        assert r["nonlinear_critical_speed_kmh"] == pytest.approx(v_lin - 19.0 * 3.6)
        assert r["branch"]["amplitude_mm"] == pytest.approx([6.0, 6.0, 6.0])
        # the Maxwell FMU's eigenvalue critical speed at that conicity is reported beside it
        assert r["eigenvalue_critical_speed_kmh"] > 0.0
    assert (out / "hunting_bifurcation.png").is_file() and (out / "critical_speed_conicity.png").is_file()
    with pytest.raises(ValueError, match="conicity"):
        limit_cycles.HuntingStudy(conicities=(0.0,))


@pytest.mark.full  # about 1 min
def test_maxwell_fmu_study_matches_its_eigenvalues(tmp_path):
    """The real study with the linear Maxwell FMU at conicity 0.3: its linear critical speed (small kicks, linear
    contact) is the eigenvalue one within 1 %, and the ramp finds a branch of cycles whose nonlinear critical speed
    is at most the linear one."""
    study = limit_cycles.HuntingStudy(conicities=(0.3,), diagram_conicity=0.3, workers=1)
    data = limit_cycles.hunting_study([ensure_fmu("maxwell")], tmp_path, study, log=lambda line: None)
    (row,) = data["results"]["DamperMaxwell"]["conicities"]
    assert row["linear_critical_speed_kmh"] == pytest.approx(row["eigenvalue_critical_speed_kmh"], rel=0.01)
    assert row["nonlinear_critical_speed_kmh"] <= row["linear_critical_speed_kmh"]
    assert np.max(row["branch"]["amplitude_mm"]) > 1.0
