"""pythonfmu slave: the two-chamber (twin-tube) damper model (damper_fmu.models.TwoChamberModel)."""
from damper_fmi import DamperSlave


class DamperTwoChamberPy(DamperSlave):
    MODEL_KIND = "twochamber"
