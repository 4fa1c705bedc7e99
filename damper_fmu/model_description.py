"""modelDescription.xml of the native FMUs, FMI 2.0 and FMI 3.0, written from one variable list.

``variables`` is the one list of the native FMU's variables (names, value references, causality,
units, start values, descriptions); ``fmi2`` and ``fmi3`` write it in each version's schema. The
value references are the C wrappers' (``c/fmi2_damper.c``, ``c/fmi3_damper.c``): FMI 2.0 Real
0 stroke, 1 stroke_velocity, 2 force, 3 oil_temperature, 10.. element outputs, 50..53 settings,
100 + i the i-th model parameter of ``parameters.MODEL_PARAMETERS``; Integer 0
input_interpolation, 1 thermal_source. FMI 3.0 keeps every Real's (as Float64) and moves what
one value-reference space cannot keep (``FMI3_VR``).
"""
from __future__ import annotations

from dataclasses import dataclass
from xml.etree.ElementTree import Element, SubElement, tostring

from .integrator import DEFAULT_MAX_STEP, DEFAULT_TOLERANCE, INPUT_INTERPOLATION_DESCRIPTION
from .models import DIAGNOSTICS
from .parameter_spec import check_rule
from .parameters import EFFECT_MODELS, MODEL_PARAMETERS, UNIT_DEFINITIONS

__all__ = ["NATIVE_SETTINGS", "SETTING_VR", "FMI3_VR", "DEFAULT_EXPERIMENT", "variables", "units",
           "fmi2_model_structure", "fmi2", "fmi3"]

#: start values of the native FMUs' settings: name -> (value, unit, description)
NATIVE_SETTINGS = {
    "max_internal_step": (DEFAULT_MAX_STEP, "s", "Largest internal integration step"),
    "internal_tolerance": (DEFAULT_TOLERANCE, "", "Local error tolerance of the internal steps, relative to the damper's "
                                     "force scale (largest |Fc,O| ordinate); 0: fixed steps of max_internal_step"),
    "stroke_limit": (1.0, "m", "Largest |stroke| accepted; beyond it fmi2DoStep returns fmi2Error (a stroke in "
                               "mm read as m)"),
    "velocity_limit": (20.0, "m/s", "Largest |stroke_velocity| accepted; beyond it fmi2DoStep returns fmi2Error"),
}
#: value references of the settings (FMI 2.0 Real, FMI 3.0 Float64)
SETTING_VR = {"max_internal_step": 50, "internal_tolerance": 51, "stroke_limit": 52, "velocity_limit": 53}

#: FMI 3.0 value references where FMI 2.0's cannot be kept: FMI 3.0 has one value-reference space for
#: all types, so the Integer settings (FMI 2.0 Integer 0 and 1, which Real 0 and 1 also use) move,
#: and the independent variable 'time' (none in FMI 2.0) gets one. Every Real keeps its FMI 2.0 value
#: reference. fmi3_damper.c uses the same numbers.
FMI3_VR = {"time": 4, "input_interpolation": 60, "thermal_source": 61}

#: DefaultExperiment of every damper FMU (native FMI 2.0 and 3.0, pythonfmu), as written
DEFAULT_EXPERIMENT = {"startTime": "0", "stopTime": "10", "stepSize": "0.001"}

_DESCRIPTION = ("Railway hydraulic damper, {kind} model (native C; SI units, stroke positive in extension, force "
                "positive in tension)")
_GENERATION_TOOL = "yaw-damper-toolchain damper_fmu.fmu"


@dataclass(frozen=True)
class _Role:
    """What a variable is to the importer: its FMI 2.0 causality, variability and initial attributes and its
    type ('Real' or 'Integer'); no units (the unit is the variable's own)."""

    causality: str
    variability: str
    initial: str | None = None
    type: str = "Real"


_INPUT = _Role("input", "continuous")
_OUTPUT = _Role("output", "continuous", "calculated")
_FIXED = _Role("parameter", "fixed", "exact")
_TUNABLE = _Role("parameter", "tunable", "exact")
_FIXED_INTEGER = _Role("parameter", "fixed", "exact", "Integer")


