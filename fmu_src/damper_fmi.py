"""Thin FMI 2.0 co-simulation wrapper (pythonfmu) shared by the damper FMUs.

Bundled into every damper FMU next to the ``damper_fmu`` package, which holds all the physics.
Interface of every damper FMU (SI units):

* inputs ``stroke`` [m] (positive in extension) and ``stroke_velocity`` [m/s];
* output ``force`` [N] (positive in tension) plus diagnostic outputs of the internal elements;
* one tunable parameter per model parameter (start value = the reference preset, or the tuned
  values when the FMU was exported by the tuner), fixed parameters for the table abscissae,
  ``max_internal_step`` [s] and ``input_interpolation`` (0 = inputs are the values at the start of
  the communication step, stroke extrapolated with the velocity: standard co-simulation;
  1 = inputs are the values at the end of the step, interpolated from the previous ones: replay of
  a known stroke history without input lag).

Bad input (NaN stroke), invalid parameters or a failed implicit solve make ``fmi2DoStep`` refuse
the step with a message logged in category ``logStatusError``; the FMU never outputs a NaN force.
The refusal status is fmi2Discard: pythonfmu's C++ wrapper maps a Python step returning False to
fmi2Discard and any Python exception to fmi2Fatal, so Discard is the strongest status a Python
FMU can return without becoming unusable.
"""
from __future__ import annotations

import ctypes
import json
import os
import sys
from xml.etree.ElementTree import Element, SubElement

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Initial, Fmi2Status

from damper_fmu.integrator import (DEFAULT_MAX_STEP, DEFAULT_TOLERANCE, EXTRAPOLATE,
                                   INPUT_INTERPOLATION_DESCRIPTION, Simulator)
from damper_fmu.models import ConvergenceError, make_model
from damper_fmu.parameters import EFFECT_MODELS, MODEL_PARAMETERS, UNIT_DEFINITIONS, check_values

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


class UnitReal(Real):
    """pythonfmu Real variable that also writes its ``unit`` attribute."""

    def __init__(self, name, unit=None, **kwargs):
        super().__init__(name, **kwargs)
        self.unit = unit

    def to_xml(self):
        node = super().to_xml()
        if self.unit:
            node.find("Real").set("unit", self.unit)
        return node


class DamperSlave(Fmi2Slave):
    """Base class: subclasses set ``MODEL_KIND`` and ``DIAGNOSTICS`` (name -> (unit, description))."""

    MODEL_KIND = ""
    DIAGNOSTICS: dict[str, tuple[str, str]] = {}
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
        self.input_interpolation = EXTRAPOLATE
        start = os.path.join(self.resources or "", START_VALUES_FILE)
        if self.resources and os.path.exists(start):
            with open(start) as fh:
                saved = json.load(fh)
            settings = saved.pop("_settings", {})
            self._p.update({k: float(v) for k, v in saved.items()})
            self.max_internal_step = float(settings.get("max_internal_step", self.max_internal_step))
            self.internal_tolerance = float(settings.get("internal_tolerance", self.internal_tolerance))
            self.input_interpolation = int(settings.get("input_interpolation", self.input_interpolation))
        self.stroke = 0.0
        self.stroke_velocity = 0.0
        self.oil_temperature = 20.0
        self.thermal_source = 0
        self.force = 0.0
        self._dirty = True
        self._sim: Simulator | None = None
        self._init_error: Exception | None = None

        self.register_variable(UnitReal("stroke", unit="m", causality=Fmi2Causality.input,
                                        variability=Fmi2Variability.continuous,
                                        description="Damper stroke, positive in extension"))
        self.register_variable(UnitReal("stroke_velocity", unit="m/s", causality=Fmi2Causality.input,
                                        variability=Fmi2Variability.continuous,
                                        description="Damper stroke velocity, positive in extension"))
        self.register_variable(UnitReal("force", unit="N", causality=Fmi2Causality.output,
                                        variability=Fmi2Variability.continuous, initial=Fmi2Initial.exact,
                                        start=0.0, description="Damper force, positive in tension"))
        if kind in EFFECT_MODELS:
            self.register_variable(UnitReal(
                "oil_temperature", unit="degC", causality=Fmi2Causality.input,
                variability=Fmi2Variability.continuous,
                description="Measured oil temperature; used by the thermal drift element when "
                            "thermal_source = 1"))
        for name, (unit, text) in self.DIAGNOSTICS.items():
            self.register_variable(UnitReal(
                name, unit=unit, causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                initial=Fmi2Initial.exact, start=0.0, description=text,
                getter=(lambda n=name: self._diagnostic(n))))
        for p in MODEL_PARAMETERS[kind]:
            self.register_variable(UnitReal(
                p.name, unit=p.unit, causality=Fmi2Causality.parameter,
                variability=Fmi2Variability.tunable if (p.tunable or p.effect) else Fmi2Variability.fixed,
                description=(f"{p.description} [{p.unit}]; identification bounds [{p.low:g}, {p.high:g}]"
                             if p.tunable else
                             f"Effect '{p.effect}' (off at 0): {p.description} [{p.unit}], range "
                             f"[{p.low:g}, {p.high:g}]" if p.effect else f"{p.description} [{p.unit}]"),
                getter=(lambda n=p.name: self._p[n]), setter=(lambda v, n=p.name: self._set_param(n, v))))
        self.register_variable(UnitReal(
            "max_internal_step", unit="s", causality=Fmi2Causality.parameter,
            variability=Fmi2Variability.fixed,
            description="Largest internal integration step; communication steps are sub-stepped"))
        self.register_variable(UnitReal(
            "internal_tolerance", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
            description="Local error tolerance of the internal steps, relative to the damper's force scale "
                        "(largest |Fc,O| ordinate); 0: fixed steps of max_internal_step"))
        if kind in EFFECT_MODELS:
            self.register_variable(Integer(
                "thermal_source", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
                description="Oil temperature of the thermal drift element: 0 internal thermal balance, "
                            "1 the oil_temperature input"))
        self.register_variable(Integer(
            "input_interpolation", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
            description=INPUT_INTERPOLATION_DESCRIPTION))

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

    def _fail(self, what: str, err: Exception) -> bool:
        self.log(f"{self.instance_name}: {what}: {err}", Fmi2Status.error)
        return False

    # -- FMI calls ------------------------------------------------------------------------
    def exit_initialization_mode(self):
        # pythonfmu turns a Python exception into fmi2Fatal: never raise, log and refuse the steps.
        try:
            self._rebuild()
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
        return root

