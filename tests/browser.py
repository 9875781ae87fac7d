"""Opening a frictionuq HTML report in headless Chromium (Debian's chromium driven through
playwright, no browser download) and checking what a reader would see.

    findings = check_report_in_browser("report.html", "test-artifacts/report-x.png")
    assert not findings["problems"], findings["problems"]

Importable by any test (tests/ is on sys.path under pytest); `chromium_path()` returns None
when the browser or playwright is missing so a test can skip with a reason.
"""
from __future__ import annotations

import shutil
from pathlib import Path

CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]
VIEWPORT = {"width": 1280, "height": 900}       # a laptop screen
MIN_BODY_TEXT = 500

_JS_SECTION = """(id) => {
  const e = document.getElementById(id);
  if (!e) return {present: false, visible: false, text: 0, height: 0};
  const r = e.getBoundingClientRect(), s = getComputedStyle(e);
  return {present: true, text: e.innerText.trim().length, height: r.height,
          visible: r.height > 0 && r.width > 0 && s.display !== 'none' && s.visibility !== 'hidden'};
}"""
_JS_IMAGES = """() => Array.from(document.images).map((i, k) => ({
  index: k, alt: i.alt, complete: i.complete, width: i.naturalWidth, height: i.naturalHeight,
  shown: i.getBoundingClientRect().width, data: i.src.startsWith('data:image/png;base64,')}))"""
_JS_LAYOUT = """() => ({scroll: document.documentElement.scrollWidth, inner: window.innerWidth,
  body: document.body.innerText.trim().length, main: document.querySelector('main') ?
  document.querySelector('main').getBoundingClientRect().width : 0,
  toc: Array.from(document.querySelectorAll('nav.toc a')).map(a => a.getAttribute('href'))})"""


def chromium_path() -> str | None:
    """The Chromium executable, or None (with playwright importable) when it cannot be used."""
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        return None
    import importlib.util
    return exe if importlib.util.find_spec("playwright") is not None else None


def check_report_in_browser(html_path, screenshot_path, sections=None, executable=None) -> dict:
    """Open `html_path` in headless Chromium and return the findings:
    sections {id: {present, visible, text, height}}, images [...], body_text, page_width,
    viewport_width, toc (link targets), network (requests other than file:/data:), console
    errors, screenshot path and `problems` (a list of sentences; empty when all is well)."""
    from playwright.sync_api import sync_playwright
    if sections is None:
        from frictionuq.report import SECTIONS
        sections = [sid for sid, _ in SECTIONS]
    exe = executable or chromium_path()
    if exe is None:
        raise RuntimeError("chromium not found (apt-get install chromium) or playwright missing")
    html_path, shot = Path(html_path).resolve(), Path(screenshot_path)
    shot.parent.mkdir(parents=True, exist_ok=True)
    found: dict = {"html": str(html_path), "screenshot": str(shot), "network": [], "console_errors": []}
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=exe, headless=True, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport=VIEWPORT)
            page.on("request", lambda r: found["network"].append(r.url)
                    if not r.url.startswith(("file:", "data:")) else None)
            page.on("console", lambda m: found["console_errors"].append(m.text) if m.type == "error" else None)
            page.goto(html_path.as_uri(), wait_until="load")
            found["title"] = page.title()
            found["sections"] = {sid: page.evaluate(_JS_SECTION, sid) for sid in sections}
            found["images"] = page.evaluate(_JS_IMAGES)
            lay = page.evaluate(_JS_LAYOUT)
            found.update(body_text=lay["body"], page_width=lay["scroll"], viewport_width=lay["inner"],
                         main_width=lay["main"], toc=lay["toc"])
            page.screenshot(path=str(shot), full_page=True)
        finally:
            browser.close()
    found["problems"] = _problems(found, sections)
    return found


def _problems(f: dict, sections) -> list[str]:
    out = []
    for sid in sections:
        s = f["sections"][sid]
        if not s["present"]:
            out.append(f"section #{sid} is missing")
        elif not s["visible"]:
            out.append(f"section #{sid} is not visible")
        elif s["text"] < 20:
            out.append(f"section #{sid} is (nearly) empty: {s['text']} characters")
        if f"#{sid}" not in f["toc"]:
            out.append(f"the table of contents has no link to #{sid}")
    if f["body_text"] < MIN_BODY_TEXT:
        out.append(f"page looks blank: {f['body_text']} characters of text")
    if not f["images"]:
        out.append("no image on the page")
    for im in f["images"]:
        if not (im["complete"] and im["width"] > 0):
            out.append(f"image {im['index']} ({im['alt']!r}) did not decode")
        if not im["data"]:
            out.append(f"image {im['index']} ({im['alt']!r}) is not an inline PNG data URI")
        if im["shown"] > f["viewport_width"]:
            out.append(f"image {im['index']} is wider than the window")
    if f["page_width"] > f["viewport_width"]:
        out.append(f"the page scrolls sideways: {f['page_width']} px wide in a "
                   f"{f['viewport_width']} px window")
    if f["network"]:
        out.append(f"the page requested external resources: {f['network'][:3]}")
    if f["console_errors"]:
        out.append(f"console errors: {f['console_errors'][:3]}")
    if not Path(f["screenshot"]).is_file():
        out.append("no screenshot written")
    return out
