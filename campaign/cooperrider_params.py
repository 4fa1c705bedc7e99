"""Parameters of the Cooperrider car (car body, two bogie frames, four wheelsets) as the DTU group's
simulator DYTSI defines it, and where each value comes from.

The suspension geometry, stiffnesses and damping coefficients are read at run time from the
simulator's input file (``<CooperriderOrthogonalModel>`` element of, e.g.,
``input/InputFiles/inputBifurcation-Cooperrider-straight.xml``), never copied into the project. The
masses, inertias, friction coefficient and shear modulus are not in that file: the simulator's model
(``src/Models/CooperriderOrthogonalModel.cpp``, ``setupModel``) fixes them; they are the defaults of
:class:`CooperriderParams` below, written down from that source (DYTSI 1.0r2, LGPL-3.0).

Lengths [m] (the simulator's names): ``r0`` nominal wheel radius, ``h1`` height of the bogie frame's
centre above the axle, ``h2`` height of the car body's centre above the bogie frame's, ``a`` half
distance between the wheel contacts, ``l1``..``l3`` lateral offsets of the primary/secondary lateral
links, ``v1``..``v4`` vertical offsets, ``u1`` half bogie distance, ``u2`` half wheelbase, ``x1``
longitudinal offset of the primary longitudinal link, ``s1``..``s4`` lateral/longitudinal offsets.
Stiffnesses [N/m]: ``k1`` primary lateral, ``k2`` primary longitudinal, ``k3`` primary vertical,
``k4`` secondary lateral, ``k5`` secondary vertical, ``k6`` secondary longitudinal (yaw) spring.
Damping [N s/m]: ``D1`` secondary vertical, ``D2`` secondary lateral, ``D3``..``D5`` primary
longitudinal/vertical/lateral, ``D6`` secondary longitudinal (the yaw damper).
"""
from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, fields, replace
from pathlib import Path

__all__ = ["CooperriderParams", "ModelFile", "ModelFileError", "XML_NAMES", "STRAIGHT_INPUT", "read_cooperrider_xml",
           "reference_input"]

XML_NAMES = ("r0", "h1", "h2", "a", "l1", "l2", "l3", "v1", "v2", "v3", "v4", "u1", "u2", "x1",
             "s1", "s2", "s3", "s4", "k1", "k2", "k3", "k4", "k5", "k6", "D1", "D2", "D3", "D4", "D5", "D6")
"""The parameters read from the simulator's input file (SI units, meaning in the module docstring)."""
STRAIGHT_INPUT = "input/InputFiles/inputBifurcation-Cooperrider-straight.xml"
"""The simulator's published straight-track input file, relative to its folder."""


def reference_input() -> Path:
    """Where the simulator's straight-track input file is expected: ``$DYTSI_REFERENCE/`` +
    :data:`STRAIGHT_INPUT`, else the reference engines' folder beside the repository
    (``../shared/reference/dytsi``). The file is not part of the project and may be absent."""
    env = os.environ.get("DYTSI_REFERENCE")
    folder = Path(env) if env else Path(__file__).resolve().parents[1].parent / "shared" / "reference" / "dytsi"
    return folder / STRAIGHT_INPUT


class ModelFileError(ValueError):
    """An input file without the Cooperrider model or one of its parameters."""


@dataclass(frozen=True)
class CooperriderParams:
    """All parameters of the car. The 30 of :data:`XML_NAMES` have no default (read them with
    :func:`read_cooperrider_xml`); the others are the simulator's built-in values.

    Masses [kg], inertias [kg m^2] about the body's x (roll), y (pitch), z (yaw) axes; ``mu`` [-]
    wheel-rail friction coefficient; ``shear_modulus`` [Pa] as the simulator writes it,
    ``E / (2 (1 - nu))`` with E = 2.1e11 Pa and nu = 0.27; ``gravity`` [m/s^2].
    """

    r0: float
    h1: float
    h2: float
    a: float
    l1: float
    l2: float
    l3: float
    v1: float
    v2: float
    v3: float
    v4: float
    u1: float
    u2: float
    x1: float
    s1: float
    s2: float
    s3: float
    s4: float
    k1: float
    k2: float
    k3: float
    k4: float
    k5: float
    k6: float
    D1: float
    D2: float
    D3: float
    D4: float
    D5: float
    D6: float
    car_mass: float = 44388.0
    car_inertia: tuple = (2.80e5, 5.0e5, 5.0e5)
    bogie_mass: float = 2918.9
    bogie_inertia: tuple = (6780.0, 6780.0, 6780.0)
    wheelset_mass: float = 1022.0
    wheelset_inertia: tuple = (678.0, 80.0, 678.0)
    mu: float = 0.15
    shear_modulus: float = 2.1e11 / (2.0 * (1.0 - 0.27))
    gravity: float = 9.81

    def with_values(self, **changes) -> "CooperriderParams":
        """A copy with some parameters changed (names as the fields)."""
        known = {f.name for f in fields(self)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise KeyError(f"unknown Cooperrider parameter(s) {unknown}")
        return replace(self, **changes)


@dataclass(frozen=True)
class ModelFile:
    """What :func:`read_cooperrider_xml` found: the parameters, the contact table's path (resolved
    against the simulator's ``input/`` folder as the simulator does) and its interpolation name."""

    params: CooperriderParams
    table_path: Path
    interpolation: str


def read_cooperrider_xml(path, input_dir=None) -> ModelFile:
    """Read the ``<CooperriderOrthogonalModel>`` element of a simulator input file ``path``.

    ``input_dir``: the folder the simulator runs in, against which the table path is resolved
    (default: the parent of the file's folder, i.e. ``input/`` for ``input/InputFiles/x.xml``).
    Raises :class:`ModelFileError` naming the file and the missing or malformed parameter."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise ModelFileError(f"cannot read simulator input file {path}: {exc}") from exc
    model = root.find(".//CooperriderOrthogonalModel")
    if model is None:
        raise ModelFileError(f"{path}: no <CooperriderOrthogonalModel> element")
    values = {name: _number(model, name, path) for name in XML_NAMES}
    table = model.find("RSGEO_Path")
    if table is None or not (table.text or "").strip():
        raise ModelFileError(f"{path}: <CooperriderOrthogonalModel> has no <RSGEO_Path>")
    base = Path(input_dir) if input_dir is not None else path.resolve().parent.parent
    return ModelFile(params=CooperriderParams(**values), table_path=base / table.text.strip(),
                     interpolation=table.get("Interp", "linear"))


def _number(model, name: str, path: Path) -> float:
    node = model.find(name)
    if node is None or node.text is None:
        raise ModelFileError(f"{path}: <CooperriderOrthogonalModel> has no <{name}> (one of {', '.join(XML_NAMES)})")
    try:
        return float(node.text)
    except ValueError as exc:
        raise ModelFileError(f"{path}: <{name}> is {node.text.strip()!r}, not a number") from exc
