"""The layering issue 27 asks for: the damper package (models, kernel, FMU building) stands alone,
and the modules on the walk from the command line to the FMU import our own modules at the top."""
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


def test_the_readme_layout_table_names_every_module():
    """The README's "What is in here" table is the map of the code: every module of the packages is named."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    start = text.index("## What is in here")
    table = text[start:text.index("\n## ", start + 5)]
    missing = [str(f.relative_to(ROOT)) for pkg in ("tuner", "damper_fmu", "damper_dataset", "campaign")
               for f in sorted((ROOT / pkg).rglob("*.py"))
               if f.name not in ("__init__.py", "__main__.py") and f"`{f.name}`" not in table
               and f"`{f.relative_to(ROOT / pkg).as_posix()}`" not in table]
    assert not missing, f"README layout table does not name: {missing}"