def variables(kind: str, start_values: dict, settings: dict, notes: dict | None = None) -> list[dict]:
    """The native FMU's variables, the one list both model descriptions (FMI 2.0, 3.0) and the pythonfmu
    slaves are written from, in FMI 2.0 order: name, vr (FMI 2.0), vr3 (FMI 3.0), type ('Real' or
    'Integer'), causality, variability, initial, unit, start, description, and 'known': True for the
    inputs and model parameters the initial outputs depend on (value references: fmi2_damper.c).

    notes: parameter name -> text appended to that parameter's description (a tuned FMU states there how
    well the identification tests determine each identified value: its 95 % range and flags)."""
    out = []

    def var(name, vr, role: _Role, unit, description, start=None, known=False):
        out.append({"name": name, "vr": vr, "vr3": FMI3_VR.get(name, vr), "type": role.type,
                    "causality": role.causality, "variability": role.variability, "initial": role.initial,
                    "unit": unit or None, "start": start, "description": description, "known": known})

    var("stroke", 0, _INPUT, "m", "Damper stroke, positive in extension", 0.0, known=True)
    var("stroke_velocity", 1, _INPUT, "m/s", "Damper stroke velocity, positive in extension", 0.0, known=True)
    if kind in EFFECT_MODELS:
        var("oil_temperature", 3, _INPUT, "degC",
            "Measured oil temperature; used by the thermal drift element when thermal_source = 1", 20.0)
    var("force", 2, _OUTPUT, "N", "Damper force, positive in tension")
    for i, (name, (unit, text)) in enumerate(DIAGNOSTICS[kind].items()):
        var(name, 10 + i, _OUTPUT, unit, text)
    for i, p in enumerate(MODEL_PARAMETERS[kind]):
        tunable = p.tunable or p.effect
        span = (f"range [{p.low:g}, {p.high:g}]" if check_rule(p) == "range" else
                f"typically [{p.low:g}, {p.high:g}], any positive value")
        text = (f"{p.description} [{p.unit}]; identification bounds [{p.low:g}, {p.high:g}] on a 20 kN yaw damper "
                "(the tuner scales them to the damper tested)" if p.tunable else
                f"Effect '{p.effect}' (off at 0): {p.description} [{p.unit}], {span}"
                if p.effect else f"{p.description} [{p.unit}]")
        if notes and notes.get(p.name):
            text = f"{text}; {notes[p.name]}"
        var(p.name, 100 + i, _TUNABLE if tunable else _FIXED, p.unit, text, start_values.get(p.name, p.default),
            known=True)
    for name, (value, unit, text) in NATIVE_SETTINGS.items():
        var(name, SETTING_VR[name], _FIXED, unit, text, settings.get(name, value))
    var("input_interpolation", 0, _FIXED_INTEGER, None, INPUT_INTERPOLATION_DESCRIPTION,
        settings.get("input_interpolation", 0))
    if kind in EFFECT_MODELS:
        var("thermal_source", 1, _FIXED_INTEGER, None,
            "Oil temperature of the thermal drift element: 0 internal thermal balance, 1 the oil_temperature input", 0)
    return out


def units(kind: str) -> list[tuple[str, dict]]:
    """UnitDefinitions: (name, SI base-unit exponents) of the units the description of ``kind`` uses."""
    used = sorted({p.unit for p in MODEL_PARAMETERS[kind]} | {"m", "m/s", "N", "s", "degC"} |
                  {u for u, _ in DIAGNOSTICS[kind].values()})
    return [(name, {k: str(e) for k, e in UNIT_DEFINITIONS[name].items()}) for name in used]


def _common(root: Element, kind: str) -> None:
    """UnitDefinitions, LogCategories and DefaultExperiment, the same in both versions."""
    el = SubElement(root, "UnitDefinitions")
    for name, exponents in units(kind):
        SubElement(SubElement(el, "Unit", {"name": name}), "BaseUnit", exponents)
    cats = SubElement(root, "LogCategories")
    SubElement(cats, "Category", {"name": "logStatusError", "description": "Errors with their reason"})
    SubElement(root, "DefaultExperiment", DEFAULT_EXPERIMENT)


def _start(v: dict) -> str:
    return repr(float(v["start"])) if v["type"] == "Real" else str(int(v["start"]))


def fmi2_model_structure(outputs: list[int], knowns: list[int]) -> Element:
    """FMI 2.0 <ModelStructure> of a damper FMU: ``outputs``, ``knowns``: 1-based indices in
    ModelVariables of the outputs and of the variables marked 'known' in ``variables`` (the
    pythonfmu slaves write theirs with this too, from the same list)."""
    # Dependencies (fmi2_damper.c): after initialization the outputs are those of the last doStep, and
    # fmi2SetReal of an input changes none of them before the next doStep: no direct feedthrough, so
    # no input dependencies (an importer assuming feedthrough reports algebraic loops that do not
    # exist). In initialization mode the outputs are computed from the stroke, the stroke velocity
    # (friction) and the model parameters.
    ms = Element("ModelStructure")
    outs = SubElement(ms, "Outputs")
    for i in outputs:
        SubElement(outs, "Unknown", {"index": str(i), "dependencies": ""})
    init = SubElement(ms, "InitialUnknowns")
    initial_knowns = " ".join(str(k) for k in sorted(knowns))
    for i in outputs:
        SubElement(init, "Unknown", {"index": str(i), "dependencies": initial_knowns})
    return ms


