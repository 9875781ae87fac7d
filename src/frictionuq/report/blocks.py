"""The content blocks a section is made of (plain dicts the template renders, see
templates/report.html): text, notes, warnings, raw HTML tables, figures, preformatted text,
headings and sub-sections with their own ids."""
from __future__ import annotations

import re

from .figures import data_uri


def para(text) -> dict:
    return {"kind": "p", "text": text}


def note(text) -> dict:
    """An explanatory sentence (e.g. why a piece is missing)."""
    return {"kind": "note", "text": text}


def warn(text) -> dict:
    """A prominent warning (e.g. a fit that did not converge)."""
    return {"kind": "warn", "text": text}


def html(markup) -> dict:
    return {"kind": "html", "html": markup}


def figure(png_bytes: bytes, alt: str, caption: str = "") -> dict:
    return {"kind": "figure", "src": data_uri(png_bytes), "alt": alt, "caption": caption}


def pre(text: str) -> dict:
    return {"kind": "pre", "text": text}


def heading(text: str) -> dict:
    return {"kind": "h4", "text": text}


def sub(sid: str, title: str, blocks: list[dict]) -> dict:
    return {"kind": "sub", "id": sid, "title": title, "blocks": blocks}


def slug(text: str) -> str:
    """A string usable in an HTML id: letters, digits, '.', '_', '-' (others become '-')."""
    return re.sub(r"[^A-Za-z0-9._-]+", "-", str(text)).strip("-") or "x"
