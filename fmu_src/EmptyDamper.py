"""FMU slave with the damper interface and no physics: measures the FMI boundary cost alone."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from pythonfmu.enums import Fmi2Initial


class EmptyDamper(Fmi2Slave):
    description = "Empty FMU with the damper interface (benchmark reference)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
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
