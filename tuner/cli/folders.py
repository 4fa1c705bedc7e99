"""Where the commands read and write: the bundled dataset, the results folder, output folders."""
from __future__ import annotations

import shutil
from pathlib import Path

from tuner.cli.log import log

__all__ = ["free_folder", "prepare_out", "tidy_checkpoints", "ROOT", "DEFAULT_DATASET", "DEFAULT_RESULTS"]

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_DATASET = ROOT / "data" / "default"
DEFAULT_RESULTS = ROOT / "results"


def free_folder(base: Path) -> Path:
    """``base`` if free, else the first free ``base-2``, ``base-3``, ..."""
    if not base.exists():
        return base
    k = 2
    while Path(f"{base}-{k}").exists():
        k += 1
    return Path(f"{base}-{k}")


def prepare_out(out: Path, resume: bool, force: bool) -> Path:
    """The output folder ``out``, created; an earlier run's is continued (``resume``), moved aside (``force``)
    or refused (FileExistsError): nothing the user had is overwritten."""
    if out.exists() and any(out.iterdir()):
        if resume:
            if not (out / "checkpoints").is_dir():
                raise ValueError(f"--resume: {out} holds no checkpoints of an earlier run")
            return out
        if not force:
            raise FileExistsError(f"output folder {out} exists and is not empty: use --resume to continue "
                                  f"that run, --force to move it aside, or another --out")
        backup = free_folder(Path(f"{out}.old"))
        out.rename(backup)
        log(f"moved the existing {out} to {backup}")
    elif resume:
        raise ValueError(f"--resume: {out} does not exist or is empty")
    out.mkdir(parents=True, exist_ok=True)
    return out


def tidy_checkpoints(out: Path, keep: bool) -> None:
    """After a successful run the checkpoints (what --resume continues from) are removed unless kept."""
    ck = out / "checkpoints"
    if ck.is_dir() and not keep:
        shutil.rmtree(ck)
