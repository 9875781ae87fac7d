"""Assembly of the report: the sections' blocks rendered by the jinja2 template into one
self-contained HTML file (inline CSS, images as base64 PNG data URIs, no script, no external
URL), written atomically."""
from __future__ import annotations

from pathlib import Path

from .. import __version__, atomic
from ..environment import timestamp
from ..errors import InputError
from . import blocks as B
from .context import Context, section_of
from .sections import SECTIONS, build_sections

TEMPLATE = "report.html"


def _env():
    import jinja2
    return jinja2.Environment(loader=jinja2.PackageLoader("frictionuq.report", "templates"),
                              autoescape=jinja2.select_autoescape(["html"]),
                              undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)


def alerts(ctx) -> list[str]:
    """Run-level warnings shown under the title."""
    out = []
    fits = ctx.fits()
    bad = [f["id"] for f in fits if not f.get("converged")]
    if bad:
        out.append(f"{len(bad)} of {len(fits)} fits did NOT converge ({', '.join(bad)}): their "
                   "intervals and everything derived from them are not reliable.")
    failed = [t.get("name", "?") for t in ctx.provenance.get("tasks") or []
              if isinstance(t, dict) and t.get("error")]
    if failed:
        out.append(f"Tasks that failed: {', '.join(map(str, failed))} (see Provenance).")
    return out


def render_html(ctx: Context, generated: str | None = None) -> str:
    """The report of the run behind `ctx` as an HTML string."""
    generated = generated or timestamp()
    sections = build_sections(ctx, generated)
    desc = section_of(ctx.workflow, "workflow").get("description") or ""
    return _page(ctx.title(), desc, ctx.run_dir, generated, sections, alerts(ctx))


def _page(title, description, run_dir, generated, sections, alert_lines) -> str:
    """The template filled: one self-contained HTML page."""
    return _env().get_template(TEMPLATE).render(
        title=title, description=description, run_dir=str(run_dir), generated=generated,
        version=__version__, sections=sections, alerts=alert_lines)


def render_report(run_dir, out_html, *, workflow: dict, provenance: dict) -> Path:
    """Build the HTML report of the workflow run folder `run_dir` and write it to `out_html`
    (atomically: on any error no file, and an existing report is left as it was).

    workflow: the parsed workflow TOML ([workflow], [fit], [predict], [compare], [report]
    title/published; missing keys take defaults). provenance: the run record (format of
    run.json: package_version, workflow {name, file, sha256, config}, seed, started, finished,
    inputs, tasks). Returns the path written."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise InputError(f"{run_dir}: no such workflow run folder")
    ctx = Context(run_dir, workflow or {}, provenance or {})
    html = render_html(ctx)
    return atomic.write_text(Path(out_html), html)


def render_discrepancy_page(folder, out_html=None) -> Path:
    """The report page of a `frictionuq discover` output folder (default: folder/report.html):
    the named effect, the candidates, the gap before and after (per-test RMSE, loops with the
    old and new model, residual signatures) and what made it (version, seed, config). Written
    atomically."""
    import json
    from .sections import discrepancy
    folder = Path(folder)
    p = folder / "discrepancy.json"
    if not p.is_file():
        raise InputError(f"{folder}: no discrepancy.json (run `frictionuq discover` first)")
    d = json.loads(p.read_text())
    ctx = Context(folder, {}, {})
    generated = timestamp()
    st = d.get("seconds_by_stage") or {}
    stages = (" (" + ", ".join(f"{k} {v:.0f} s" for k, v in st.items()) + ")") if st else ""
    prov = [B.para(f"Made by frictionuq {d.get('package_version')} from campaign "
                   f"{d.get('campaign')} ({d.get('campaign_path')}), seed {d.get('seed')}, in "
                   f"{d.get('seconds', float('nan')):.0f} s{stages}."),
            B.pre(json.dumps(d.get("config", {}), indent=2))]
    if isinstance(d.get("environment"), dict):      # software and machine (frictionuq.environment)
        prov.append(B.pre(json.dumps(d["environment"], indent=2)))
    sections = [{"id": "discrepancy", "title": "Discrepancy: the missing effect",
                 "blocks": discrepancy.build(ctx, folder)},
                {"id": "provenance", "title": "Provenance", "blocks": prov}]
    html = _page(f"frictionuq discover: {d.get('campaign')}", "", folder, generated, sections, [])
    return atomic.write_text(Path(out_html) if out_html else folder / "report.html", html)


__all__ = ["render_report", "render_html", "render_discrepancy_page", "SECTIONS"]
