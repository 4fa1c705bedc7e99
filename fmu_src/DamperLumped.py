"""FMU slave: the nonlinear lumped damper model (Isacchi, Ripamonti, Corsi 2023)."""
from damper_fmi import DamperSlave


class DamperLumped(DamperSlave):
    MODEL_KIND = "lumped"
    DIAGNOSTICS = {
        "blockA_elongation": ("m", "Silent block A elongation x1 - x2"),
        "blockA_rate": ("m/s", "Silent block A elongation rate"),
        "damping_rate": ("m/s", "Damping element Fc,O elongation rate x2' - x3'"),
        "damping_force": ("N", "Damping element force Fc,O"),
        "elastic_elongation": ("m", "Elastic element Fk,O elongation x3 - x4"),
        "elastic_force": ("N", "Elastic element force Fk,O"),
        "blockB_elongation": ("m", "Silent block B elongation x4"),
        "blockB_force": ("N", "Silent block B force (frame reaction)"),
    }
