"""Build the damper FMUs (FMI 2.0 co-simulation, pythonfmu) and validate them with fmpy.

Usage:  python build_fmu.py [--out DIR] [--force] [lumped maxwell maxwell_table empty]

Built FMUs go to ``build/fmu/`` in the project folder (git-ignored) unless ``--out`` or the
environment variable ``DAMPER_FMU_DIR`` says otherwise. Each FMU bundles the ``damper_fmu``
package (all the physics) and ``fmu_src/damper_fmi.py`` (the FMI wrapper); a stamp file next to
it records a hash of those sources so ``ensure_fmu`` rebuilds only when they changed.

The FMUs embed Python code: the importing tool needs a Python 3 interpreter with numpy
(``needsExecutionTool="true"``), as for every pythonfmu FMU.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent
SRC = ROOT / "fmu_src"
PACKAGE = ROOT / "damper_fmu"
SLAVES = {
    "lumped": "DamperLumped",
    "maxwell": "DamperMaxwell",
    "maxwell_table": "DamperMaxwellTable",
    "empty": "EmptyDamper",
}
BUILD_OPTIONS = {"canGetAndSetFMUstate": True, "canSerializeFMUstate": True}


def default_dir() -> Path:
    """Folder of the built FMUs: $DAMPER_FMU_DIR or <project>/build/fmu."""
    return Path(os.environ.get("DAMPER_FMU_DIR", ROOT / "build" / "fmu"))


def _source_hash() -> str:
    import pythonfmu

    h = hashlib.sha256(pythonfmu.__version__.encode())
    for f in sorted([*PACKAGE.glob("*.py"), *SRC.glob("*.py")]):
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def build(kind: str, out: str | Path | None = None, *, start_values: dict | None = None,
          settings: dict | None = None, filename: str | None = None) -> Path:
    """Build the FMU of ``kind`` and return its path.

    ``start_values``: parameter name -> SI value used as start values (and as the values the
    FMU uses when the importer sets none), e.g. identified parameters; ``settings``: optional
    ``max_internal_step`` [s] and ``input_interpolation`` (0 or 1). The build runs in a fresh
    Python process (pythonfmu imports the slave script, which must not meet a slave module an
    FMU already loaded in the caller); the file is written atomically.
    """
    import subprocess

    if kind not in SLAVES:
        raise ValueError(f"unknown FMU kind '{kind}', expected one of {sorted(SLAVES)}")
    if kind != "empty" and start_values:
        from damper_fmu.parameters import check_values

        check_values(kind, start_values)
    out = Path(out) if out is not None else default_dir()
    out.mkdir(parents=True, exist_ok=True)
    target = out / (filename or f"{SLAVES[kind]}.fmu")
    spec = json.dumps({"kind": kind, "target": str(target), "start_values": start_values or {},
                       "settings": settings or {}})
    proc = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--build-spec", spec],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"building {target.name} failed:\n{proc.stderr.strip()}")
    return target


def _build_here(kind: str, target: Path, start_values: dict, settings: dict) -> None:
    from pythonfmu.builder import FmuBuilder

    with tempfile.TemporaryDirectory(prefix="damper_fmu_build_") as tmp:
        tmp = Path(tmp)
        project = []
        if kind != "empty":
            project = [PACKAGE, SRC / "damper_fmi.py"]
            if start_values or settings:
                staged = tmp / "start_values.json"
                data = {k: float(v) for k, v in start_values.items()}
                data["_settings"] = dict(settings)
                staged.write_text(json.dumps(data, indent=1, sort_keys=True))
                project.append(staged)
        sys.path.insert(0, str(SRC))
        built = FmuBuilder.build_FMU(SRC / f"{SLAVES[kind]}.py", dest=tmp / "out", project_files=project,
                                     **BUILD_OPTIONS)
        part = target.with_suffix(".fmu.part")
        shutil.copyfile(built, part)
        os.replace(part, target)


def ensure_fmu(kind: str, out: str | Path | None = None) -> Path:
    """Path of the default FMU of ``kind``, (re)building it if missing or its sources changed."""
    out = Path(out) if out is not None else default_dir()
    path = out / f"{SLAVES[kind]}.fmu"
    stamp = path.with_suffix(".sha256")
    digest = _source_hash()
    if path.exists() and stamp.exists() and stamp.read_text().strip() == digest:
        return path
    build(kind, out)
    stamp.write_text(digest + "\n")
    return path


def validate(path: str | Path) -> list[str]:
    """Problems fmpy's validator reports for the FMU at ``path`` (empty list: valid)."""
    from fmpy.validation import validate_fmu

    return list(validate_fmu(str(path)))


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--build-spec"]:  # internal: one build in this fresh process
        spec = json.loads(argv[1])
        _build_here(spec["kind"], Path(spec["target"]), spec["start_values"], spec["settings"])
        return 0
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("kinds", nargs="*", default=["lumped", "maxwell", "maxwell_table"],
                    help=f"FMUs to build, from {sorted(SLAVES)} (default: the three damper models)")
    ap.add_argument("--out", type=Path, default=None, help="output folder (default build/fmu)")
    ap.add_argument("--force", action="store_true", help="rebuild even if up to date")
    args = ap.parse_args(argv)
    bad = [k for k in args.kinds if k not in SLAVES]
    if bad:
        ap.error(f"unknown FMU kind(s) {bad}; choose from {sorted(SLAVES)}")
    status = 0
    for kind in args.kinds:
        if args.force:
            path = build(kind, args.out)
            path.with_suffix(".sha256").write_text(_source_hash() + "\n")
        else:
            path = ensure_fmu(kind, args.out)
        problems = validate(path)
        print(f"{path}: {'valid' if not problems else 'INVALID'}")
        for p in problems:
            print(f"  - {p}")
            status = 1
    return status


if __name__ == "__main__":
    sys.exit(main())
