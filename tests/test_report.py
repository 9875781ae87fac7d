"""frictionuq.report: the self-contained HTML report of a workflow run.

Most tests use the session's run folder and report (tests/conftest.py: a tiny, unconverged run
on 2 short BRFD tests, built with the library); a few check helpers on synthetic data. The last
test opens the report as a reader sees it, in headless Chromium (tests/browser.py). (One file:
pytest-xdist sends each file to one worker, so the shared run is built once.)"""
from __future__ import annotations

import base64
import json
import re
import shutil
from html import unescape
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from frictionuq import published
from frictionuq.campaign import Record
from frictionuq.campaign import Test as CampaignTest
from browser import check_report_in_browser, chromium_path
from frictionuq.report import SECTIONS, render_report
from frictionuq.quality import quality
from frictionuq.report.sections import comparison
from frictionuq.report.tables import num, table

PNG = b"\x89PNG\r\n\x1a\n"


class Outline(HTMLParser):
    """Text per element id (a section's text includes its sub-sections'), img sources, links."""

    def __init__(self):
        super().__init__()
        self.stack, self.text, self.imgs, self.urls, self.tags = [], {}, [], [], []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.append(tag)
        if tag == "img":
            self.imgs.append(a)
        for k in ("src", "href"):
            if k in a:
                self.urls.append(a[k])
        if tag not in ("img", "meta", "br", "link", "input"):
            self.stack.append(a.get("id"))
            if a.get("id"):
                self.text.setdefault(a["id"], "")

    def handle_endtag(self, tag):
        if tag not in ("img", "meta", "br", "link", "input") and self.stack:
            self.stack.pop()

    def handle_data(self, data):
        for i in self.stack:
            if i:
                self.text[i] += data


def outline(html: str) -> Outline:
    p = Outline()
    p.feed(html)
    return p


def section_html(html: str, sid: str) -> str:
    """The HTML of the element with id `sid` up to the next top-level section."""
    start = html.index(f'id="{sid}"')
    nxt = html.find('<section class="section"', start)
    return html[start:nxt if nxt > 0 else len(html)]


def sub_html(html: str, sid: str) -> str:
    start = html.index(f'<section class="sub" id="{sid}"')
    return html[start:html.index("</section>", start)]


# ---------------------------------------------------------------- fast helpers

def test_paper_table4_constant_matches_published():
    kn = comparison.PAPER_TABLE4_RMSE_KN
    assert set(kn) == set(published.BRFD_TABLE4_RMSE_N)
    for a, row in kn.items():
        for f, (s3, lg) in row.items():
            ref = published.BRFD_TABLE4_RMSE_N[a][f]
            assert (s3 * 1e3, lg * 1e3) == pytest.approx(ref)
    assert comparison.paper_level(35.5) == 35.0 and comparison.paper_level(160.0) is None


def test_num_formats_integers_and_missing_values():
    assert num(28698.0) == "28698"
    assert num(13000.83) == "13001"
    assert num(0.0123456) == "0.01235"
    assert num(float("nan")) == "\u2013" and num(None) == "\u2013"
    assert num(1.2e9) == "1.200e+09"
    html = table(["a (N)", "b"], [["<x>", 3]])
    assert "&lt;x&gt;" in html and 'class="table-wrap"' in html


def _test(x, f, kind="harmonic", freq=1.0):
    t = np.arange(x.size) / 100.0
    return CampaignTest(id="t", file="t.csv", applied=10.0, kind=kind, frequency_hz=freq,
                record=Record(t, x, f))


