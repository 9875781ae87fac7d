"""Unit conversion at the edges: everything inside frictionuq is SI (s, m, N, Pa, J).

One table per quantity kind; `to_si` and `from_si` are the only two conversions. Ingest, the
twins, the CLI and every report go through this module, so a unit is spelled one way everywhere.
"""
from __future__ import annotations

import numpy as np

from .errors import unknown

# Exact definitions: 1 in = 0.0254 m (international inch, 1959); 1 lbf = 4.4482216152605 N
# (avoirdupois pound x standard gravity 9.80665 m/s^2); 1 kip = 1000 lbf; 1 psi = 1 lbf/in^2.
LBF = 4.4482216152605
INCH = 0.0254
PSI = LBF / INCH**2

#: a drive amplitude (largest |x - median x|) or a length option above this is refused: no damper
#: test moves a metre; it is millimetres given as metres (inputs are in SI)
AMPLITUDE_PLAUSIBLE_M = 1.0

UNITS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3},
    "displacement": {"m": 1.0, "mm": 1e-3, "in": INCH},
    "force": {"N": 1.0, "kN": 1e3, "lbf": LBF, "lb": LBF, "kip": 1e3 * LBF},
    # `applied` is a force or, for hydraulic devices (the MFD), a pressure
    "applied": {"N": 1.0, "kN": 1e3, "lbf": LBF, "lb": LBF, "kip": 1e3 * LBF, "psi": PSI, "Pa": 1.0},
    "velocity": {"m/s": 1.0, "mm/s": 1e-3, "in/s": INCH},
    "stiffness": {"N/m": 1.0, "kN/m": 1e3, "kN/mm": 1e6, "kip/in": 1e3 * LBF / INCH, "lbf/in": LBF / INCH},
    "damping": {"N s/m": 1.0, "kN s/m": 1e3, "lbf s/in": LBF / INCH},
    "energy": {"J": 1.0, "kJ": 1e3},
    "acceleration": {"m/s^2": 1.0, "g": 9.80665, "cm/s^2": 1e-2},
}

SI = {"time": "s", "displacement": "m", "force": "N", "velocity": "m/s", "stiffness": "N/m",
      "damping": "N s/m", "energy": "J", "acceleration": "m/s^2"}


def si_unit_of_applied(unit: str) -> str:
    """The SI unit an `applied` value in `unit` becomes: N for a force, Pa for a pressure."""
    factor("applied", unit)  # validates
    return "Pa" if unit in ("psi", "Pa") else "N"


def factor(kind: str, unit: str) -> float:
    """Multiplier taking a value of `kind` in `unit` to SI. ValueError names the unknown unit."""
    try:
        table = UNITS[kind]
    except KeyError:
        raise ValueError(unknown("quantity kind", kind, UNITS)) from None
    try:
        return table[unit]
    except (KeyError, TypeError):
        raise ValueError(unknown(f"{kind} unit", unit, table)) from None


def to_si(value, kind: str, unit: str):
    """Convert `value` (scalar or array) of `kind` from `unit` to SI."""
    f = factor(kind, unit)
    return value * f if not isinstance(value, (list, tuple)) else np.asarray(value) * f


def from_si(value, kind: str, unit: str):
    """Convert `value` of `kind` from SI to `unit` (for display)."""
    f = factor(kind, unit)
    return value / f if not isinstance(value, (list, tuple)) else np.asarray(value) / f


#: the unit a report shows an SI quantity in (a damper's forces are kN, its strokes mm): every
#: parameter of one unit is shown in the same display unit, so a column reads without exponents
DISPLAY = {"N": ("kN", 1e-3), "m": ("mm", 1e3), "m/s": ("mm/s", 1e3), "N/m": ("kN/mm", 1e-6),
           "N s/m": ("kN s/m", 1e-3), "J": ("kJ", 1e-3)}


def display(si_unit: str) -> tuple[str, float]:
    """(display unit, factor from SI) of a quantity in `si_unit`; other units are shown as they
    are (factor 1)."""
    return DISPLAY.get(si_unit, (si_unit, 1.0))


def fmt(value: float, unit: str, digits: int = 4) -> str:
    """`value` (already in `unit`) with its unit, for reports: fmt(12.3, 'kN') -> '12.3 kN'."""
    return f"{value:.{digits}g} {unit}"


def metres_note() -> str:
    """The end of a message refusing a length above AMPLITUDE_PLAUSIBLE_M."""
    return (f"above {AMPLITUDE_PLAUSIBLE_M:g} m, which no damper test reaches: lengths are in "
            "metres (25 mm is 0.025)")


def check_amplitude(x, what: str) -> None:
    """Refuse a drive whose amplitude (largest |x - median x|) is above AMPLITUDE_PLAUSIBLE_M:
    millimetres given as metres."""
    from .errors import InputError
    from .noise import amplitude
    amp = amplitude(x)
    if amp > AMPLITUDE_PLAUSIBLE_M:
        raise InputError(f"{what}: the drive's amplitude is {amp:.4g} m, {metres_note()}")
