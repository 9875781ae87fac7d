"""Section "campaign": one row per test of the ingested campaign, with data-quality flags."""
from __future__ import annotations

import numpy as np

from ... import noise
from ...quality import EPS_STROKE_MAX, FEW_REVERSALS, FORCE_PLAUSIBLE_N, STROKE_PLAUSIBLE_M, quality
from .. import blocks as B
from ..tables import DASH, nowrap, num, table
from ...wording import count

UM = 1e6


def build(ctx) -> list[dict]:
    camp = ctx.campaign()
    if camp is None:
        return [B.note("No ingested campaign in this run (ingest/manifest.json missing): the "
                       "campaign overview is not available.")]
    unit = ctx.applied_unit()
    head = [B.para(f"Campaign {camp.name!s}: {count(len(camp.tests), 'test')}. Device: "
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
    blocks = head + [B.html(table(cols, rows, row_classes=classes, tid="campaign-table",
                                        caption="tests of the ingested campaign, with data-quality flags"))]
    blocks.append(B.note(
        "Displacement noise: robust estimate from 4th differences (frictionuq.noise); dead band "
        f"eps = {noise.EPS_MULTIPLIER:g} x noise sd; reversals counted by the kernel's detector "
        f"with that eps. Flags: eps above {EPS_STROKE_MAX:.0%} of the stroke, a long run of "
        "samples at the record's extreme (clipping), a constant record, fewer than "
        f"{FEW_REVERSALS} reversals or under half of the 2 per cycle a harmonic test should give, "
        f"a stroke above {STROKE_PLAUSIBLE_M:g} m (a displacement unit mix-up), a force above "
        f"{FORCE_PLAUSIBLE_N:.0e} N (a force unit mix-up or a corrupt sample)."))
    if n_flagged:
        blocks.append(B.warn(f"{n_flagged} of {len(camp.tests)} tests carry data-quality flags "
                             "(highlighted rows)."))
    return blocks