def fmi2(kind: str, identifier: str, guid: str, start_values: dict, settings: dict, source_files: list[str],
         notes: dict | None = None) -> bytes:
    """modelDescription.xml of the native FMI 2.0 FMU of ``kind``; ``source_files``: the files of ``sources/`` to
    compile (value references: fmi2_damper.c); ``notes``: as ``variables``."""
    root = Element("fmiModelDescription", {
        "fmiVersion": "2.0", "modelName": identifier, "guid": guid,
        "description": _DESCRIPTION.format(kind=kind),
        "author": "yaw-damper-toolchain", "license": "MIT", "generationTool": _GENERATION_TOOL,
        "variableNamingConvention": "flat", "numberOfEventIndicators": "0"})
    cs = SubElement(root, "CoSimulation", {
        "modelIdentifier": identifier, "canHandleVariableCommunicationStepSize": "true",
        "canInterpolateInputs": "true", "maxOutputDerivativeOrder": "0", "canGetAndSetFMUstate": "true",
        "canSerializeFMUstate": "true", "providesDirectionalDerivative": "false",
        "canNotUseMemoryManagementFunctions": "true", "canBeInstantiatedOnlyOncePerProcess": "false"})
    files = SubElement(cs, "SourceFiles")
    # the wrapper (it includes the rest, static: only the fmi2 functions have external linkage) and this FMU's
    # generated values (hidden symbols named after the model identifier)
    for name in source_files:
        SubElement(files, "File", {"name": name})
    _common(root, kind)
    mv = SubElement(root, "ModelVariables")
    outputs, knowns = [], []
    for v in variables(kind, start_values, settings, notes):
        attrs = {"name": v["name"], "valueReference": str(v["vr"]), "description": v["description"],
                 "causality": v["causality"], "variability": v["variability"]}
        if v["initial"]:
            attrs["initial"] = v["initial"]
        sv = SubElement(mv, "ScalarVariable", attrs)
        t = {}
        if v["unit"]:
            t["unit"] = v["unit"]
        if v["start"] is not None:
            t["start"] = _start(v)
        SubElement(sv, v["type"], t)
        if v["causality"] == "output":
            outputs.append(len(mv))
        if v["known"]:
            knowns.append(len(mv))
    root.append(fmi2_model_structure(outputs, knowns))
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root, encoding="utf-8")


def fmi3(kind: str, identifier: str, token: str, start_values: dict, settings: dict,
         notes: dict | None = None) -> bytes:
    """modelDescription.xml of the native FMI 3.0 FMU of ``kind``: the variables of the FMI 2.0 one
    (``variables``; Real as Float64, Integer as Int32, value references FMI3_VR where FMI 2.0's
    cannot be kept) plus the independent variable 'time' (value references: fmi3_damper.c);
    ``notes``: as ``variables``."""
    vs = variables(kind, start_values, settings, notes)
    root = Element("fmiModelDescription", {
        "fmiVersion": "3.0", "modelName": identifier, "instantiationToken": token,
        "description": _DESCRIPTION.format(kind=kind),
        "author": "yaw-damper-toolchain", "license": "MIT", "generationTool": _GENERATION_TOOL,
        "variableNamingConvention": "flat"})
    SubElement(root, "CoSimulation", {
        "modelIdentifier": identifier, "canHandleVariableCommunicationStepSize": "true",
        "maxOutputDerivativeOrder": "0", "canGetAndSetFMUState": "true", "canSerializeFMUState": "true",
        "providesDirectionalDerivatives": "false", "providesAdjointDerivatives": "false",
        "canBeInstantiatedOnlyOncePerProcess": "false", "hasEventMode": "false",
        "mightReturnEarlyFromDoStep": "false", "providesIntermediateUpdate": "false"})
    _common(root, kind)
    mv = SubElement(root, "ModelVariables")
    SubElement(mv, "Float64", {"name": "time", "valueReference": str(FMI3_VR["time"]),
                               "description": "Simulation time", "causality": "independent",
                               "variability": "continuous", "unit": "s"})
    for v in vs:
        attrs = {"name": v["name"], "valueReference": str(v["vr3"]), "description": v["description"],
                 "causality": v["causality"], "variability": v["variability"]}
        if v["initial"]:
            attrs["initial"] = v["initial"]
        if v["unit"]:
            attrs["unit"] = v["unit"]
        if v["start"] is not None:
            attrs["start"] = _start(v)
        SubElement(mv, {"Real": "Float64", "Integer": "Int32"}[v["type"]], attrs)
    # dependencies as in the FMI 2.0 description (see there), by value reference
    ms = SubElement(root, "ModelStructure")
    outputs = [v["vr3"] for v in vs if v["causality"] == "output"]
    knowns = " ".join(str(k) for k in sorted(v["vr3"] for v in vs if v["known"]))
    for vr in outputs:
        SubElement(ms, "Output", {"valueReference": str(vr), "dependencies": ""})
    for vr in outputs:
        SubElement(ms, "InitialUnknown", {"valueReference": str(vr), "dependencies": knowns})
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root, encoding="utf-8")