def test_quality_flags_clipping_few_reversals_and_clean_records():
    t = np.arange(2000) / 100.0
    x = 0.02 * np.sin(2 * np.pi * 1.0 * t)
    q = quality(_test(x, 1e3 * np.sign(np.cos(2 * np.pi * t)) + np.sin(t)))
    assert q["flags"] == [] and q["applied_channel"] is False
    assert q["reversals"] == pytest.approx(q["expected_reversals"], abs=2)
    f = np.clip(5e3 * np.sin(2 * np.pi * t), -2e3, 2e3)           # saturated load cell
    rng = np.random.default_rng(0)
    q = quality(_test(x + 1e-6 * rng.standard_normal(x.size), f))
    assert any("force looks clipped" in s for s in q["flags"]), q["flags"]
    slow = 0.02 * np.sin(2 * np.pi * 0.02 * t)                    # says 1 Hz, moves at 0.02 Hz
    q = quality(_test(slow + 1e-6 * rng.standard_normal(t.size), np.sin(t)))
    assert any("very few reversals" in s for s in q["flags"]), q["flags"]
    # millimetres read as metres: a 40 m stroke is flagged, not fitted silently
    q = quality(_test(1e3 * x + 1e-3 * rng.standard_normal(x.size),
                                       1e3 * np.sign(np.cos(2 * np.pi * t))))
    assert any("check the campaign's displacement unit" in s for s in q["flags"]), q["flags"]
    # one corrupt sample of 1e300 N (or kN read as N on a big machine) is flagged, not fitted
    # silently; 10 MN is the limit, a real damper's force (tens of kN) is not flagged
    noisy = x + 1e-6 * rng.standard_normal(x.size)
    bad = 1e3 * np.sign(np.cos(2 * np.pi * t))
    bad[700] = 1e300
    q = quality(_test(noisy, bad))
    assert any("peak |force| 1e+300 N is above 1e+07 N" in s for s in q["flags"]), q["flags"]
    assert quality(_test(noisy, 0.99e7 * np.sign(np.cos(2 * np.pi * t)) + np.sin(t)))["flags"] == []


# ---------------------------------------------------------------- the rendered report

@pytest.mark.slow
def test_every_section_present_nonempty_and_linked(rendered_report):
    html = rendered_report["html"]
    o = outline(html)
    for sid, title in SECTIONS:
        assert sid in o.text, f"section {sid} missing"
        body = o.text[sid].replace(title, "").strip()
        assert len(body) > 80, f"section {sid} is (nearly) empty: {body!r}"
        assert f'href="#{sid}"' in html, f"no table-of-contents link to {sid}"
    for fid in ("applied-36lb", "applied-0lb"):
        assert f'id="fit-{fid}"' in html and f'href="#fit-{fid}"' in html
    assert rendered_report["path"].stat().st_size < 8e6


@pytest.mark.slow
def test_images_are_inline_pngs_and_nothing_external(rendered_report):
    html = rendered_report["html"]
    o = outline(html)
    # 2 fits x (test figures + residuals + corner + rank), across, advantage, validation, prediction
    assert len(o.imgs) >= 12
    for im in o.imgs:
        src = im["src"]
        assert src.startswith("data:image/png;base64,"), src[:60]
        data = base64.b64decode(src.split(",", 1)[1], validate=True)
        assert data.startswith(PNG) and len(data) > 1000
        assert im.get("alt")
    assert not [u for u in o.urls if re.match(r"\s*(https?:)?//", u)], "external URL in src/href"
    assert not re.search(r"https?://", " ".join(o.urls))
    assert "script" not in o.tags and "link" not in o.tags and "iframe" not in o.tags
    assert "url(" not in html                                   # no CSS resource either
    assert "max-width: 1100px" in html
    assert html.count("<table") == html.count('class="table-wrap"')


@pytest.mark.slow
def test_parameter_tables_carry_units(report_run, rendered_report):
    part = sub_html(rendered_report["html"], "fit-applied-36lb")
    summary = json.loads((report_run["run_dir"] / "fit" / "summary.json").read_text())
    fit = next(f for f in summary["fits"] if f["id"] == "applied-36lb")
    # shown in display units (summary.json keeps SI): the mean is the SI mean times the factor
    for name, unit, factor in (("fc_fwd", "kN", 1e-3), ("sigma0", "kN/mm", 1e-6),
                               ("sigma1", "kN s/m", 1e-3), ("v_s", "mm/s", 1e3), ("d2", "mm", 1e3),
                               ("force_offset", "kN", 1e-3),
                               ("sigma_noise[sine-2Hz-36lb-0.5in]", "kN", 1e-3),
                               ("noise_phi[sine-2Hz-36lb-0.5in]", "1", 1.0)):
        row = re.search(re.escape(f"<tr><td>{name}</td><td>{unit}</td>") + r"<td>([^<]*)</td>", part)
        assert row, f"parameter {name} without its unit {unit}"
        shown, mean = float(row.group(1)), fit["parameters"][name]["mean"] * factor
        assert shown == pytest.approx(mean, rel=1e-3, abs=1e-12), (name, shown, mean)
    for header in ("<th>unit</th>", "<th>2.5 %</th>", "<th>97.5 %</th>", "R-hat", "ESS bulk",
                   "ESS tail", "autocorrelation time tau (steps)", "RMSE of the posterior-median"):
        assert header in part


