"""The C kernel reads parameters through generated index names (damper_fmu/c/damper_index.h): the
committed header must be what damper_fmu/parameters.py gives, and its names must point at the
parameters the kernel itself lists."""
import re

import pytest

from damper_fmu import c_header, native
from damper_fmu.parameters import MODEL_PARAMETERS


def test_committed_index_header_is_current():
    assert c_header.PATH.read_text() == c_header.render(), (
        f"{c_header.PATH} is out of date with damper_fmu/parameters.py: regenerate it with "
        f"'python -m damper_fmu.c_header' and commit it")


def _defines() -> dict[str, int]:
    return {m.group(1): int(m.group(2))
            for m in re.finditer(r"^#define (DK_\w+) (\d+)\b", c_header.PATH.read_text(), re.M)}


@pytest.mark.skipif(not native.available(), reason="needs the C kernel")
def test_index_names_point_at_the_kernels_own_parameter_list():
    """Every DK_<KIND>_<NAME> index names, in the compiled kernel's own list (dk_parameter_names,
    from the parameter specs), the parameter <name>; the counts and blocks agree with it."""
    d = _defines()
    lib = native.library()
    for kind, code in native.KINDS.items():
        names = lib.dk_parameter_names(code).decode().split(",")
        tag = kind.upper()
        assert d[f"DK_{tag}_N"] == len(names) == len(MODEL_PARAMETERS[kind])
        for name in names:
            assert names[d[f"DK_{tag}_{name.upper()}"]] == name, (kind, name)
        for table, axis in (("FK", "X"), ("FC", "V")):
            if f"DK_{tag}_{table}_COUNT" in d:
                n, f0, x0 = d[f"DK_{tag}_{table}_COUNT"], d[f"DK_{tag}_{table}_01"], d[f"DK_{tag}_{table}_{axis}01"]
                assert names[f0:f0 + n] == [f"{table[0]}{table[1].lower()}_{i:02d}" for i in range(1, n + 1)]
                assert names[x0:x0 + n] == [f"{table[0]}{table[1].lower()}_{axis.lower()}{i:02d}"
                                            for i in range(1, n + 1)]
        if f"DK_{tag}_EFFECTS" in d:
            e0 = d[f"DK_{tag}_EFFECTS"]
            assert names[e0 + d["DK_EFFECT_FRICTION_FORCE"]] == "friction_force"
            assert names[e0 + d["DK_EFFECT_INERTIA_MASS"]] == "inertia_mass"
            for effect in ("hysteresis_force", "hysteresis_displacement", "bypass_ratio", "bypass_center",
                           "bypass_width", "bypass_edge"):  # the form elements, read by effects_init
                assert names[e0 + d[f"DK_EFFECT_{effect.upper()}"]] == effect


def test_render_refuses_a_parameter_list_the_kernel_could_not_read(monkeypatch):
    """A table whose ordinates are not one block would be read wrongly by C: generation stops."""
    params = list(MODEL_PARAMETERS["maxwell_table"])
    params[1], params[2] = params[2], params[1]  # Fc_01 after Fc_02
    monkeypatch.setitem(c_header.MODEL_PARAMETERS, "maxwell_table", tuple(params))
    with pytest.raises(ValueError, match="not numbered 01.. in order"):
        c_header.render()
    params = list(MODEL_PARAMETERS["maxwell_table"])
    params.insert(3, params.pop(0))  # k_s between the ordinates
    monkeypatch.setitem(c_header.MODEL_PARAMETERS, "maxwell_table", tuple(params))
    with pytest.raises(ValueError, match="not contiguous"):
        c_header.render()
