"""The layering issue 27 asks for: the damper package (models, kernel, FMU building) stands alone,
and the modules on the walk from the command line to the FMU import our own modules at the top; and
the map of the code: every package's docstring describes each of its modules in one line."""
import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
OURS = ("damper_fmu", "damper_dataset", "tuner", "campaign", "build_fmu")


def test_damper_fmu_imports_neither_the_tuner_nor_the_campaign():
    mods = [f"damper_fmu.{p.stem}" for p in (ROOT / "damper_fmu").glob("*.py") if p.stem != "__init__"]
    code = (f"import sys; sys.path.insert(0, {str(ROOT)!r}); " + "; ".join(f"import {m}" for m in mods)
            + "; print(sorted(m for m in sys.modules if m.split('.')[0] in ('tuner', 'campaign', 'damper_dataset')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize("path", [*sorted((ROOT / "damper_fmu").glob("*.py")), ROOT / "build_fmu.py",
                                  ROOT / "tuner" / "__main__.py", ROOT / "tuner" / "job.py",
                                  *[ROOT / "tuner" / "identification" / f for f in ("engine.py", "runner.py", "fit.py")],
                                  ROOT / "tuner" / "vehicle" / "cosim.py", ROOT / "tuner" / "diagnosis" / "diagnose.py",
                                  *sorted((ROOT / "tuner" / "cli").glob("*.py")), *sorted((ROOT / "tuner" / "fleet").glob("*.py")),
                                  *sorted((ROOT / "tuner" / "results").glob("*.py")),
                                  *sorted((ROOT / "damper_dataset").glob("*.py")),
                                  *sorted((ROOT / "campaign").glob("*.py"))],
                         ids=lambda p: p.relative_to(ROOT).as_posix())
def test_own_modules_are_imported_at_module_top(path):
    tree = ast.parse(path.read_text())
    hidden = []
    for fn in ast.walk(tree):
        if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for node in ast.walk(fn):
                if isinstance(node, ast.ImportFrom):
                    name = "." * node.level + (node.module or "")
                elif isinstance(node, ast.Import):
                    name = node.names[0].name
                else:
                    continue
                if name.startswith(".") or name.split(".")[0] in OURS:
                    hidden.append(f"line {node.lineno}: {name} in {fn.name}()")
    assert not hidden, f"{path.name} imports our own modules inside functions: {hidden}"


#: every package of ours: its ``__init__.py`` docstring is the map of its modules and sub-packages
PACKAGES = sorted(p.parent for root in ("damper_fmu", "damper_dataset", "tuner", "campaign")
                  for p in (ROOT / root).rglob("__init__.py"))
#: packages whose docstring is being rewritten with their code on another branch: only these of their
#: modules may lack their line for now (a module added there is still caught); ``screen`` is the
#: diagnosis's new candidate screen on main
NOT_YET_DESCRIBED: dict[str, set[str]] = {}


def package_children(pkg: Path) -> list[str]:
    """The modules (``__main__`` included) and sub-packages of the package folder ``pkg``."""
    modules = [p.stem for p in pkg.glob("*.py") if p.stem != "__init__"]
    packages = [p.name for p in pkg.iterdir() if (p / "__init__.py").is_file()]
    return sorted(modules + packages)


def described(doc: str, name: str) -> bool:
    """A docstring line of the form ``- ``name``: what it holds``."""
    return any(line.strip().startswith(f"- ``{name}``:") for line in doc.splitlines())


@pytest.mark.parametrize("pkg", PACKAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_the_package_docstring_describes_every_module(pkg):
    """The package docstrings are the map of the code: one line per module and sub-package."""
    doc = ast.get_docstring(ast.parse((pkg / "__init__.py").read_text(encoding="utf-8")))
    assert doc, f"{pkg.relative_to(ROOT)}/__init__.py has no docstring"
    missing = [m for m in package_children(pkg) if not described(doc, m)]
    pending = NOT_YET_DESCRIBED.get(pkg.relative_to(ROOT).as_posix(), set())
    assert set(missing) <= pending, (f"{pkg.relative_to(ROOT)}/__init__.py has no line '- ``<module>``: what it "
                                     f"holds' for {sorted(set(missing) - pending)}")
