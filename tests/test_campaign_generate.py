"""The campaign generator: reproducibility of the bundled dataset, format, refusals."""
import filecmp
import json
from pathlib import Path

import matplotlib.image as plt_image
import numpy as np
import pytest

from campaign.generate import DEFAULT_SEED, CampaignPlan, generate_dataset, library_versions, numerical_kernels
from campaign.sensors import SensorChain
from tuner.data.reading import load_dataset

ROOT = Path(__file__).resolve().parents[1]
BUNDLED = ROOT / "data" / "default"


def test_regenerating_the_bundled_dataset_reproduces_it(tmp_path):
    """Regenerated with any library versions the project allows, on any processor, every sample of every
    channel is within a quarter of the rig's noise rms or one step of its ADC (whichever is larger: the
    stroke's ADC step, 3.05 um, exceeds its 2 um noise) and the force's rms difference is under 5 % of the
    load cell's noise. Every byte is the same only with the library versions *and* the numerical kernels
    recorded in the manifest (numpy's SIMD targets, OpenBLAS's core and threads, the C library): the same
    versions round differently on another processor, so only then is byte equality asserted."""
    out = generate_dataset(tmp_path / "again", seed=DEFAULT_SEED, log=lambda m: None)
    files = sorted(p.name for p in BUNDLED.iterdir())
    assert files == sorted(p.name for p in out.iterdir())
    stored, again = (json.loads((d / "manifest.json").read_text()) for d in (BUNDLED, out))
    versions = stored["generator"].pop("library_versions")
    kernels = stored["generator"].pop("numerical_kernels")  # None: made before the kernels were recorded
    assert again["generator"].pop("library_versions") == library_versions()
    assert again["generator"].pop("numerical_kernels") == numerical_kernels()
    assert stored == again  # same seed, scenarios, rig and test list

    chain = SensorChain()  # the rig's sensor chain (campaign.rig uses the defaults)
    tol = {"stroke": max(chain.stroke_noise / 4, chain.lsb(chain.stroke_range)),
           "force": max(chain.force_noise / 4, chain.lsb(chain.force_range)),
           "temperature": chain.temperature_resolution}
    a_tests, b_tests = ({t.name: t for t in load_dataset(d)} for d in (BUNDLED, out))
    for name, a in a_tests.items():
        b = b_tests[name]
        np.testing.assert_array_equal(a.time, b.time)
        for ch, x, y in [("stroke", a.stroke, b.stroke), ("force", a.force, b.force),
                         *[(c, a.channels[c], b.channels[c]) for c in a.channels]]:
            assert np.abs(x - y).max() <= tol[ch] * (1 + 1e-9), (name, ch, np.abs(x - y).max())
        assert np.sqrt(np.mean((a.force - b.force) ** 2)) <= 0.05 * chain.force_noise, name
    png_a, png_b = (plt_image.imread(d / "overview.png") for d in (BUNDLED, out))
    # the same figure size (13 in wide at 90 dpi) within matplotlib's pixel rounding (3.7 gives one row
    # fewer than 3.11); the pixels themselves depend on its version
    assert png_a.shape[2] == png_b.shape[2] and all(abs(a - b) <= 2 for a, b in zip(png_a.shape[:2], png_b.shape[:2]))

    if versions == library_versions() and kernels == numerical_kernels():
        match, mismatch, errors = filecmp.cmpfiles(BUNDLED, out, files, shallow=False)
        assert not mismatch and not errors, (mismatch, errors)


def test_generating_twice_on_one_machine_gives_the_same_bytes(tmp_path):
    """What the byte-for-byte claim rests on: with the same versions and kernels (one environment), the
    generator is deterministic, every file of a dataset the same byte for byte."""
    kw = dict(seed=5, plan=CampaignPlan(scenarios=["id3_switch_R190_43"], t_end=2.0), log=lambda m: None)
    a, b = generate_dataset(tmp_path / "a", **kw), generate_dataset(tmp_path / "b", **kw)
    names = sorted(p.name for p in a.iterdir())
    match, mismatch, errors = filecmp.cmpfiles(a, b, names, shallow=False)
    assert sorted(match) == names and not mismatch and not errors, (mismatch, errors)