def test_fit_block_says_how_the_drive_was_prepared(report_run, rendered_report):
    """Each fit's table names the drive low-pass cutoffs fit.json records per test and the
    reversal rule of its config (the real records of the session's run have eps > 0: filtered)."""
    part = unescape(sub_html(rendered_report["html"], "fit-applied-36lb"))
    rec = json.loads((report_run["run_dir"] / "fit" / "applied-36lb" / "fit.json").read_text())
    cuts = [r["drive_cutoff_hz"] for r in rec["records"]]
    assert cuts and all(c > 0 for c in cuts), cuts
    assert "displacement the model ran on" in part
    for r in rec["records"]:
        assert f"{r['id']} {r['drive_cutoff_hz']:.3g} Hz" in part
    assert rec["config"]["reversal"] == "extreme" and "reversals at the motion's extreme" in part


@pytest.mark.slow
def test_unconverged_fits_are_flagged(report_run, rendered_report):
    summary = json.loads((report_run["run_dir"] / "fit" / "summary.json").read_text())
    assert not any(f["converged"] for f in summary["fits"])      # the tiny sampler cannot converge
    html = rendered_report["html"]
    head = html[:html.index('<nav class="toc"')]
    assert "did NOT converge" in head and 'class="warn"' in head
    for f in summary["fits"]:
        part = sub_html(html, f"fit-{f['id']}")
        assert "converged: NO" in part and f"Fit {f['id']} did NOT converge" in part
        assert "16 independent chains (independence move and random walk)" in part   # the default
    assert "Computed from fits that did NOT converge" in section_html(html, "advantage")
    assert "Fits of the comparison that did NOT converge" in section_html(html, "comparison")


@pytest.mark.slow
def test_optional_sections_content(rendered_report):
    html = rendered_report["html"]
    across = section_html(html, "across")
    assert "needs fits at 2 or more applied forces" in across and "<img" in across
    comp = section_html(html, "comparison")
    assert "n/a (1 test: not cross-validated)" in comp      # one test per level here
    assert "BRFD paper, Table 4" in comp and "5.96" in comp
    pred = section_html(html, "predictions")
    assert 'id="predictions-validation"' in pred and "coverage of the 95 % band" in pred
    assert 'id="prediction-harmonic-25mm-2Hz-36lb"' in pred and "energy median (J)" in pred
    prov = unescape(section_html(html, "provenance"))
    assert "f" * 64 in prov and "report generated" in prov and '"published": "brfd"' in prov
    # the task times are summed as such, the wall time beside (the fixture's run took 60 s)
    assert "add up to" in prov and "this run had taken 60 s when the record was written" in prov
    # the output files, each with what records its version, configuration and seed
    assert "output files: " in prov and "fit/summary.json" in prov and "posterior.nc" in prov


@pytest.mark.slow
def test_every_figure_has_title_legend_and_labelled_axes(rendered_report):
    figs = rendered_report["figures"]
    assert len(figs) >= 12
    for f in figs:
        assert f["titles"] and f["titles"][0].strip(), f
        assert f["fig_legend"] or any(a["legend"] for a in f["axes"]), f["titles"]
        grid = any(k in f["titles"][0] for k in ("posterior of the model parameters", "rank plot"))
        for a in f["axes"]:
            if not (a["visible"] and a["has_data"]) or grid:
                continue
            for lab in (a["xlabel"], a["ylabel"]):
                assert re.search(r"\(.+\)", lab), f"axis label without unit: {lab!r} in {f['titles']}"


