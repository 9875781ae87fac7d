"""The HTML report of a workflow run: one self-contained file (inline CSS, every figure a base64
PNG data URI, no script, no external URL) with a table of contents and the sections of
`SECTIONS`, each an element with a stable id.

    from frictionuq.report import render_report
    render_report("runs/quick", "runs/quick/report.html", workflow=wf, provenance=run_json)
    render_discrepancy_page("out/discover")    # the page of a `frictionuq discover` folder

Modules: context (reads the run folder), sections/ (one builder per section), tables (HTML
tables), figures, figures_fit, figures_levels (matplotlib -> PNG), blocks (content blocks),
render (jinja2 template templates/report.html, atomic write).
"""
from .sections import SECTIONS
from .render import render_discrepancy_page, render_report

__all__ = ["render_report", "render_discrepancy_page", "SECTIONS"]