def test_the_numerical_kernels_follow_what_numpy_and_openblas_are_told():
    """The manifest's kernel record changes when the kernels do: numpy's dispatch targets are what
    NPY_DISABLE_CPU_FEATURES leaves (read in a fresh process, as numpy reads it at import), and the record
    names OpenBLAS's core type, which OPENBLAS_CORETYPE overrides."""
    import subprocess
    import sys

    here = numerical_kernels()
    assert here["blas"] and all(b["architecture"] for b in here["blas"] if b["internal_api"] == "openblas")
    found = here["numpy_simd_dispatch_found"]
    if not found:
        pytest.skip("this processor offers numpy no dispatch target beyond its baseline")
    code = "import json; from campaign.generate import numerical_kernels; print(json.dumps(numerical_kernels()))"
    env = {**__import__("os").environ, "NPY_DISABLE_CPU_FEATURES": found[-1]}
    other = json.loads(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                                      cwd=ROOT, check=True).stdout)
    assert found[-1] not in other["numpy_simd_dispatch_found"] and other != here


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
    kw = dict(seed=3, plan=CampaignPlan(scenarios=["id3_switch_R190_43"], t_end=4.0), overview=False,
              log=lambda m: None)
    clean = generate_dataset(tmp_path / "clean", **kw)
    fric = generate_dataset(tmp_path / "fric", effects={"friction": 200.0}, **kw)
    a, b = load_dataset(clean)[0], load_dataset(fric)[0]
    np.testing.assert_array_equal(a.stroke, b.stroke)
    assert np.abs(a.force - b.force).max() > 100.0
    assert json.loads((fric / "manifest.json").read_text())["generator"]["effects"] == {"friction": 200.0}


def test_model_forms_are_generated_and_recorded_like_effects(tmp_path, capsys):
    """``--effect bypass --effect hysteresis=300`` (the forms of campaign.effects.FORMS) change the data
    and are recorded in the manifest with their units; the lumped damper refuses them up front."""
    from campaign.cli import main

    kw = dict(seed=3, plan=CampaignPlan(scenarios=["id1_straight_250"], t_end=2.0), overview=False, log=lambda m: None)
    clean = load_dataset(generate_dataset(tmp_path / "clean", **kw))[0]
    assert main(["generate", "--out", str(tmp_path / "forms"), "--t-end", "2", "--seed", "3",
                 "--effect", "bypass", "--effect", "hysteresis=300"]) == 0
    formed = {t.name: t for t in load_dataset(tmp_path / "forms")}["id1_straight_250"]
    np.testing.assert_array_equal(clean.stroke, formed.stroke)
    assert np.abs(clean.force - formed.force).max() > 300.0
    gen = json.loads((tmp_path / "forms" / "manifest.json").read_text())["generator"]
    assert gen["effects"] == {"bypass": 6e-8, "hysteresis": 300.0}
    assert gen["effect_units"] == {"bypass": "m^2", "hysteresis": "N"}
    capsys.readouterr()
    assert main(["generate", "--out", str(tmp_path / "lumped"), "--effect", "hysteresis",
                 "--damper", "lumped"]) == 2
    assert "twin-tube physics only" in capsys.readouterr().err and not (tmp_path / "lumped").exists()


def test_generator_refuses_to_overwrite_and_rejects_bad_effects(tmp_path):
    (tmp_path / "taken").mkdir()
    (tmp_path / "taken" / "x.txt").write_text("mine")
    with pytest.raises(FileExistsError):
        generate_dataset(tmp_path / "taken", plan=CampaignPlan(scenarios=["id1_straight_250"], t_end=2.0),
                         log=lambda m: None)
    assert (tmp_path / "taken" / "x.txt").read_text() == "mine"
    with pytest.raises(ValueError, match="unknown effect"):
        generate_dataset(tmp_path / "n", effects={"gremlins": 1.0}, plan=CampaignPlan(t_end=2.0), log=lambda m: None)
    with pytest.raises(ValueError, match="unknown scenario"):
        generate_dataset(tmp_path / "n", plan=CampaignPlan(scenarios=["moon_landing"]), log=lambda m: None)


def test_campaign_command_generates_and_refuses_to_overwrite(tmp_path):
    """``python -m campaign generate`` owns generation (the tuner's ``generate`` is the same command)."""
    import subprocess
    import sys

    cmd = [sys.executable, "-m", "campaign", "generate", "--out", str(tmp_path / "d"), "--t-end", "2"]
    assert subprocess.run(cmd, capture_output=True, text=True, cwd=tmp_path).returncode == 0
    assert len(load_dataset(tmp_path / "d")) == 6
    again = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp_path)
    assert again.returncode == 2 and "--overwrite" in again.stderr


def test_the_campaign_and_the_dataset_format_do_not_import_the_tuner():
    """Layers: the dataset format imports neither package; the campaign writes through it and never
    imports the tuner (the tuner may use the campaign's vehicle)."""
    import ast

    def imports(folder):
        for path in (ROOT / folder).glob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.Import):
                    yield from ((path.name, a.name) for a in node.names)
                elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                    yield path.name, node.module

    assert not [(f, m) for f, m in imports("campaign") if m.split(".")[0] == "tuner"]
    assert not [(f, m) for f, m in imports("damper_dataset") if m.split(".")[0] in ("tuner", "campaign")]
