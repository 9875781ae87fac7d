"""The HTML report as a reader sees it: opened in headless Chromium (tests/browser.py), every
section present and visible, the page not blank, every image decoded, no sideways scrolling on a
laptop-sized window, no network request; a full-page screenshot goes to
test-artifacts/report-<name>.png for a human look."""
from __future__ import annotations

from pathlib import Path

import pytest

from browser import check_report_in_browser, chromium_path
from frictionuq.report import SECTIONS

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
