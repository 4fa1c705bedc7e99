"""Number formatting for people, in one place: engineering notation with SI prefixes (``eng``),
unit display (``unit_html``), physical quantities and fitted effect magnitudes (``fmt_quantity``,
``effect_value``). Values come in SI units."""
from __future__ import annotations

import math
import re

from damper_fmu.effect_catalogue import ALL_EFFECTS

__all__ = ["eng", "sig", "unit_html", "fmt_quantity", "effect_value", "pct_change"]

_PREFIX = {-15: "f", -12: "p", -9: "n", -6: "µ", -3: "m", 0: "", 3: "k", 6: "M", 9: "G", 12: "T"}
_SUPER = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")
_NO_PREFIX_UNITS = {"kg", "%", "-", "", "N^2", "1/N^2", "degC", "K"}


def unit_html(unit: str) -> str:
    """Display form of a unit string: 'N.s/m' -> 'N·s/m', 'N^2' -> 'N²', '1/N^2' -> 'N⁻²'."""
    u = {"1/N^2": "N⁻²", "-": ""}.get(unit, unit)
    u = u.replace(".", "·")
    return re.sub(r"\^(-?\d+)", lambda m: m.group(1).translate(_SUPER), u)


def sig(x: float, digits: int) -> str:
    """x with ``digits`` significant figures, fixed-point (x already in [1, 1000))."""
    mag = int(math.floor(math.log10(abs(x)))) if x != 0 else 0
    return f"{x:.{max(digits - 1 - mag, 0)}f}"


def pct_change(x: float) -> str:
    """A signed change in percent with at most four significant figures and one decimal: '+5.2', '-99.0', '+1927'
    (the unit is the caller's: ``f"{pct_change(x)} %"``)."""
    return f"{x:+.1f}" if abs(x) < 999.95 else f"{x:+.0f}"


def eng(x, unit: str = "", digits: int = 3) -> str:
    """Engineering format with SI prefix: eng(0.00125, 'm') = '1.25 mm', eng(18e3, 'N') = '18.0 kN'.

    Units in _NO_PREFIX_UNITS (kg, squared units, '%', dimensionless) get a power-of-ten factor
    with an exponent multiple of 3 instead of a prefix (5.88e6 N^2 -> '5.88×10⁶ N²'), except
    '%' which is printed with one decimal and plain numbers between 1e-3 and 1e4 which are
    printed as they are. Non-finite values: 'n/a', '∞', '-∞'.
    """
    if x is None:
        return "n/a"
    x = float(x)
    u = unit_html(unit)
    sep = " " if u else ""
    if math.isnan(x):
        return "n/a"
    if math.isinf(x):
        return ("∞" if x > 0 else "-∞") + sep + u
    if unit == "%":
        return f"{x:.1f} %"
    if x == 0:
        return "0" + sep + u
    x = float(f"{x:.{digits - 1}e}")            # round first: 999.7 -> 1.00e3
    exp3 = 3 * math.floor(math.log10(abs(x)) / 3)
    plain = unit in _NO_PREFIX_UNITS
    if plain and -3 <= math.log10(abs(x)) < 4:
        return sig(x, digits) + sep + u
    if not plain and exp3 in _PREFIX:
        return sig(x / 10.0 ** exp3, digits) + " " + _PREFIX[exp3] + u
    mant = sig(x / 10.0 ** exp3, digits)
    return f"{mant}×10{str(exp3).translate(_SUPER)}" + sep + u


def fmt_quantity(v: float, unit: str) -> str:
    """A value [SI] for people: lengths in mm, times in ms, ratios without a unit, 3 significant digits."""
    if unit == "1":
        return f"{v:.3g}"
    if unit == "m":
        return f"{v * 1e3:.3g} mm"
    if unit == "s":
        return f"{v * 1e3:.3g} ms"
    return f"{v:.3g} {unit}"


def effect_value(name: str, v: float, unit: str) -> str:
    """A fitted effect magnitude; one below 1/1000 of the low end of its typical range prints as 0
    (the refit switched the effect off; 5e-15 mm is not a measurement)."""
    typical = next((e.typical[name] for e in ALL_EFFECTS.values() if name in e.typical), None)  # its record's
    if typical is not None and abs(v) < 1e-3 * typical[0]:
        return "0 (off)"
    text = fmt_quantity(v, unit)
    if typical is not None:
        lo, hi = typical
        if abs(v) > hi:
            text += f" (above its typical {fmt_quantity(lo, unit)} - {fmt_quantity(hi, unit)})"
        elif abs(v) < lo:
            text += f" (below its typical {fmt_quantity(lo, unit)} - {fmt_quantity(hi, unit)})"
    return text
