"""The units the reader takes, with their exact factors to SI: the dataset format's metric units
(``damper_dataset.format``) and US customary units.

US customary factors are exact by definition (the international inch and pound, 1959): 1 in = 0.0254 m,
1 ft = 0.3048 m, 1 lbf = 0.45359237 kg x 9.80665 m/s^2 = 4.4482216152605 N, 1 kip = 1000 lbf. A damping
rate in lbf*s/in is 4.4482216152605 / 0.0254 = 175.126835246476 N s/m.
"""
from __future__ import annotations

from damper_dataset.format import FORCE_UNITS, STROKE_UNITS, TEMPERATURE_UNITS, TIME_UNITS, VELOCITY_UNITS

__all__ = ["M_PER_IN", "N_PER_LBF", "TIME", "STROKE", "FORCE", "VELOCITY", "TEMPERATURE", "DAMPING", "US_UNITS",
           "family", "us_conversions"]

#: [m/in], exact
M_PER_IN = 0.0254
#: [N/lbf], exact (0.45359237 kg x 9.80665 m/s^2)
N_PER_LBF = 4.4482216152605

TIME = dict(TIME_UNITS)
STROKE = {**STROKE_UNITS, "in": M_PER_IN, "ft": 12 * M_PER_IN}
FORCE = {**FORCE_UNITS, "lbf": N_PER_LBF, "kip": 1000 * N_PER_LBF}
VELOCITY = {**VELOCITY_UNITS, "in/s": M_PER_IN, "ft/s": 12 * M_PER_IN}
TEMPERATURE = dict(TEMPERATURE_UNITS)
#: a damping rate's units [N s/m per unit]
DAMPING = {"N*s/m": 1.0, "lbf*s/in": N_PER_LBF / M_PER_IN}
#: the US customary units among them
US_UNITS = ("in", "ft", "lbf", "kip", "in/s", "ft/s", "lbf*s/in")


def family(table: dict, unit: str) -> dict:
    """The units of ``table`` of the same system as ``unit`` (US customary or metric), for suggesting the
    unit a wrongly read file was in: a file in lbf read as kip is offered lbf, one in N read as kN N."""
    us = unit in US_UNITS
    return {u: f for u, f in table.items() if (u in US_UNITS) == us}


def us_conversions(units: dict) -> dict:
    """Role -> {'unit', 'factor' [SI per unit], 'si'} of each US customary unit among ``units`` (role ->
    unit read); empty when none is."""
    tables = {"stroke": (STROKE, "m"), "force": (FORCE, "N"), "velocity": (VELOCITY, "m/s")}
    return {role: {"unit": u, "factor": tables[role][0][u], "si": tables[role][1]}
            for role, u in units.items() if u in US_UNITS and role in tables}
