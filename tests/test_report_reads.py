"""The report of a short real run reads cleanly (issue 16): sections numbered in order, every figure it
references exists, printed numbers carry at most four significant digits outside the parameter and
file tables, values outside their documented range are flagged, and it loads in a browser."""
import json
import re
import shutil
import subprocess

import pytest

from campaign.synthetic import write_model_dataset
from damper_fmu import defaults


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    from tuner.data.reading import load_dataset
    from tuner.diagnosis.bases import FittedBases
    from tuner.diagnosis.diagnose import DiagnosisSettings, diagnose
    from tuner.identification.engine import fastest_engine
    from tuner.identification.fit import FitSettings, fit
    from tuner.job import write_diagnosis
    from tuner.results.report import make_report

    tmp = tmp_path_factory.mktemp("rep")
    tests = load_dataset(write_model_dataset(tmp / "d", "lumped", defaults("lumped"), seed=4, durations=(4.0, 3.0),
                                             roles=("identification", "validation"), noise_n=20.0))
    ident = [t for t in tests if t.role == "identification"]
    valid = [t for t in tests if t.role == "validation"]
    out = tmp / "fit"
    fit(ident, valid, FitSettings(models=("lumped", "maxwell"), population=4, iterations=1, workers=0,
                                  engine=fastest_engine(), polish_jacobians=1), log=lambda m: None).write(out)
    base = json.loads((out / "parameters.json").read_text())["lumped"]["values"]
    res = diagnose(ident, valid, DiagnosisSettings(engine=fastest_engine(), workers=0, candidates=("friction", "inertia"),
                                                   polish_jacobians=2, final_jacobians=2),
                   from_fit=FittedBases("lumped", base), log=lambda m: None)
    write_diagnosis(res, out, log=lambda m: None)
    path = make_report(out)
    return out, path.read_text(encoding="utf-8")


def _sections(text):
    parts = re.split(r"<h2>(.*?)</h2>", text)
    return [(re.sub(r"<[^>]+>", "", parts[i]), parts[i + 1]) for i in range(1, len(parts), 2)]


def _significant(token: str) -> int:
    mantissa = token.lstrip("+-").lower().split("e")[0].replace(".", "").lstrip("0")
    return len(mantissa.rstrip("0")) if "." not in token.split("e")[0] else len(mantissa)


def test_sections_are_numbered_in_order_and_include_the_diagnosis(report):
    _, text = report
    titles = [t for t, _ in _sections(text)]
    assert [int(t.split(".")[0]) for t in titles] == list(range(1, len(titles) + 1))
    assert any("Diagnosis" in t for t in titles)


def test_every_referenced_figure_exists(report):
    out, text = report
    srcs = re.findall(r"<img src='([^']+)'", text) + re.findall(r'<img src="([^"]+)"', text)
    assert srcs
    for s in srcs:
        assert (out / s).is_file(), s


def test_numbers_carry_at_most_four_significant_digits_outside_parameter_tables(report):
    _, text = report
    offenders = {}
    for title, body in _sections(text):
        if "Identified parameters" in title or "Provenance" in title:
            continue  # parameter values and file sizes/hashes are printed in full on purpose
        words = re.sub(r"<[^>]+>", " ", body)
        words = re.sub(r"\b[0-9a-f]{16}\b", " ", words)  # hash prefixes
        nums = re.findall(r"(?<![\w.])[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?(?![\w.])", words)
        bad = [n for n in nums if _significant(n) > 4 and not re.fullmatch(r"\d{4}", n)]
        if bad:
            offenders[title] = bad[:5]
    assert not offenders, offenders


def test_out_of_range_effect_values_are_flagged():
    from tuner.formatting import effect_value  # the one formatter of fitted magnitudes

    assert "above its typical" in effect_value("thermal_beta", 0.05, "1/K")
    assert "below its typical" in effect_value("friction_force", 10.0, "N")
    assert effect_value("free_play", 5e-18, "m") == "0 (off)"
    assert "typical" not in effect_value("inertia_mass", 50.0, "kg")


def test_report_loads_in_a_headless_browser(report):
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        pytest.skip("Debian's chromium is not installed here: the headless page-load check needs it")
    out, _ = report
    proc = subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--dump-dom",
                           (out / "report.html").resolve().as_uri()], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "Damper model identification report" in proc.stdout
