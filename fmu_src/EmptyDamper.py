"""FMU slave with the damper interface and no physics: measures the FMI boundary cost alone."""
import ctypes
import sys

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Initial


def _pin():  # compensates pythonfmu 0.7.0's reference leak, see fmu_src/damper_fmi.py
    ctypes.pythonapi.Py_IncRef(ctypes.py_object(sys.modules[__name__].__dict__))


_pin()


class EmptyDamper(Fmi2Slave):
    description = "Empty FMU with the damper interface (benchmark reference)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        _pin()
        self.stroke = 0.0
        self.stroke_velocity = 0.0
        self.force = 0.0
        self.register_variable(Real("stroke", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("stroke_velocity", causality=Fmi2Causality.input,
                                    variability=Fmi2Variability.continuous))
        self.register_variable(Real("force", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous,
                                    initial=Fmi2Initial.exact, start=0.0))

    def do_step(self, current_time, step_size):
        return True
