"""Real ground motions as drives for the earthquake tests: accelerogram readers, baseline-drift
removal, double integration to displacement, scaling and resampling.

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

Baseline correction (`baseline_correct`): the standard procedure described by Boore & Bommer
(2005) and Boore (2005), in the spirit of the PEER NGA processing (acausal Butterworth filtering
of zero-padded records):

1. remove the baseline drift by least squares: fit a polynomial of degree `poly_degree` (default
   2) to the velocity and subtract its derivative from the acceleration (the velocity-fit
   baseline correction reviewed by Boore & Bommer 2005). Degree 2 removes any constant and linear drift of the acceleration; with
   `poly_degree=None` only the mean is removed (the "pre-event mean": these records carry no
   pre-event memory, and the acceleration of a record at rest at both ends has zero mean);
2. taper both ends with a half-cosine over `taper` of the record's length;
3. pad both ends with zeros, `1.5 * order / f_corner` seconds in total, half at each end
   (Converse & Brady 1992; Boore 2005, "On pads and filters", BSSA 95(2) 745-750): long enough
   for the acausal filter's transient to die out inside the pads;
4. high-pass with an acausal (zero-phase) Butterworth filter of total order `order` (a causal
   filter of order `order/2` run forward and backward, `scipy.signal.sosfiltfilt`; gain 1/2 at
   `f_corner`);
5. integrate the padded, filtered acceleration twice (trapezoid rule) from the start of the
   front pad, where the ground is at rest, and keep the original window plus `pad_keep` seconds
   of each pad. Integrating the padded record is what keeps displacement consistent with the
   filtered acceleration (Boore 2005).

Step 1 is what removes an instrument's baseline drift exactly; step 4 removes the long-period
noise that a polynomial cannot (and what is left of a drift that is not polynomial).

References: D. M. Boore, J. J. Bommer (2005), Processing of strong-motion accelerograms: needs,
options and consequences, Soil Dyn. Earthq. Eng. 25, 93-115. D. M. Boore (2005), On pads and
filters: processing strong-motion data, BSSA 95(2), 745-750. A. F. Converse, A. G. Brady (1992),
BAP: basic strong-motion accelerogram processing software, USGS Open-File Report 92-296A.

`displacement_history(record, peak_m, fs_out)` does all of the above, scales the displacement to
a peak |x| (the papers: 0.01 m for the BRFD, 0.4 in for the MFD: the test rig's stroke limit)
and resamples it (polyphase FIR with anti-alias filtering, `scipy.signal.resample_poly`, for a
rational rate ratio; otherwise a cubic spline of the displacement, which double integration has
already made smooth).
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import numpy as np
from scipy import signal
from scipy.interpolate import CubicSpline

from .errors import InputError
from .units import factor

__all__ = ["GroundMotion", "read_at2", "read_single_column", "read_columns", "read_record",
           "baseline_correct", "integrate", "displacement_history", "resample", "RECORDS",
           "load_record", "ground_motions_dir"]


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
    return np.asarray(values, dtype=float) * f


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
    if dt is None:
        raise InputError(f"{path}: a single-column accelerogram has no time step in the file; "
                         "give dt")
    return read_single_column(path, dt=dt, unit=unit or "g", name=name)


# --------------------------------------------------------------------- processing

def _check_filter(f_corner: float, order: int, dt: float) -> None:
    if not (np.isfinite(f_corner) and 0 < f_corner < 0.5 / dt):
        raise ValueError(f"f_corner must be in (0, Nyquist = {0.5 / dt:g} Hz), got {f_corner!r}")
    if int(order) != order or order < 2 or order % 2:
        raise ValueError(f"order must be an even integer >= 2 (the acausal filter's total order), "
                         f"got {order!r}")


def _taper(a: np.ndarray, frac: float) -> np.ndarray:
    if not 0 <= frac <= 0.5:
        raise ValueError(f"taper must be a fraction in [0, 0.5], got {frac!r}")
    m = int(round(frac * a.size))
    if m < 2:
        return a
    w = 0.5 * (1 - np.cos(np.pi * np.arange(m) / m))      # half-cosine, 0 -> 1
    out = a.copy()
    out[:m] *= w
    out[-m:] *= w[::-1]
    return out


def _pad_samples(f_corner: float, order: int, dt: float) -> int:
    """Samples of zero pad at each end: half of Tzpad = 1.5 order / f_corner (Boore 2005)."""
    return int(np.ceil(0.5 * 1.5 * order / f_corner / dt))


def integrate(a: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Velocity and displacement of acceleration `a` (uniform step dt) by the trapezoid rule,
    both starting at 0."""
    v = np.concatenate(([0.0], np.cumsum(0.5 * (a[1:] + a[:-1]) * dt)))
    x = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt)))
    return v, x


