"""The README's main job end to end: `frictionuq run workflows/quick.toml -j 2` on the shipped
real records (here into a temporary run folder), its report opened in headless Chromium (every
section present and filled, images decoded, nothing external; screenshot kept in
test-artifacts/), and the second run a no-op."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from browser import check_report_in_browser, chromium_path

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    d = tmp_path_factory.mktemp("quick")
    text = (ROOT / "workflows" / "quick.toml").read_text()
    text = text.replace('campaign = "../data/brfd-arts-d2"',
                        f'campaign = "{ROOT / "data" / "brfd-arts-d2"}"\noutput = "out"\nreport = "report"')
    assert 'output = "out"' in text
    wf = d / "quick.toml"
    wf.write_text(text)
    r = subprocess.run([sys.executable, "-m", "frictionuq.cli", "run", str(wf), "-j", "2"],
                       capture_output=True, text=True)
    return d, wf, r


def test_quick_workflow_runs_and_writes_every_output(quick):
    d, wf, r = quick
    assert r.returncode == 0, r.stdout + r.stderr[-3000:]
    assert "report:" in r.stdout
    out = d / "out"
    summary = json.loads((out / "fit" / "summary.json").read_text())
    assert [f["id"] for f in summary["fits"]] == ["applied-0lb", "applied-36lb"]
    val = json.loads((out / "predict" / "validation" / "validation.json").read_text())
    t = val["tests"][0]
    assert t["test"] == "eq-imperial-valley-36lb" and t["held_out"] is True
    # the scores are the bands' against the measured record (recomputed here from the files)
    import numpy as np
    import pandas as pd
    from frictionuq.campaign import load_campaign
    from frictionuq.validate import calibration_notes
    b = pd.read_csv(out / "predict" / "validation" / "eq-imperial-valley-36lb.bands.csv")
    y = load_campaign(out / "ingest").test("eq-imperial-valley-36lb").record.force
    inside = (y >= b["force_q2.5"]) & (y <= b["force_q97.5"])
    assert t["coverage95"] == pytest.approx(float(np.mean(inside)), abs=1e-12)
    assert t["nrmse"] == pytest.approx(float(np.sqrt(np.mean((y - b["force_median"]) ** 2))
                                             / np.ptp(y)), rel=1e-9)
    # a miscalibrated band is said in the report (the replay's 50 % band covers about 15 %)
    report = (d / "report" / "index.html").read_text()
    for line in calibration_notes(t):
        assert line.split(":")[0][1:] in report     # the report capitalises its first letter
    cmp = json.loads((out / "compare" / "compare.json").read_text())
    assert set(cmp["levels"][0]["models"]) == {"three_stage", "lugre"}
    assert cmp["levels"][0]["pairs"], "two tests: the comparison is cross-validated"
    # the comparison records the tests it compared (not the fits'), each level its provenance
    assert cmp["config"]["tests"] == ["sine-1Hz-36lb-1in", "sine-2Hz-36lb-0.5in"]
    assert all(m["tests"] is None for m in cmp["config"]["models"].values())
    lvl = json.loads((out / "compare" / "applied-36lb" / "lugre" / "level.json").read_text())
    assert lvl["package_version"] and lvl["seed"] == 1 and lvl["config"]["model"] == "lugre"
    # the ground motion is a clean generated drive (dead band 0, unfiltered), its source recorded,
    # and its cycles are between real turning points, not micrometre wiggles
    kobe = json.loads((out / "predict" / "kobe-10mm-36lb" / "prediction.json").read_text())
    assert kobe["input"]["kind"] == "generated record" and kobe["input"]["eps_m"] == 0.0
    assert kobe["input"]["source"] == {"record": "kobe", "peak_m": 0.01, "rate_hz": 256.0}
    cyc = pd.read_csv(out / "predict" / "kobe-10mm-36lb" / "cycles.csv")
    assert len(cyc) and (cyc["t_end"] - cyc["t_start"]).min() > 0.1, cyc
    prov = json.loads((out / "run.json").read_text())
    assert prov["package_version"] and prov["workflow"]["file"] == str(wf.resolve())
    assert all(t["status"] == "ran" for t in prov["tasks"])


@pytest.mark.skipif(chromium_path() is None, reason="chromium or playwright missing: "
                    "run tools/install-chromium (make test does)")
def test_quick_report_in_headless_chromium(quick):
    d, wf, r = quick
    html = d / "report" / "index.html"
    assert html.is_file(), r.stderr[-2000:]
    found = check_report_in_browser(html, ROOT / "test-artifacts" / "report-quick.png")
    assert not found["problems"], found["problems"]
    assert found["title"]
    # the report names the real data and carries the numbers, with units
    text = html.read_text()
    assert "eq-imperial-valley-36lb" in text and "brfd-arts-d2" in text
    assert re.search(r"\bkN\b", text) and "R-hat" in text


def test_quick_second_run_is_a_noop(quick):
    d, wf, r = quick
    again = subprocess.run([sys.executable, "-m", "frictionuq.cli", "run", str(wf), "-j", "2"],
                           capture_output=True, text=True)
    assert again.returncode == 0 and "nothing to do" in again.stdout, again.stdout + again.stderr
