"""FMU slave: Maxwell damper with a piecewise-linear dashpot Fc,O (standard multibody element)."""
from damper_fmi import DamperSlave


class DamperMaxwellTable(DamperSlave):
    MODEL_KIND = "maxwell_table"
    DIAGNOSTICS = {"spring_elongation": ("m", "Series spring elongation")}