@pytest.mark.slow
def test_missing_optional_folders_give_sentences(report_run, partial_run, tmp_path):
    run = partial_run("ingest", "fit")
    out = render_report(run, tmp_path / "r.html", workflow={}, provenance={})
    html = out.read_text()
    o = outline(html)
    for sid, _ in SECTIONS:
        assert len(o.text[sid].strip()) > 40, sid
    assert "The mechanical advantage was not computed in this workflow" in html
    assert "The model comparison was not run in this workflow" in html
    assert "No prediction or validation was run in this workflow" in html
    assert "No published parameter set to compare with" in html
    assert "No input hashes recorded" in html and "No task record" in html
    only = render_report(partial_run("ingest"), tmp_path / "i.html", workflow={}, provenance={})
    text = only.read_text()
    assert "This run has no fits" in text and "frictionuq report:" in text


@pytest.mark.slow
def test_law_band_when_law_json_present(report_run, tmp_path):
    """A law.json (here a synthetic linear law) gives the law's curves beside the points."""
    from frictionuq.report.context import Context
    from frictionuq.report.sections import levels
    run = tmp_path / "run"
    run.mkdir()
    (run / "ingest").symlink_to(report_run["run_dir"] / "ingest", target_is_directory=True)
    shutil.copytree(report_run["run_dir"] / "fit", run / "fit")
    rng = np.random.default_rng(0)
    laws = {n: {"family": "linear", "log_space": True, "tau_draws": list(np.full(50, 0.1)),
                "beta_draws": [[b] for b in np.log(80.0) + 0.05 * rng.standard_normal(50)]}
            for n in ("fc_fwd", "fc_bwd")}
    (run / "fit" / "law.json").write_text(json.dumps({"family": "linear", "levels": [{}, {}], "laws": laws}))
    blocks = levels.across(Context(run, {"report": {"published": "mfd"}}, {}))
    texts = " ".join(str(b.get("text", "")) for b in blocks)
    assert "Force-dependence law (fit/law.json): family linear" in texts
    assert "this campaign's applied unit is lb: not compared" in texts    # MFD is per pressure
    assert any(b["kind"] == "figure" for b in blocks)
    ctx = Context(run, {}, {})
    curves = levels.law_curves(ctx, json.loads((run / "fit" / "law.json").read_text()),
                               levels.level_stats(ctx))
    g, med, lo, hi, lo_s, hi_s = curves["fc_fwd"]
    assert np.all(lo <= med) and np.all(med <= hi) and np.all(lo_s <= lo + 1e-9)
    assert med[-1] == pytest.approx(80.0 * 4.4482216152605 * g[-1], rel=0.1)   # 80 x applied (N)


@pytest.mark.slow
def test_write_is_atomic(report_run, tmp_path, monkeypatch):
    from frictionuq.report import figures_fit
    out = tmp_path / "report.html"
    out.write_text("previous report")

    def boom(*a, **k):
        raise RuntimeError("figure failed")
    monkeypatch.setattr(figures_fit, "corner_figure", boom)
    with pytest.raises(RuntimeError, match="figure failed"):
        render_report(report_run["run_dir"], out, workflow=report_run["workflow"],
                      provenance=report_run["provenance"])
    assert out.read_text() == "previous report"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.html"]
    fresh = tmp_path / "new" / "report.html"
    with pytest.raises(RuntimeError):
        render_report(report_run["run_dir"], fresh, workflow={}, provenance={})
    assert not fresh.exists()


@pytest.mark.slow
def test_incomplete_fit_folder_is_reported_not_fatal(report_run, tmp_path):
    from frictionuq.report.context import Context
    from frictionuq.report.sections import fits, levels
    run = tmp_path / "run"
    shutil.copytree(report_run["run_dir"] / "fit", run / "fit")
    (run / "fit" / "applied-0lb" / "posterior.nc").unlink()
    ctx = Context(run, {}, {})
    blocks = fits.build(ctx)
    subs = {b["id"]: b for b in blocks if b["kind"] == "sub"}
    assert [b["kind"] for b in subs["fit-applied-0lb"]["blocks"]] == ["warn"]
    assert "posterior.nc: missing" in subs["fit-applied-0lb"]["blocks"][0]["text"]
    assert any(b["kind"] == "figure" for b in subs["fit-applied-36lb"]["blocks"])
    assert [L["id"] for L in levels.level_stats(ctx)] == ["applied-36lb"]


