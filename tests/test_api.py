"""The library's public names at package level (``from tuner import fit, diagnose, ...``): each is the
object its module defines, importing the package stays cheap (the stages load on first use), and the
command line still starts."""
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

import tuner

ROOT = Path(__file__).resolve().parents[1]
#: what the README and docs/ examples use, at least
DOCUMENTED = ("fit", "diagnose", "Problem", "DataSettings", "FitSettings", "FitResult", "DiagnosisSettings",
              "DiagnosisFailed", "run", "run_diagnosis", "JobResult", "export_fmus", "load_dataset", "load_files",
              "load_tests", "ReadOptions", "RigTest", "DataError")


@pytest.mark.parametrize("name", tuner.__all__)
def test_every_public_name_is_the_object_of_its_module(name):
    module = importlib.import_module(tuner._EXPORTS[name])
    assert getattr(tuner, name) is getattr(module, name)


def test_the_documented_names_are_exported_and_a_typo_is_an_attribute_error():
    assert set(DOCUMENTED) <= set(tuner.__all__)
    with pytest.raises(AttributeError, match="no attribute 'fitt'"):
        tuner.fitt  # noqa: B018


def test_importing_the_package_loads_no_stage_and_the_submodule_imports_still_work():
    code = ("import sys; import tuner; loaded = sorted(m for m in sys.modules if m.startswith('tuner.')); "
            "from tuner import fit, diagnose, Problem, FitSettings, DiagnosisSettings, run, job, strict_json; "
            "print(loaded, job.__name__, strict_json.__name__, fit.__module__, diagnose.__module__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True).stdout
    assert out.split() == ["[]", "tuner.job", "tuner.strict_json", "tuner.identification.fit",
                           "tuner.diagnosis.diagnose"]


def test_the_command_line_help_still_works():
    out = subprocess.run([sys.executable, "-m", "tuner", "--help"], capture_output=True, text=True, cwd=ROOT,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert "python -m tuner" in out.stdout and "fit" in out.stdout


def test_a_diagnosis_result_is_read_only_and_holds_its_record():
    """The object ``diagnose`` returns: attributes for the answers, the record by key, and nothing a caller
    reads can change what was decided (each read is a copy)."""
    import json

    from tuner import Diagnosis

    record = {"cause": "friction", "causes": ["friction"], "form": None, "verdict": "friction: 150 N",
              "base_model": "lumped", "unexplained": None, "ranking": [{"effect": "friction", "score": 0.4}],
              "effect_parameters": {"friction_force": {"value": 150.0, "unit": "N"}}}
    d = Diagnosis(record)
    assert (d.cause, d.causes, d.form, d.base_model) == ("friction", ["friction"], None, "lumped")
    assert d.effect_parameters["friction_force"]["value"] == 150.0 and d["ranking"][0]["score"] == 0.4
    d["ranking"][0]["score"] = -1.0
    d.effect_parameters["friction_force"]["value"] = 0.0
    d.causes.append("preload")
    record["cause"] = "none"  # nor through the dict it was made from
    assert d["ranking"][0]["score"] == 0.4 and d.effect_parameters["friction_force"]["value"] == 150.0
    assert d.causes == ["friction"] and d.cause == "friction"
    assert json.loads(json.dumps(d.to_dict())) == d.to_dict() and set(d) == set(record) and len(d) == len(record)
    with pytest.raises(TypeError):
        d["cause"] = "none"
