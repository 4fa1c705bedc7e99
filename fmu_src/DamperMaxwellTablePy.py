"""pythonfmu slave: Maxwell damper with a piecewise-linear dashpot Fc,O (standard multibody element)."""
from damper_fmi import DamperSlave


class DamperMaxwellTablePy(DamperSlave):
    MODEL_KIND = "maxwell_table"