# ------------------------------------------------------------------ in headless Chromium
ARTIFACTS = Path(__file__).resolve().parent.parent / "test-artifacts"


@pytest.mark.slow
def test_report_in_headless_chromium(rendered_report):
    if chromium_path() is None:
        pytest.skip("headless Chromium not available: needs /usr/bin/chromium (apt-get install "
                    "chromium) and the playwright package (pip install -e .[test])")
    html = rendered_report["path"]
    shot = ARTIFACTS / f"report-{html.stem}.png"
    found = check_report_in_browser(html, shot)
    assert not found["problems"], found["problems"]
    for sid, _ in SECTIONS:
        s = found["sections"][sid]
        assert s["present"] and s["visible"] and s["text"] > 20, (sid, s)
    assert found["title"] == "Tiny report test"
    assert found["body_text"] > 2000
    assert len(found["images"]) >= 12 and all(i["width"] > 0 for i in found["images"])
    assert found["page_width"] <= found["viewport_width"]
    assert found["main_width"] <= 1100
    assert shot.is_file() and shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_outputs_the_workflow_no_longer_asks_for_are_not_shown(report_run, partial_run, tmp_path):
    """A run folder keeps an earlier run's comparison, discrepancy and prediction folders when
    the workflow drops them; the report shows only what the workflow asks for and says so."""
    import copy
    run = partial_run("ingest", "fit", "compare", "predict")
    wf = copy.deepcopy(report_run["workflow"])
    html = render_report(run, tmp_path / "all.html", workflow=wf, provenance={}).read_text()
    assert 'id="prediction-harmonic-25mm-2Hz-36lb"' in html and "BRFD paper, Table 4" in html
    wf["compare"]["enabled"] = False
    wf["predict"] = {"validate": [], "harmonic": []}
    html = render_report(run, tmp_path / "some.html", workflow=wf, provenance={}).read_text()
    comp, pred = section_html(html, "comparison"), section_html(html, "predictions")
    assert "not enabled in this workflow ([compare] enabled = false)" in comp
    assert "<table" not in comp
    assert 'id="prediction-' not in pred and 'id="predictions-validation"' not in pred
    assert "No prediction for a new drive in this workflow" in pred


def test_provenance_lists_the_output_files_and_what_records_them(tmp_path):
    """The footer says the run folder's files are named in the provenance section: they are,
    each with the file that records its package version, configuration and seed (itself, the
    JSON beside it or one folder up, a netCDF/HDF5 file's attributes), or a dash."""
    from types import SimpleNamespace
    from frictionuq.report.sections.provenance import _outputs
    run = tmp_path / "run"
    (run / "predict" / "h").mkdir(parents=True)
    (run / "ingest" / "tests").mkdir(parents=True)
    (run / "predict" / "h" / "prediction.json").write_text('{"package_version": "0.1.0", "seed": 7}')
    (run / "predict" / "h" / "bands.csv").write_text("time\n0\n")
    (run / "ingest" / "manifest.json").write_text('{"package_version": "0.1.0"}')
    (run / "ingest" / "tests" / "a.csv").write_text("time\n0\n")
    (run / "fit").mkdir()
    (run / "fit" / "posterior.nc").write_bytes(b"x")
    (run / "stray.csv").write_text("x\n")
    (run / ".tmp-x").mkdir()
    (run / ".tmp-x" / "half.json").write_text("{")
    html = unescape(_outputs(SimpleNamespace(run_dir=run))[0]["html"])
    rows = dict(re.findall(r"<tr><td>([^<]+)</td><td>[^<]*</td><td>([^<]*)</td></tr>", html))
    assert rows == {"fit/posterior.nc": "its own attributes", "ingest/manifest.json": "itself",
                    "ingest/tests/a.csv": "ingest/manifest.json",
                    "predict/h/bands.csv": "predict/h/prediction.json",
                    "predict/h/prediction.json": "itself (seed 7)", "stray.csv": "\u2013"}, html
    assert "output files: 6" in html