def velocity_baseline(a: np.ndarray, dt: float, degree: int = 2) -> np.ndarray:
    """Acceleration minus the derivative of the least-squares polynomial of degree `degree`
    fitted to its velocity (Boore & Bommer 2005; degree 2 removes a constant and a
    linear drift of the acceleration, degree 1 a constant one)."""
    if int(degree) != degree or not 1 <= degree <= 6:
        raise ValueError(f"poly_degree must be an integer in 1..6, got {degree!r}")
    v, _ = integrate(a, dt)
    t = np.arange(a.size) * dt
    tau = t / t[-1]                                   # scaled for a well-conditioned fit
    coef = np.polynomial.polynomial.polyfit(tau, v, int(degree))
    dcoef = np.polynomial.polynomial.polyder(coef) / t[-1]
    return a - np.polynomial.polynomial.polyval(tau, dcoef)


def baseline_correct(record: GroundMotion, f_corner: float = 0.1, order: int = 4,
                     taper: float = 0.05, poly_degree: int | None = 2, pad_keep: float = 0.0):
    """Baseline-corrected acceleration, velocity and displacement (SI) of `record`.

    Boore & Bommer (2005) / Boore (2005): velocity-polynomial baseline of degree `poly_degree`
    (None: mean removal only), half-cosine end tapers over `taper` of the length, zero pads of
    1.5*order/f_corner s in total, acausal Butterworth high-pass (total order `order`, corner
    `f_corner` Hz), double trapezoid integration of the padded record. Returns (t, a, v, x); t is
    0 at the record's first sample. `pad_keep` (s, default 0; inf = all) keeps that much of each
    zero pad, where the acausal filter's response already or still moves the ground (Boore 2005
    recommends keeping the pads; with them the displacement starts and ends at rest).
    """
    dt = record.dt
    _check_filter(f_corner, order, dt)
    a = np.asarray(record.a, dtype=float)
    a = a - a.mean() if poly_degree is None else velocity_baseline(a, dt, poly_degree)
    a = _taper(a, taper)
    npad = _pad_samples(f_corner, order, dt)
    ap = np.concatenate((np.zeros(npad), a, np.zeros(npad)))
    sos = signal.butter(order // 2, f_corner, btype="highpass", fs=1.0 / dt, output="sos")
    af = signal.sosfiltfilt(sos, ap, padtype=None)
    v, x = integrate(af, dt)
    t = (np.arange(ap.size) - npad) * dt
    if not pad_keep >= 0:
        raise ValueError(f"pad_keep must be >= 0 s, got {pad_keep!r}")
    keep = npad if pad_keep == np.inf else min(npad, int(round(pad_keep / dt)))
    sl = slice(npad - keep, npad + a.size + keep)
    return t[sl], af[sl], v[sl], x[sl]


def resample(t: np.ndarray, x: np.ndarray, fs_out: float) -> tuple[np.ndarray, np.ndarray]:
    """Resample a uniformly sampled smooth signal to `fs_out` Hz, same start time, within the
    same time span. Rational rate ratios (denominator <= 100) use a polyphase anti-alias FIR
    (`scipy.signal.resample_poly`, ends extended linearly); others a cubic spline."""
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    if not (np.isfinite(fs_out) and fs_out > 0):
        raise ValueError(f"fs_out must be > 0 Hz, got {fs_out!r}")
    dt = (t[-1] - t[0]) / (t.size - 1)
    fs_in = 1.0 / dt
    n_out = int(np.floor((t[-1] - t[0]) * fs_out + 1e-9)) + 1
    t_out = t[0] + np.arange(n_out) / fs_out
    ratio = Fraction(fs_out / fs_in).limit_denominator(100)
    if abs(float(ratio) - fs_out / fs_in) <= 1e-9 * fs_out / fs_in:
        if ratio == 1:
            return t.copy(), x.copy()
        y = signal.resample_poly(x, ratio.numerator, ratio.denominator, padtype="line")
        return t_out, y[:n_out]
    return t_out, CubicSpline(t, x)(t_out)


def displacement_history(record: GroundMotion, peak_m: float | None = None,
                         fs_out: float | None = None, *, f_corner: float = 0.1, order: int = 4,
                         taper: float = 0.05, poly_degree: int | None = 2,
                         pad_keep: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Ground displacement (m) of `record` at times t (s, from 0): baseline-corrected
    (`baseline_correct`, which documents the parameters), double-integrated, scaled so that
    max|x| = `peak_m` (None: unscaled) and resampled to `fs_out` Hz (None: the record's own
    rate). With `pad_keep` > 0, t = 0 is the start of the kept front pad."""
    t, _, _, x = baseline_correct(record, f_corner=f_corner, order=order, taper=taper,
                                  poly_degree=poly_degree, pad_keep=pad_keep)
    t = t - t[0]
    if peak_m is not None:
        if not (np.isfinite(peak_m) and peak_m > 0):
            raise ValueError(f"peak_m must be > 0 m, got {peak_m!r}")
        x = x * (peak_m / np.max(np.abs(x)))
    if fs_out is not None:
        t, x = resample(t, x, fs_out)
        if peak_m is not None:      # resampling moves the peak slightly: scale again, exactly
            x = x * (peak_m / np.max(np.abs(x)))
    return t, x


# ------------------------------------------------------------ the shipped records

def ground_motions_dir() -> Path:
    """The folder of the shipped accelerograms: $FRICTIONUQ_GROUND_MOTIONS, else the source
    tree's data/ground-motions."""
    env = os.environ.get("FRICTIONUQ_GROUND_MOTIONS")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[2] / "data" / "ground-motions"


@dataclass(frozen=True)
class RecordRef:
    key: str
    folder: str
    file: str
    label: str                      # short name used in test ids
    description: str
    dt: float | None = None         # for files that do not state it
    unit: str | None = None
    column: int = 0


#: The accelerograms the paper twins use (see data/ground-motions/README.md for why these).
RECORDS: dict[str, RecordRef] = {r.key: r for r in (
    RecordRef("imperial-valley", "eq-impvall1979-elcentro12", "RSN175_IMPVALL.H_H-E12140.AT2",
              "imperial-valley",
              "1979 Imperial Valley (Imperial Valley-06), El Centro Array #12, 140 deg; "
              "PEER NGA-West2 RSN 175 (the papers used USGS 5115 / PEER P0174, not available)"),
    RecordRef("hollister", "eq-hollister1961-cityhall", "Hollister-01_271.dat", "hollister",
              "1961 Hollister (Hollister-01), very likely Hollister City Hall (USGS 1028), 271 deg; "
              "PEER NGA-West2 RSN 26 via a student repository, no licence",
              dt=0.005, unit="g"),
    RecordRef("kobe", "eq-kobe1995-jma-benchmark", "kobe.txt", "kobe",
              "1995 Kobe, JMA Kobe station, fault-normal (N-S) component, ASCE base-isolation "
              "benchmark set (the MFD paper used Kakogawa CUE90, not available)",
              dt=0.005, unit="cm/s^2", column=0),
)}


def load_record(key: str, root=None) -> GroundMotion:
    """One of the shipped accelerograms by key (`RECORDS`), in SI."""
    try:
        ref = RECORDS[key]
    except KeyError:
        raise InputError(f"unknown ground motion {key!r}; known: {', '.join(RECORDS)}") from None
    root = Path(root) if root is not None else ground_motions_dir()
    path = root / ref.folder / ref.file
    if not path.is_file():
        raise InputError(f"{path}: ground-motion file not found (set FRICTIONUQ_GROUND_MOTIONS to "
                         "the folder holding data/ground-motions)")
    if path.suffix.lower() == ".at2":
        gm = read_at2(path, name=key)
    elif ref.column or path.suffix.lower() == ".txt":
        gm = read_columns(path, column=ref.column, dt=ref.dt, unit=ref.unit, name=key)
    else:
        gm = read_single_column(path, dt=ref.dt, unit=ref.unit or "g", name=key)
    return GroundMotion(name=gm.name, source=gm.source, dt=gm.dt, a=gm.a,
                        unit_in_file=gm.unit_in_file,
                        description=ref.description, meta={**gm.meta, "file_header": gm.description})
