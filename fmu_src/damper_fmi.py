"""Thin FMI 2.0 co-simulation wrapper (pythonfmu) shared by the damper FMUs.

Bundled into every damper FMU next to the ``damper_fmu`` package, which holds all the physics.
The interface is the native FMU's, variable for variable (``damper_fmu.model_description.variables``,
the list the native model description is written from: names, value references, causality,
variability, initial, units, descriptions; DefaultExperiment and ModelStructure as the native's).
In SI units:

* inputs ``stroke`` [m] (positive in extension) and ``stroke_velocity`` [m/s];
* output ``force`` [N] (positive in tension) plus diagnostic outputs of the internal elements,
  ``initial="calculated"``: read in initialization mode they are the initial outputs;
* one tunable parameter per model parameter (start value = the reference preset, or the tuned
  values when the FMU was exported by the tuner), fixed parameters for the table abscissae,
  ``max_internal_step`` [s], ``internal_tolerance``, ``stroke_limit`` [m], ``velocity_limit`` [m/s]
  and ``input_interpolation`` (0 = inputs are the values at the start of the communication step,
  stroke extrapolated with the velocity: standard co-simulation; 1 = inputs are the values at the
  end of the step, interpolated from the previous ones: replay of a known stroke history without
  input lag).

Bad input (NaN stroke), invalid parameters or a failed implicit solve make ``fmi2DoStep`` refuse
the step with a message logged in category ``logStatusError``; the FMU never outputs a NaN force.
The refusal status is fmi2Discard: pythonfmu's C++ wrapper maps a Python step returning False to
fmi2Discard and any Python exception to fmi2Fatal, so Discard is the strongest status a Python
FMU can return without becoming unusable. A parameter the model refuses, met while the initial
outputs are read in initialization mode, can only be an exception there: fmi2Fatal, the parameter
named in the log (the native FMU returns fmi2Error).
"""
from __future__ import annotations

import ctypes
import json
import math
import os
import sys
from xml.etree.ElementTree import Element, SubElement

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String
from pythonfmu.enums import Fmi2Initial, Fmi2Status

from damper_fmu.integrator import DEFAULT_MAX_STEP, DEFAULT_TOLERANCE, EXTRAPOLATE, Simulator
from damper_fmu.model_description import DEFAULT_EXPERIMENT, NATIVE_SETTINGS, fmi2_model_structure
from damper_fmu.model_description import variables as native_variables
from damper_fmu.models import ConvergenceError, make_model
from damper_fmu.parameters import MODEL_PARAMETERS, UNIT_DEFINITIONS, check_values

START_VALUES_FILE = "start_values.json"


def pin_module_namespace(module_name: str) -> None:
    """Add one reference to a slave module's namespace dict.

    pythonfmu 0.7.0's native constructor releases one reference of the slave module's
    ``__dict__`` it does not own, once per fmi2Instantiate. Without compensation the second
    instance of an FMU in one process finds a freed namespace and crashes. Pinning at class
    creation covers the first instantiation, pinning in every ``__init__`` covers each later one
    (resets also call ``__init__``: the extra references only keep the namespace alive, which a
    loaded module's namespace is anyway).
    """
    ctypes.pythonapi.Py_IncRef(ctypes.py_object(sys.modules[module_name].__dict__))


#: value references of variables the native FMU does not have (none today): from here up, per type,
#: in registration order, clear of every native reference (0..53, 100 + parameter index)
EXTRA_VR_BASE = 1000


class UnitReal(Real):
    """pythonfmu Real variable that also writes its ``unit`` attribute, and its start value as the
    native model description does (repr: shortest exact, where pythonfmu's '%.16g' can drop the
    last bit of a tuned value)."""

    def __init__(self, name, unit=None, **kwargs):
        super().__init__(name, **kwargs)
        self.unit = unit

    def to_xml(self):
        node = super().to_xml()
        real = node.find("Real")
        if self.unit:
            real.set("unit", self.unit)
        if self.start is not None:
            real.set("start", repr(float(self.start)))
        return node


