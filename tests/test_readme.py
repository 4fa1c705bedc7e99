"""The README as a manual: its Python examples run, its two commands are the ones CI runs, it stays
short, and every relative link of the README and of docs/ leads to a file (and heading) that exists."""
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: the two set-up commands a new user runs on a fresh machine (``.ci/run`` runs the second)
MAIN_JOB = "pip install -e '.[test]' && python -m tuner"
TESTS = "pip install -e '.[test]' && python -m pytest -q -n 2"
MAX_LINES = 250


def code_blocks(text: str, language: str) -> list[str]:
    """The fenced code blocks of ``language`` in a Markdown text, in order."""
    return re.findall(rf"^```{language}\n(.*?)^```", text, flags=re.S | re.M)


def heading_slugs(text: str) -> set[str]:
    """GitHub's anchors of a Markdown text's headings: lower case, punctuation dropped, spaces as '-'."""
    slugs = set()
    for title in re.findall(r"^#{1,6} (.+)$", text, flags=re.M):
        slug = re.sub(r"[^\w\- ]", "", title.strip().lower())
        slugs.add(slug.replace(" ", "-"))
    return slugs


def test_the_readme_python_examples_run(tmp_path):
    """Every python block of the README, in order, in one process, from a folder holding the bundled data
    (the examples' paths are relative to the project folder; the FMU goes to the temporary folder)."""
    code = "\n".join(code_blocks(README.read_text(encoding="utf-8"), "python"))
    assert "from tuner import" in code
    (tmp_path / "data").symlink_to(ROOT / "data", target_is_directory=True)
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "identification RMSE" in out.stdout and "peak force" in out.stdout, out.stdout
    assert (tmp_path / "my_fit" / "fmu" / "DamperLumped_tuned.fmu").is_file()


def test_the_readme_two_commands_are_the_ones_ci_runs():
    bash = "\n".join(code_blocks(README.read_text(encoding="utf-8"), "bash"))
    commands = [line.strip() for line in bash.splitlines() if line.startswith("pip install")]
    assert commands == [MAIN_JOB, TESTS]
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    assert "-e '.[test]'" in ci
    ci_tests = [line.split() for line in ci.splitlines() if line.startswith("python -m pytest")]
    readme_tests = TESTS.split("&& ")[1].split()
    assert [[w for w in line if w != "-ra"] for line in ci_tests] == [readme_tests]


def test_the_readme_is_a_manual_of_at_most_250_lines():
    assert len(README.read_text(encoding="utf-8").splitlines()) <= MAX_LINES


def test_every_relative_link_of_the_readme_and_docs_leads_somewhere():
    broken = []
    for page in [README, *sorted((ROOT / "docs").glob("*.md"))]:
        text = page.read_text(encoding="utf-8")
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"[a-z]+:", target):
                continue
            path, _, anchor = target.partition("#")
            linked = (page.parent / path).resolve() if path else page
            if not linked.exists():
                broken.append(f"{page.name}: {target}")
            elif anchor and anchor not in heading_slugs(linked.read_text(encoding="utf-8")):
                broken.append(f"{page.name}: {target} (no such heading)")
    assert not broken, broken
