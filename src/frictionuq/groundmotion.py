"""Real ground motions as drives for the earthquake tests: accelerogram readers, baseline-drift
removal, double integration to displacement, scaling and resampling.

Readers: `frictionuq.accelerograms` (re-exported here): `read_at2` (PEER NGA `.AT2`),
`read_single_column`, `read_columns`, `read_record`, all returning a `GroundMotion` in SI.

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

import math
import os
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np
from scipy import signal
from scipy.interpolate import CubicSpline

from .accelerograms import (GroundMotion, read_at2, read_columns, read_record,  # noqa: F401
                            read_single_column)
from .errors import InputError, unknown

__all__ = ["GroundMotion", "read_at2", "read_single_column", "read_columns", "read_record",
           "baseline_correct", "integrate", "displacement_history", "resample", "RECORDS",
           "load_record", "ground_motions_dir"]


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


def legfit_exact(t: np.ndarray, y: np.ndarray, degree: int) -> np.ndarray:
    """Least-squares Legendre coefficients (numpy.polynomial.legendre order) of y on t in
    [-1, 1], from the normal equations with correctly rounded sums (math.fsum) and Gaussian
    elimination in Python floats: the same bits on every CPU. numpy's polyfit goes through
    LAPACK, whose OpenBLAS kernels are chosen per CPU: the shipped twins' earthquake drives
    differed in the last printed digit between an Intel (SkylakeX kernels) and an AMD EPYC
    machine (measured 2026-11-25). In the Legendre basis the normal equations of a uniform grid
    are nearly diagonal, so forming them loses nothing."""
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    n = degree + 1
    P = [np.ones_like(t), t.copy()]
    for k in range(1, degree):
        P.append(((2 * k + 1) * t * P[k] - k * P[k - 1]) / (k + 1))
    P = P[:n]
    A = [[math.fsum(P[i] * P[j]) for j in range(n)] for i in range(n)]
    b = [math.fsum(P[i] * y) for i in range(n)]
    for k in range(n):                    # Gaussian elimination with partial pivoting
        p = max(range(k, n), key=lambda r: abs(A[r][k]))
        A[k], A[p], b[k], b[p] = A[p], A[k], b[p], b[k]
        for r in range(k + 1, n):
            f = A[r][k] / A[k][k]
            A[r] = [A[r][j] - f * A[k][j] for j in range(n)]
            b[r] -= f * b[k]
    c = [0.0] * n
    for k in reversed(range(n)):
        c[k] = (b[k] - math.fsum(A[k][j] * c[j] for j in range(k + 1, n))) / A[k][k]
    return np.array(c)


def velocity_baseline(a: np.ndarray, dt: float, degree: int = 2) -> np.ndarray:
    """Acceleration minus the derivative of the least-squares polynomial of degree `degree`
    fitted to its velocity (Boore & Bommer 2005; degree 2 removes a constant and a
    linear drift of the acceleration, degree 1 a constant one)."""
    if int(degree) != degree or not 1 <= degree <= 6:
        raise ValueError(f"poly_degree must be an integer in 1..6, got {degree!r}")
    v, _ = integrate(a, dt)
    t = np.arange(a.size) * dt
    s = 2.0 * t / t[-1] - 1.0                         # [-1, 1]: Legendre basis
    L = np.polynomial.legendre
    coef = legfit_exact(s, v, int(degree))
    return a - L.legval(s, L.legder(coef)) * (2.0 / t[-1])


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
        if not np.max(np.abs(x)) > 0:
            raise ValueError(f"{record.source}: the record's displacement is 0 everywhere after "
                             "baseline correction; it cannot be scaled to peak_m")
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


def load_source(src: dict) -> GroundMotion:
    """The accelerogram (SI) of a workflow's [[predict.ground_motion]] entry: a shipped record
    {"record": key}, or the user's file {"file", "dt", "unit", "column"} (read_record)."""
    if "record" in src:
        return load_record(src["record"])
    p = Path(src["file"])
    return read_record(p, dt=src.get("dt"), unit=src.get("unit"), column=src.get("column", 0),
                       name=p.stem)


def load_record(key: str, root=None) -> GroundMotion:
    """One of the shipped accelerograms by key (`RECORDS`), in SI."""
    try:
        ref = RECORDS[key]
    except KeyError:
        raise InputError(unknown("ground motion", key, RECORDS)) from None
    root = Path(root) if root is not None else ground_motions_dir()
    path = root / ref.folder / ref.file
    if not path.is_file():
        raise InputError(f"{path}: ground-motion file not found (set FRICTIONUQ_GROUND_MOTIONS to "
                         f"the shipped data/ground-motions folder itself, the one holding {ref.folder}/)")
    if path.suffix.lower() == ".at2":
        gm = read_at2(path, name=key)
    elif ref.column or path.suffix.lower() == ".txt":
        gm = read_columns(path, column=ref.column, dt=ref.dt, unit=ref.unit, name=key)
    else:
        gm = read_single_column(path, dt=ref.dt, unit=ref.unit or "g", name=key)
    return GroundMotion(name=gm.name, source=gm.source, dt=gm.dt, a=gm.a,
                        unit_in_file=gm.unit_in_file,
                        description=ref.description, meta={**gm.meta, "file_header": gm.description})
