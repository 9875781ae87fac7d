"""Section "campaign": one row per test of the ingested campaign, with data-quality flags."""
from __future__ import annotations

import numpy as np

from ... import noise
from .. import blocks as B
from ..tables import DASH, nowrap, num, table

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


def build(ctx) -> list[dict]:
    camp = ctx.campaign()
    if camp is None:
        return [B.note("No ingested campaign in this run (ingest/manifest.json missing): the "
                       "campaign overview is not available.")]
    unit = ctx.applied_unit()
    head = [B.para(f"Campaign {camp.name!s}: {len(camp.tests)} tests. Device: "
                   f"{camp.device or 'not stated'}. {camp.description}".strip())]
    if camp.geometry:
        geo = ", ".join(f"{k} = {v:g}" + {"drum_radius": " m", "damping_radius": " m",
                                          "wrap_deg": " deg"}.get(k, "")
                        for k, v in sorted(camp.geometry.items()))
        head.append(B.para(f"Geometry: {geo}."))
    rows, classes, n_flagged = [], [], 0
    for te in camp.tests:
        r = te.record
        q = quality(te)
        n_flagged += bool(q["flags"])
        rows.append([nowrap(te.id), "; ".join(q["flags"]) or "none", ctx.applied_number(te.applied), te.kind,
                     num(te.frequency_hz) if te.frequency_hz else DASH, r.n,
                     num(float(r.t[-1] - r.t[0])),
                     nowrap(f"{np.min(r.force) * 1e-3:.3g} to {np.max(r.force) * 1e-3:.3g}"),
                     nowrap(f"{np.min(r.x) * 1e3:.3g} to {np.max(r.x) * 1e3:.3g}"),
                     num(q["noise_sd"] * UM, 3), num(q["eps"] * UM, 3), q["reversals"],
                     "measured" if q["applied_channel"] else "absent"])
        classes.append("flagged" if q["flags"] else "")
    cols = ["test", "data-quality flags", f"applied force ({unit})", "kind", "frequency (Hz)", "samples", "duration (s)",
            "force range (kN)", "displacement range (mm)", "displacement noise sd (µm)",
            "dead band eps (µm)", "reversals seen", "measured applied-force channel"]
    blocks = head + [B.html(table(cols, rows, row_classes=classes, tid="campaign-table"))]
    blocks.append(B.note(
        "Displacement noise: robust estimate from 4th differences (frictionuq.noise); dead band "
        f"eps = {noise.EPS_MULTIPLIER:g} x noise sd; reversals counted by the kernel's detector "
        f"with that eps. Flags: eps above {EPS_STROKE_MAX:.0%} of the stroke, a long run of "
        "samples at the record's extreme (clipping), a constant record, fewer than "
        f"{FEW_REVERSALS} reversals or under half of the 2 per cycle a harmonic test should give."))
    if n_flagged:
        blocks.append(B.warn(f"{n_flagged} of {len(camp.tests)} tests carry data-quality flags "
                             "(highlighted rows)."))
    return blocks
