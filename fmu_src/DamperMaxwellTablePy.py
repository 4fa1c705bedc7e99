"""pythonfmu slave: Maxwell damper with a piecewise-linear dashpot Fc,O (standard multibody element)."""
from damper_fmi import DamperSlave

from damper_fmu.models import DIAGNOSTICS


class DamperMaxwellTablePy(DamperSlave):
    MODEL_KIND = "maxwell_table"
    DIAGNOSTICS = DIAGNOSTICS["maxwell_table"]
