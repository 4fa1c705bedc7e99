"""pythonfmu slave: the nonlinear lumped damper model (Isacchi, Ripamonti, Corsi 2023)."""
from damper_fmi import DamperSlave


class DamperLumpedPy(DamperSlave):
    MODEL_KIND = "lumped"
