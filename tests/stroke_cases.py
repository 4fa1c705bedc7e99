"""Test support: the two-sine stroke the FMU tests drive every model with (1.3 Hz, 4 mm and 6 Hz, 0.6 mm)."""
from __future__ import annotations

import numpy as np


def two_sines(fs: float = 1000.0, duration: float = 1.0):
    """time [s], stroke [m], stroke velocity [m/s] at ``fs`` [Hz] for ``duration`` [s]."""
    t = np.arange(0.0, duration, 1.0 / fs)
    w1, w2 = 2 * np.pi * 1.3, 2 * np.pi * 6.0
    x = 4e-3 * np.sin(w1 * t) + 6e-4 * np.sin(w2 * t + 0.4)
    v = 4e-3 * w1 * np.cos(w1 * t) + 6e-4 * w2 * np.cos(w2 * t + 0.4)
    return t, x, v
