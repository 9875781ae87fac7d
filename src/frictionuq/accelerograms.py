"""Accelerogram readers: real ground-motion records in their files' formats, to SI.

Readers (all return a `GroundMotion` in SI: t in s, acceleration in m/s^2):

* `read_at2`: PEER NGA `.AT2` files: 4 header lines (title; event, date, station, component;
  "ACCELERATION TIME SERIES IN UNITS OF G"; `NPTS=  7814, DT=   .0050 SEC`, or the older
  `7814  .0050  NPTS, DT` form), then the values in g, any number per line (PEER writes 5).
* `read_single_column`: one value per line, no header (e.g. `Hollister-01_181.dat`); the time
  step and unit are not in the file and must be given.
* `read_columns`: whitespace-separated columns with `%` comment lines (the base-isolation
  benchmark files `kobe.txt`, `elcentro_impvall1979_fnfp.txt`: cm/s^2, dt 0.005 s). The time step
  and unit are taken from the comment header ("dt=0.005", "cm/sec^2") unless given.

Bad files raise `frictionuq.errors.InputError` with one line naming the file, the line and the
problem.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError
from .units import factor

__all__ = ["GroundMotion", "read_at2", "read_single_column", "read_columns", "read_record"]


@dataclass(frozen=True, eq=False)
class GroundMotion:
    """One accelerogram component, SI: `a` in m/s^2 at times `t` = k*dt (s)."""
    name: str
    source: str                  # the file it was read from
    dt: float                    # s
    a: np.ndarray                # m/s^2
    unit_in_file: str = "g"
    description: str = ""        # e.g. the AT2 event/station/component line
    meta: dict = field(default_factory=dict)

    @property
    def t(self) -> np.ndarray:
        return np.arange(self.a.size) * self.dt

    @property
    def npts(self) -> int:
        return int(self.a.size)

    @property
    def duration(self) -> float:
        return (self.a.size - 1) * self.dt

    @property
    def pga(self) -> float:
        """Peak |acceleration|, m/s^2."""
        return float(np.max(np.abs(self.a)))

    @property
    def pga_g(self) -> float:
        return self.pga / factor("acceleration", "g")


# ------------------------------------------------------------------------------------- readers

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][-+]?\d+)?"


def _read_lines(path: Path) -> list[str]:
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a folder, expected an accelerogram file") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    return text.splitlines()


def _floats(path, lineno: int, line: str) -> list[float]:
    out = []
    for tok in line.replace(",", " ").split():
        try:
            val = float(tok.replace("D", "E").replace("d", "e"))
        except ValueError:
            raise InputError(f"{path}, line {lineno}: non-numeric value {tok!r}") from None
        if not np.isfinite(val):
            raise InputError(f"{path}, line {lineno}: value {tok!r} is not finite")
        out.append(val)
    return out


def _check_dt(path, dt) -> float:
    try:
        dt = float(dt)
    except (TypeError, ValueError):
        raise InputError(f"{path}: time step {dt!r} is not a number") from None
    if not (np.isfinite(dt) and dt > 0):
        raise InputError(f"{path}: time step must be > 0 s, got {dt:g}")
    return dt


def _to_si(path, values, unit: str) -> np.ndarray:
    try:
        f = factor("acceleration", unit)
    except ValueError as e:
        raise InputError(f"{path}: {e}") from None
    a = np.asarray(values, dtype=float) * f
    if a.size and np.all(a == a[0]):     # baseline correction leaves no motion to scale
        raise InputError(f"{path}: every acceleration value is {values[0]!r}: no ground motion "
                         "in this record")
    return a


def _check_count(path, n: int, minimum: int = 10) -> None:
    if n < minimum:
        raise InputError(f"{path}: only {n} acceleration values; an accelerogram needs at least {minimum}")


def read_at2(path, name: str | None = None) -> GroundMotion:
    """A PEER NGA `.AT2` file (values in g) -> GroundMotion in SI."""
    path = Path(path)
    lines = _read_lines(path)
    if len(lines) < 4:
        raise InputError(f"{path}: missing header: a PEER .AT2 file has 4 header lines, "
                         f"this file has {len(lines)} lines")
    head = lines[3]
    m_n = re.search(r"NPTS\s*=\s*(\d+)", head, re.I)
    m_dt = re.search(r"DT\s*=\s*(" + _NUM + ")", head, re.I)
    if not (m_n and m_dt):
        # older PEER form: "  7814    0.0050    NPTS, DT"
        m_old = re.match(r"\s*(\d+)\s+(" + _NUM + r")\s+NPTS\s*,\s*DT", head, re.I)
        if not m_old:
            raise InputError(f"{path}, line 4: missing header: expected 'NPTS=..., DT=... SEC', "
                             f"got {head.strip()[:60]!r}")
        npts, dt = int(m_old.group(1)), m_old.group(2)
    else:
        npts, dt = int(m_n.group(1)), m_dt.group(1)
    dt = _check_dt(f"{path}, line 4", dt)
    unit_line = lines[2].upper()
    if "UNITS OF G" not in unit_line and "IN G" not in unit_line:
        raise InputError(f"{path}, line 3: expected 'ACCELERATION TIME SERIES IN UNITS OF G', "
                         f"got {lines[2].strip()[:60]!r}")
    vals: list[float] = []
    for i, line in enumerate(lines[4:], start=5):
        vals.extend(_floats(path, i, line))
    if len(vals) != npts:
        raise InputError(f"{path}: NPTS mismatch: the header says NPTS={npts}, "
                         f"the file holds {len(vals)} values")
    _check_count(path, npts)
    return GroundMotion(name=name or path.stem, source=str(path), dt=dt,
                        a=_to_si(path, vals, "g"), unit_in_file="g",
                        description=lines[1].strip(), meta={"title": lines[0].strip()})


def read_single_column(path, dt: float, unit: str = "g", name: str | None = None,
                       description: str = "") -> GroundMotion:
    """One acceleration value per line, no header; `dt` (s) and `unit` come from elsewhere."""
    path = Path(path)
    dt = _check_dt(path, dt)
    lines = _read_lines(path)
    vals = []
    for i, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        row = _floats(path, i, line)
        if len(row) != 1:
            raise InputError(f"{path}, line {i}: expected one value per line, got {len(row)}")
        vals.append(row[0])
    _check_count(path, len(vals))
    return GroundMotion(name=name or path.stem, source=str(path), dt=dt,
                        a=_to_si(path, vals, unit), unit_in_file=unit, description=description)


_UNIT_WORDS = (("cm/sec^2", "cm/s^2"), ("cm/s^2", "cm/s^2"), ("cm/sec2", "cm/s^2"),
               ("cm/s2", "cm/s^2"), ("gal", "cm/s^2"), ("m/s^2", "m/s^2"), ("m/sec^2", "m/s^2"))


def read_columns(path, column: int = 0, dt: float | None = None, unit: str | None = None,
                 name: str | None = None, comment: str = "%") -> GroundMotion:
    """Whitespace-separated columns with `comment` header lines; one column is read.

    `dt` and `unit` default to what the comment header states ("dt=0.005 sec", "cm/sec^2").
    """
    path = Path(path)
    lines = _read_lines(path)
    header = " ".join(ln.strip().lstrip(comment) for ln in lines if ln.strip().startswith(comment))
    if dt is None:
        m = re.search(r"\bdt\s*=\s*(" + _NUM + ")", header, re.I)
        if not m:
            raise InputError(f"{path}: missing header: no 'dt=...' in the {comment!r} comment lines "
                             "and no time step given")
        dt = m.group(1)
    dt = _check_dt(path, dt)
    if unit is None:
        low = header.lower()
        unit = next((u for word, u in _UNIT_WORDS if word in low), None)
        if unit is None:
            raise InputError(f"{path}: missing header: no acceleration unit (e.g. 'cm/sec^2') in "
                             f"the {comment!r} comment lines and no unit given")
    vals, ncol = [], None
    for i, line in enumerate(lines, start=1):
        s = line.strip()
        if not s or s.startswith(comment):
            continue
        row = _floats(path, i, s)
        if ncol is None:
            ncol = len(row)
            if not 0 <= column < ncol:
                raise InputError(f"{path}, line {i}: column {column} requested, the file has "
                                 f"{ncol} column(s)")
        elif len(row) != ncol:
            raise InputError(f"{path}, line {i}: expected {ncol} values, got {len(row)}")
        vals.append(row[column])
    _check_count(path, len(vals))
    if ncol > 1 and np.all(np.diff(vals) > 0):     # no accelerogram rises on every line
        raise InputError(f"{path}: column {column} increases on every line, like a time column; "
                         f"give the column of the accelerations (0 to {ncol - 1})")
    return GroundMotion(name=name or f"{path.stem}[{column}]", source=str(path), dt=dt,
                        a=_to_si(path, vals, unit), unit_in_file=unit,
                        description=header[:200], meta={"column": column})


def read_record(path, dt: float | None = None, unit: str | None = None, column: int = 0,
                name: str | None = None) -> GroundMotion:
    """Dispatch on the file: `.AT2` -> read_at2; a file with `%` comments or several columns ->
    read_columns; otherwise one value per line (needs `dt`; unit default g)."""
    path = Path(path)
    if path.suffix.lower() == ".at2":
        return read_at2(path, name=name)
    lines = _read_lines(path)
    first = next((ln for ln in lines if ln.strip()), "")
    if first.strip().startswith("%") or len(first.replace(",", " ").split()) > 1:
        return read_columns(path, column=column, dt=dt, unit=unit, name=name)
    if column:
        raise InputError(f"{path}: column {column} requested, the file has one value per line "
                         "(column 0)")
    if dt is None:
        raise InputError(f"{path}: a single-column accelerogram has no time step in the file; "
                         "give dt")
    return read_single_column(path, dt=dt, unit=unit or "g", name=name)


# --------------------------------------------------------------------- processing
