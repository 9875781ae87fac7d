"""The report's sections, in order: each builder reads the run folder through a
`report.context.Context` and returns a list of content blocks (report.blocks)."""
from __future__ import annotations

from .. import blocks as B

#: (id, title) of every section, in the report's order
SECTIONS: list[tuple[str, str]] = [
    ("campaign", "Campaign overview"),
    ("fits", "Fits"),
    ("across", "Across applied forces"),
    ("advantage", "Mechanical advantage"),
    ("comparison", "Model comparison"),
    ("predictions", "Predictions and validation"),
    ("discrepancy", "Discrepancy: the missing effect"),
    ("provenance", "Provenance"),
]


def build_sections(ctx, generated: str) -> list[dict]:
    """[{"id", "title", "blocks"}] for every section of SECTIONS (never an empty one)."""
    from . import campaign, comparison, discrepancy, fits, levels, predictions, provenance
    builders = {"campaign": campaign.build, "fits": fits.build, "across": levels.across,
                "advantage": levels.advantage, "comparison": comparison.build,
                "predictions": predictions.build, "discrepancy": discrepancy.build,
                "provenance": lambda c: provenance.build(c, generated)}
    out = []
    for sid, title in SECTIONS:
        blocks = builders[sid](ctx) or [B.note("Nothing to show in this section for this run.")]
        out.append({"id": sid, "title": title, "blocks": blocks})
    return out
