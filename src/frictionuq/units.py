"""Unit conversion at the edges: everything inside frictionuq is SI (s, m, N, Pa, J).

One table per quantity kind; `to_si` and `from_si` are the only two conversions. Ingest, the
twins, the CLI and every report go through this module, so a unit is spelled one way everywhere.
"""
from __future__ import annotations

import math

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
#: a drive whose peak speed is above this is refused: servo-hydraulic damper tests and scaled
#: earthquake ground motions stay below a few m/s (the shipped ARTS records peak at 0.25 m/s);
#: beyond it a time, frequency or length is in the wrong unit (a harmonic of 0.1 mm at 1 MHz
#: moves at 628 m/s)
SPEED_PLAUSIBLE_M_S = 10.0

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


def speed_note() -> str:
    """The end of a message refusing a speed above SPEED_PLAUSIBLE_M_S."""
    return (f"above {SPEED_PLAUSIBLE_M_S:g} m/s, which no damper test reaches: times are in "
            "seconds, frequencies in Hz and lengths in metres")


def harmonic_speed_problem(amplitude_m: float, frequency_hz: float) -> str | None:
    """Why a harmonic A sin(2 pi f t) is refused for its peak speed 2 pi f A, or None."""
    v = 2.0 * math.pi * float(frequency_hz) * float(amplitude_m)
    if v <= SPEED_PLAUSIBLE_M_S:
        return None
    return (f"its peak speed 2 pi f A is {v:.4g} m/s ({float(amplitude_m):g} m at "
            f"{float(frequency_hz):g} Hz), {speed_note()}")


def check_drive(t, x, what: str) -> None:
    """Refuse a drive (times s, displacements m, time increasing) whose amplitude is above
    AMPLITUDE_PLAUSIBLE_M (check_amplitude) or whose fastest step is above SPEED_PLAUSIBLE_M_S,
    naming the step's times."""
    from .errors import InputError
    check_amplitude(x, what)
    t = np.asarray(t, float)
    x = np.asarray(x, float)
    if x.size < 2:
        return
    v = np.abs(np.diff(x) / np.diff(t))
    k = int(np.argmax(v))
    if v[k] > SPEED_PLAUSIBLE_M_S:
        raise InputError(f"{what}: the drive moves at {v[k]:.4g} m/s between t = {t[k]:.6g} s "
                         f"and {t[k + 1]:.6g} s, {speed_note()}")
