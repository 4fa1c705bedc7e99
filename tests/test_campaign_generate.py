"""The campaign generator: reproducibility of the bundled dataset, format, refusals."""
import filecmp
import json
from pathlib import Path

import numpy as np
import pytest

from campaign.generate import DEFAULT_SEED, generate_dataset
from tuner.data.reading import load_dataset

ROOT = Path(__file__).resolve().parents[1]
BUNDLED = ROOT / "data" / "default"


def test_regenerating_the_bundled_dataset_reproduces_it_bit_for_bit(tmp_path):
    out = generate_dataset(tmp_path / "again", seed=DEFAULT_SEED, log=lambda m: None)
    files = sorted(p.name for p in BUNDLED.iterdir())
    assert files == sorted(p.name for p in out.iterdir())
    match, mismatch, errors = filecmp.cmpfiles(BUNDLED, out, files, shallow=False)
    assert not mismatch and not errors, (mismatch, errors)


def test_bundled_dataset_has_the_six_scenarios_with_roles_and_plausible_forces():
    manifest = json.loads((BUNDLED / "manifest.json").read_text())
    roles = {t["name"]: t["role"] for t in manifest["tests"]}
    assert sorted(roles.values()) == ["identification"] * 3 + ["validation"] * 3
    tests = {t.name: t for t in load_dataset(BUNDLED)}
    assert set(tests) == set(roles)
    peaks = {n: np.abs(t.force).max() for n, t in tests.items()}
    assert 15e3 < max(peaks.values()) < 35e3  # the paper's yaw damper: peaks of 15-25 kN
    assert all(t.sample_rate == 1000.0 for t in tests.values())
    assert sum(p.stat().st_size for p in BUNDLED.iterdir()) < 6e6  # small enough for the repo


def test_effects_change_the_data_and_are_recorded(tmp_path):
    kw = dict(seed=3, scenarios=["id3_switch_R190_43"], t_end=4.0, log=lambda m: None)
    clean = generate_dataset(tmp_path / "clean", **kw)
    fric = generate_dataset(tmp_path / "fric", effects={"friction": 200.0}, **kw)
    a, b = load_dataset(clean)[0], load_dataset(fric)[0]
    np.testing.assert_array_equal(a.stroke, b.stroke)
    assert np.abs(a.force - b.force).max() > 100.0
    assert json.loads((fric / "manifest.json").read_text())["generator"]["effects"] == {"friction": 200.0}


def test_generator_refuses_to_overwrite_and_rejects_bad_effects(tmp_path):
    (tmp_path / "taken").mkdir()
    (tmp_path / "taken" / "x.txt").write_text("mine")
    with pytest.raises(FileExistsError):
        generate_dataset(tmp_path / "taken", t_end=2.0, scenarios=["id1_straight_250"], log=lambda m: None)
    assert (tmp_path / "taken" / "x.txt").read_text() == "mine"
    with pytest.raises(ValueError, match="unknown effect"):
        generate_dataset(tmp_path / "n", effects={"gremlins": 1.0}, t_end=2.0, log=lambda m: None)
    with pytest.raises(ValueError, match="unknown scenario"):
        generate_dataset(tmp_path / "n", scenarios=["moon_landing"], log=lambda m: None)
