"""Data-quality figures and flags of a test's record: the displacement noise and dead band, the
reversals seen against those a harmonic should give, clipping, a flat record, and a stroke or a
force no damper test has (a unit mix-up or a corrupt sample). Used by the `table` command and the report's campaign section."""
from __future__ import annotations

import numpy as np

from . import noise

UM = 1e6
EPS_STROKE_MAX = 0.05       # dead band above this fraction of the stroke: reversals seen late
FEW_REVERSALS = 3
CLIP_RUN = 8                # samples pinned at the record's extreme: clipped above this run length


def _longest_run_at(v: np.ndarray, value: float) -> int:
    eq = np.concatenate([[False], v == value, [False]]).astype(np.int8)
    d = np.diff(eq)
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    return int(np.max(ends - starts)) if starts.size else 0


def clipped(v) -> bool:
    """The record sits at its maximum or minimum for a long run of samples (saturated sensor)."""
    v = np.asarray(v, float)
    limit = max(CLIP_RUN, v.size // 500)
    return _longest_run_at(v, np.max(v)) > limit or _longest_run_at(v, np.min(v)) > limit


STROKE_PLAUSIBLE_M = 1.0    # peak-to-peak displacement above this: probably a unit mix-up
FORCE_PLAUSIBLE_N = 1e7     # |force| above this (10 MN): a unit mix-up or a corrupt sample


def quality(test) -> dict:
    """Data-quality figures and flags of one test's record (SI arrays)."""
    r = test.record
    x, f = r.x, r.force
    out = {"flags": []}
    stroke = float(np.ptp(x))
    try:
        sd = noise.displacement_noise_sd(x)
        eps = noise.default_eps(x)
    except ValueError:
        sd = eps = float("nan")
        out["flags"].append("too short to estimate the displacement noise")
    out.update(noise_sd=sd, eps=eps)
    out["reversals"] = noise.count_reversals(x, eps if np.isfinite(eps) else 0.0)
    expected = None
    if test.kind == "harmonic" and test.frequency_hz:
        expected = 2.0 * test.frequency_hz * float(r.t[-1] - r.t[0])
    out["expected_reversals"] = expected
    if np.isfinite(eps) and stroke > 0 and eps > EPS_STROKE_MAX * stroke:
        out["flags"].append(f"dead band eps {eps * UM:.3g} µm is > {EPS_STROKE_MAX:.0%} of the stroke")
    if np.isfinite(sd) and sd == 0:
        out["flags"].append("no displacement noise (clean or simulated record): eps = 0")
    if stroke > STROKE_PLAUSIBLE_M:     # a damper test's stroke is centimetres: mm read as m?
        out["flags"].append(f"stroke {stroke:.3g} m is above {STROKE_PLAUSIBLE_M:g} m: check the "
                            "campaign's displacement unit")
    peak = float(np.max(np.abs(f))) if f.size else 0.0
    if peak > FORCE_PLAUSIBLE_N:        # the papers' dampers reach tens of kN
        out["flags"].append(f"peak |force| {peak:.3g} N is above {FORCE_PLAUSIBLE_N:.0e} N: check the "
                            "campaign's force unit, or a corrupt sample")
    if np.ptp(f) == 0 or stroke == 0:
        out["flags"].append("flat record (force or displacement constant)")
    else:
        for name, v in (("force", f), ("displacement", x)):
            if clipped(v):
                out["flags"].append(f"{name} looks clipped (long run at its extreme)")
    few = out["reversals"] < FEW_REVERSALS or (expected is not None and out["reversals"] < 0.5 * expected)
    if few:
        exp = f", about {expected:.0f} expected" if expected is not None else ""
        out["flags"].append(f"very few reversals ({out['reversals']}{exp})")
    out["applied_channel"] = r.applied is not None
    return out
