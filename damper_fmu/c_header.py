"""The C names of every model parameter's index, generated from ``parameters.py``: ``c/damper_index.h``.

The C kernel and the FMU wrappers read a model's parameter vector (the order of
``parameters.MODEL_PARAMETERS``) only through these names, so a parameter added, removed or moved
in ``parameters.py`` cannot silently shift what C reads. Per model kind ``<KIND>`` (LUMPED,
MAXWELL, MAXWELL_TABLE, TWOCHAMBER):

* ``DK_<KIND>_<NAME>``: index of the parameter ``<name>`` (upper case), e.g. ``DK_LUMPED_M_C``,
  ``DK_LUMPED_FK_01`` (first ordinate of the Fk,O table), ``DK_LUMPED_FK_X01`` (its first abscissa);
* ``DK_<KIND>_<TABLE>_COUNT``: ordinates of each table (``FK``, ``FC``; zero point implied), whose
  ordinates and abscissae are contiguous (checked here);
* ``DK_<KIND>_EFFECTS``: index of the first effect parameter, the block in the order of
  ``EFFECT_PARAMETERS``, whose members are ``DK_EFFECT_<NAME>`` relative to it;
* ``DK_<KIND>_N``: number of parameters; ``DK_<KIND>_NDIAG``: element outputs (``models.DIAGNOSTICS``).

The header is committed; tests/test_c_header.py fails when it differs from ``render()``.
Regenerate with ``python -m damper_fmu.c_header``.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

from .models import DIAGNOSTICS
from .parameters import EFFECT_PARAMETERS, MODEL_PARAMETERS

__all__ = ["PATH", "render", "write"]

#: the committed header
PATH = Path(__file__).resolve().parent / "c" / "damper_index.h"

_TABLE = re.compile(r"^(F[a-z])_(\d\d)$")


def _macro(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9]", "_", name).upper()


def _tables(kind: str, names: list[str]) -> list[tuple[str, int]]:
    """(table prefix, ordinate count) of the tables of ``kind``, after checking that ordinates
    ``<P>_01..`` and abscissae ``<P>_<axis>01..`` are contiguous, in order and equal in number."""
    out = []
    for prefix in sorted({m.group(1) for m in map(_TABLE.match, names) if m}):
        ords = [i for i, n in enumerate(names) if re.fullmatch(rf"{prefix}_\d\d", n)]
        absc = [i for i, n in enumerate(names) if re.fullmatch(rf"{prefix}_[a-z]\d\d", n)]
        for what, idx in (("ordinates", ords), ("abscissae", absc)):
            if not idx or idx != list(range(idx[0], idx[0] + len(idx))):
                raise ValueError(f"{kind}: the {prefix} table's {what} are not contiguous in MODEL_PARAMETERS "
                                 f"(the C kernel reads each as one block)")
            nums = [int(names[i][-2:]) for i in idx]
            if nums != list(range(1, len(idx) + 1)):
                raise ValueError(f"{kind}: the {prefix} table's {what} are not numbered 01.. in order")
        if len(ords) != len(absc):
            raise ValueError(f"{kind}: the {prefix} table has {len(ords)} ordinates and {len(absc)} abscissae")
        out.append((prefix, len(ords)))
    return out


def render() -> str:
    """Text of ``c/damper_index.h`` from ``parameters.MODEL_PARAMETERS``."""
    effect_names = [p.name for p in EFFECT_PARAMETERS]
    lines = ["/* Generated from damper_fmu/parameters.py by damper_fmu/c_header.py: do not edit.",
             "   Regenerate: python -m damper_fmu.c_header (tests/test_c_header.py checks it is current).",
             "   Index of every model parameter in the parameter vector (MODEL_PARAMETERS order). */",
             "#ifndef DAMPER_INDEX_H", "#define DAMPER_INDEX_H", "",
             f"#define DK_NEFFECT {len(effect_names)} /* effect parameters, EFFECT_PARAMETERS order */"]
    lines += [f"#define DK_EFFECT_{_macro(n)} {i}" for i, n in enumerate(effect_names)]
    counts = []
    for kind, params in MODEL_PARAMETERS.items():
        tag = _macro(kind)
        names = [p.name for p in params]
        macros = [_macro(n) for n in names]
        if len(set(macros)) != len(macros):
            raise ValueError(f"{kind}: parameter names that differ only in case or punctuation: {names}")
        lines += ["", f"/* {kind} */", f"#define DK_{tag}_N {len(names)}",
                  f"#define DK_{tag}_NDIAG {len(DIAGNOSTICS[kind])}"]
        lines += [f"#define DK_{tag}_{m} {i}" for i, m in enumerate(macros)]
        for prefix, n in _tables(kind, names):
            lines.append(f"#define DK_{tag}_{_macro(prefix)}_COUNT {n}")
        if any(p.effect for p in params):
            first = names.index(effect_names[0])
            if names[first:first + len(effect_names)] != effect_names:
                raise ValueError(f"{kind}: the effect parameters are not one block in EFFECT_PARAMETERS order")
            lines.append(f"#define DK_{tag}_EFFECTS {first}")
        counts.append((len(names), tag))
    lines += ["", f"#define DK_NPAR_MAX {max(counts)[0]} /* the longest parameter vector ({max(counts)[1]}) */",
              f"#define DK_NDIAG_MAX {max(len(d) for d in DIAGNOSTICS.values())}", "", "#endif", ""]
    return "\n".join(lines)


def write(path: Path = PATH) -> bool:
    """Write the header if it differs; True when it changed."""
    text = render()
    if path.exists() and path.read_text() == text:
        return False
    path.write_text(text)
    return True


if __name__ == "__main__":
    changed = write()
    print(f"{PATH}: {'written' if changed else 'up to date'}")
    sys.exit(0)
