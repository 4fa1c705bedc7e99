"""FMU slave: linear Maxwell damper model (spring k_s in series with a linear dashpot c)."""
from damper_fmi import DamperSlave


class DamperMaxwell(DamperSlave):
    MODEL_KIND = "maxwell"
    DIAGNOSTICS = {"spring_elongation": ("m", "Series spring elongation")}