class DamperSlave(Fmi2Slave):
    """Base class: subclasses set ``MODEL_KIND``.

    The variables are the native FMU's (``damper_fmu.model_description.variables``, the list the
    native model description is written from): names, value references, causality, variability,
    initial, units and descriptions, in the same order, so a master can swap one FMU for the other
    without re-mapping. pythonfmu numbers variables in registration order and looks them up in
    ``self.vars`` by value reference alone; FMI 2.0 value references are per type (Real 0 is
    ``stroke``, Integer 0 ``input_interpolation``), so ``register_variable`` keys ``self.vars`` by
    (type, value reference) and the get/set methods look up with their type.
    """

    MODEL_KIND = ""
    author = "yaw-damper-toolchain"
    license = "MIT"

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        pin_module_namespace(cls.__module__)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        pin_module_namespace(type(self).__module__)
        kind = self.MODEL_KIND
        self.description = f"Railway hydraulic damper, {kind} model (SI units, force positive in tension)"
        self._p = {p.name: p.default for p in MODEL_PARAMETERS[kind]}
        self.max_internal_step = DEFAULT_MAX_STEP
        self.internal_tolerance = DEFAULT_TOLERANCE
        self.stroke_limit = NATIVE_SETTINGS["stroke_limit"][0]
        self.velocity_limit = NATIVE_SETTINGS["velocity_limit"][0]
        self.input_interpolation = EXTRAPOLATE
        notes = {}
        start = os.path.join(self.resources or "", START_VALUES_FILE)
        if self.resources and os.path.exists(start):
            with open(start) as fh:
                saved = json.load(fh)
            settings = saved.pop("_settings", {})
            notes = saved.pop("_notes", {})  # text for the parameters' descriptions (a tuned FMU's ranges)
            self._p.update({k: float(v) for k, v in saved.items()})
            for name in ("max_internal_step", "internal_tolerance", "stroke_limit", "velocity_limit"):
                setattr(self, name, float(settings.get(name, getattr(self, name))))
            self.input_interpolation = int(settings.get("input_interpolation", self.input_interpolation))
        self.stroke = 0.0
        self.stroke_velocity = 0.0
        self.oil_temperature = 20.0
        self.thermal_source = 0
        self.force = 0.0
        self._dirty = True
        self._sim: Simulator | None = None
        self._init_error: Exception | None = None
        self._initializing = False

        self._native = native_variables(kind, self._p, {}, notes)
        self._native_vr = {(v["type"], v["name"]): v["vr"] for v in self._native}
        params = {p.name for p in MODEL_PARAMETERS[kind]}
        for v in self._native:
            name, getter, setter = v["name"], None, None
            if name in params:
                getter, setter = (lambda n=name: self._p[n]), (lambda x, n=name: self._set_param(n, x))
            elif v["causality"] == "output":
                getter = lambda n=name: self._output(n)  # noqa: E731
            common = dict(causality=Fmi2Causality[v["causality"]], variability=Fmi2Variability[v["variability"]],
                          initial=Fmi2Initial[v["initial"]] if v["initial"] else None,
                          description=v["description"], getter=getter, setter=setter)
            self.register_variable(UnitReal(name, unit=v["unit"], **common) if v["type"] == "Real" else
                                   Integer(name, **common))

    # -- variables by (type, value reference) ---------------------------------------------
    @staticmethod
    def _type(var) -> str:
        for cls in (Real, Integer, Boolean, String):
            if isinstance(var, cls):
                return cls.__name__
        raise TypeError(f"unsupported variable type {type(var).__name__}")

    def register_variable(self, var, nested: bool = True):
        """pythonfmu's register_variable with the native FMU's value reference: that of the
        native variable of this name and type, or for a variable the native FMU does not have the
        next free one from EXTRA_VR_BASE (per type, in registration order). No hierarchical names."""
        typ = self._type(var)
        if "." in var.name:
            raise ValueError(f"{var.name}: the damper FMUs use flat names")
        vr = self._native_vr.get((typ, var.name))
        if vr is None:
            vr = max([EXTRA_VR_BASE - 1] + [r for t, r in self.vars if t == typ]) + 1
        if (typ, vr) in self.vars:
            raise ValueError(f"{var.name}: {typ} value reference {vr} is {self.vars[(typ, vr)].name}'s")
        var.value_reference = vr
        self.vars[(typ, vr)] = var
        if var.getter is None:
            var.getter = lambda: getattr(self, var.local_name)
        if var.setter is None and hasattr(self, var.local_name) and var.variability != Fmi2Variability.constant:
            var.setter = lambda value: setattr(self, var.local_name, value)

    def _var(self, typ: str, vr: int):
        try:
            return self.vars[(typ, vr)]
        except KeyError:
            raise TypeError(f"no {typ} variable with valueReference={vr}") from None

    def get_real(self, vrs):
        return [float(self._var("Real", vr).getter()) for vr in vrs]

    def get_integer(self, vrs):
        return [int(self._var("Integer", vr).getter()) for vr in vrs]

    def get_boolean(self, vrs):
        return [bool(self._var("Boolean", vr).getter()) for vr in vrs]

    def get_string(self, vrs):
        return [str(self._var("String", vr).getter()) for vr in vrs]

    def _set(self, kind: str, vrs, values):
        for vr, value in zip(vrs, values):
            self._var(kind, vr).setter(value)

    def set_real(self, vrs, values):
        self._set("Real", vrs, values)

    def set_integer(self, vrs, values):
        self._set("Integer", vrs, values)

    def set_boolean(self, vrs, values):
        self._set("Boolean", vrs, values)

    def set_string(self, vrs, values):
        self._set("String", vrs, values)

    # -- parameters and state -------------------------------------------------------------
    def _set_param(self, name: str, value: float) -> None:
        self._p[name] = float(value)
        self._dirty = True

    def _rebuild(self) -> None:
        check_values(self.MODEL_KIND, self._p)
        model = make_model(self.MODEL_KIND, self._p)
        if self._sim is None:
            self._sim = Simulator(model, self.max_internal_step, int(self.input_interpolation),
                                  float(self.internal_tolerance))
        else:
            self._sim.set_model(model)
        self._dirty = False

    def _diagnostic(self, name: str) -> float:
        sim = self._sim
        if sim is None or not sim.y:
            return 0.0
        return float(sim.model.diagnostics(sim.y, sim.x1, sim.v1)[name])

    def _output(self, name: str) -> float:
        """An output: in initialization mode the initial one (declared initial="calculated" from the
        inputs and parameters, as the native FMU computes it), after it the last step's."""
        if self._initializing:
            return self._initial_outputs()[name]
        return float(self.force) if name == "force" else self._diagnostic(name)

    def _initial_outputs(self) -> dict[str, float]:
        """The outputs fmi2ExitInitializationMode would give with the present inputs and parameters;
        a parameter the model refuses is logged by name and raised (the getter fails)."""
        try:
            check_values(self.MODEL_KIND, self._p)
            sim = Simulator(make_model(self.MODEL_KIND, self._p), self.max_internal_step,
                            int(self.input_interpolation), float(self.internal_tolerance))
            force = sim.initialize(float(self.stroke), float(self.stroke_velocity))
        except (ValueError, ConvergenceError) as err:
            self._fail("initial outputs", err)
            raise
        out = {k: float(v) for k, v in sim.model.diagnostics(sim.y, sim.x1, sim.v1).items()}
        out["force"] = float(force)
        return out

    def _check_inputs(self) -> None:
        """The native FMU's input limits (stroke_limit, velocity_limit): ValueError beyond them."""
        if not (self.stroke_limit > 0.0 and self.velocity_limit > 0.0):
            raise ValueError("stroke_limit and velocity_limit must be positive")
        if abs(self.stroke) > self.stroke_limit or abs(self.stroke_velocity) > self.velocity_limit:
            raise ValueError(
                f"input out of range: stroke = {self.stroke:g} m (limit {self.stroke_limit:g} m), stroke_velocity = "
                f"{self.stroke_velocity:g} m/s (limit {self.velocity_limit:g} m/s); inputs are SI: a stroke in mm or "
                f"a velocity in mm/s gives this. Raise stroke_limit / velocity_limit if the values are real")

    def _fail(self, what: str, err: Exception) -> bool:
        self.log(f"{self.instance_name}: {what}: {err}", Fmi2Status.error)
        return False

    # -- FMI calls ------------------------------------------------------------------------
    def enter_initialization_mode(self):
        self._initializing = True

    def exit_initialization_mode(self):
        # pythonfmu turns a Python exception into fmi2Fatal: never raise, log and refuse the steps.
        self._initializing = False
        try:
            self._rebuild()
            if all(map(math.isfinite, (self.stroke, self.stroke_velocity))):
                self._check_inputs()  # non-finite inputs: the simulator names them
            self.force = self._sim.initialize(float(self.stroke), float(self.stroke_velocity))
            self._init_error = None
        except (ValueError, ConvergenceError) as err:
            self._init_error = err
            self._fail("initialisation failed", err)
        return True

    def do_step(self, current_time: float, step_size: float) -> bool:
        """One communication step; False (fmi2Discard, message logged as error) on failure."""
        if self._init_error is not None:
            return self._fail("initialisation had failed", self._init_error)
        try:
            if self._dirty:
                self._rebuild()
            if all(map(math.isfinite, (self.stroke, self.stroke_velocity))):
                self._check_inputs()
            if self.thermal_source:
                self._sim.temperature_input = float(self.oil_temperature)
            self.force = self._sim.step(step_size, self.stroke, self.stroke_velocity)
        except (ValueError, ConvergenceError, FloatingPointError, ZeroDivisionError) as err:
            return self._fail(f"step at t = {current_time:g} s failed", err)
        return True

    def _get_fmu_state(self):
        state = super()._get_fmu_state()
        state["_simulator_state"] = self._sim.get_state() if self._sim is not None else None
        return state

    def _set_fmu_state(self, state):
        state = dict(state)
        sim_state = state.pop("_simulator_state", None)
        super()._set_fmu_state(state)
        if sim_state is not None:
            self._rebuild()
            self._sim.set_state(sim_state)

    # -- model description ----------------------------------------------------------------
    def to_xml(self, model_options=dict()) -> Element:
        root = super().to_xml(model_options)
        units = SubElement(root, "UnitDefinitions")
        root.remove(units)
        used = sorted({v.unit for v in self.vars.values() if getattr(v, "unit", None)})
        for name in used:
            unit = SubElement(units, "Unit", {"name": name})
            SubElement(unit, "BaseUnit", {k: str(e) for k, e in UNIT_DEFINITIONS[name].items()})
        root.insert(1, units)  # after <CoSimulation>, before <LogCategories> (FMI 2.0 schema order)
        # the native FMU's DefaultExperiment, before ModelVariables (schema order)
        for old in root.findall("DefaultExperiment"):
            root.remove(old)
        root.insert(list(root).index(root.find("ModelVariables")), Element("DefaultExperiment", DEFAULT_EXPERIMENT))
        # the native FMU's ModelStructure (pythonfmu writes Outputs without dependencies and no
        # InitialUnknowns), from the indices of this description's variables
        root.remove(root.find("ModelStructure"))
        known = {v["name"] for v in self._native if v["known"]}
        order = list(self.vars.values())
        root.append(fmi2_model_structure(
            [i for i, v in enumerate(order, 1) if v.causality == Fmi2Causality.output],
            [i for i, v in enumerate(order, 1) if v.name in known]))
        return root

