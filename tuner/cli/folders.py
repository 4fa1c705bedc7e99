"""Output folders of the commands."""
from __future__ import annotations

from pathlib import Path

__all__ = ["free_folder"]


def free_folder(base: Path) -> Path:
    """``base`` if free, else the first free ``base-2``, ``base-3``, ..."""
    if not base.exists():
        return base
    k = 2
    while Path(f"{base}-{k}").exists():
        k += 1
    return Path(f"{base}-{k}")
