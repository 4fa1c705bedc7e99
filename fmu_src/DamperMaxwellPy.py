"""pythonfmu slave: linear Maxwell damper model (spring k_s in series with a linear dashpot c)."""
from damper_fmi import DamperSlave


class DamperMaxwellPy(DamperSlave):
    MODEL_KIND = "maxwell"
